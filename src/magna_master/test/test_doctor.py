"""`magna doctor`: each check sees both a healthy and a broken installation."""
import subprocess
import sys
from pathlib import Path

from magna_common.workspace import Workspace
from magna_master import doctor

ROOT = Path(__file__).resolve().parents[3]


def test_checksums_of_the_built_ual_types_match_grvc():
    assert doctor.check_ual_checksums().ok


def test_missing_debian_package_is_reported(tmp_path):
    (tmp_path / "scripts").mkdir()
    (tmp_path / "scripts" / "apt-packages.txt").write_text("bash  # present\nmagna-no-such-package\n")
    result = doctor.check_apt(Workspace(tmp_path))
    assert not result.ok
    assert "magna-no-such-package" in result.detail and "bash" not in result.detail
    assert result.fix == "make setup"


def test_present_debian_packages_pass(tmp_path):
    (tmp_path / "scripts").mkdir()
    (tmp_path / "scripts" / "apt-packages.txt").write_text("bash\ncoreutils\n")
    assert doctor.check_apt(Workspace(tmp_path)).ok


def test_wrong_pinned_version_is_reported(tmp_path, monkeypatch):
    (tmp_path / "requirements.txt").write_text("pytest==0.0.1\n")
    monkeypatch.setattr(sys, "prefix", str(tmp_path / ".venv"))
    (tmp_path / ".venv").mkdir()
    result = doctor.check_venv(Workspace(tmp_path))
    assert not result.ok and "pytest" in result.detail and "0.0.1" in result.detail


def test_missing_build_is_reported(tmp_path):
    result = doctor.check_build(Workspace(tmp_path))
    assert not result.ok and "devel/setup.bash" in result.detail


def test_doctor_end_to_end_through_the_wrapper():
    out = subprocess.run([str(ROOT / "magna"), "doctor", "--round-trips", "20"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "5 of 5 checks passed" in out.stdout
    assert "take_off p50" in out.stdout
