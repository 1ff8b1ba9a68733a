"""scripts/slurm_cluster.py --dry-run: the Slurm job script starts MAGNA's workers as `magna run --cluster` needs."""
import subprocess

from tests.support import ROOT


def test_the_job_script_runs_single_thread_workers_in_this_checkout():
    done = subprocess.run([str(ROOT / "scripts" / "with_env.sh"), "python", "scripts/slurm_cluster.py", "--dry-run",
                           "--cores-per-job", "8", "--partition", "short", "--walltime", "00:30:00"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    script = done.stdout
    assert "#SBATCH -p short" in script and "#SBATCH --cpus-per-task=8" in script and "#SBATCH -t 00:30:00" in script
    assert f"source {ROOT}/devel/setup.bash" in script and f"export MAGNA_ROOT={ROOT}" in script
    worker = next(line for line in script.splitlines() if "dask_worker" in line)
    assert worker.startswith(f"{ROOT}/.venv/bin/python -m distributed.cli.dask_worker tcp://")
    assert "--nthreads 1" in worker and "--nworkers 4" in worker  # one simulation per 2 cores


def test_too_few_cores_per_job_is_refused():
    done = subprocess.run([str(ROOT / "scripts" / "with_env.sh"), "python", "scripts/slurm_cluster.py", "--dry-run",
                           "--cores-per-job", "1"], capture_output=True, text=True, timeout=120)
    assert done.returncode != 0 and "--cores-per-job must be >= 2" in done.stderr
