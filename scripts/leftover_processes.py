"""List processes of one test run still alive: those whose environment carries the run's token.

Every process the tests start inherits MAGNA_TEST_RUN (unless a test replaced the
whole environment), even after it is orphaned; this script's own ancestors are
the test driver and are not counted. Exit status 1 when any is found.
"""
import os
import sys
from pathlib import Path


def ancestors(pid: int) -> set[int]:
    chain = set()
    while pid > 1:
        chain.add(pid)
        status = Path(f"/proc/{pid}/status").read_text()
        pid = int(next(line.split()[1] for line in status.splitlines() if line.startswith("PPid:")))
    return chain


def carrying(token: bytes, variable: bytes = b"MAGNA_TEST_RUN") -> list[tuple[int, str]]:
    """(pid, command line) of every live process whose environment has variable=token."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if variable + b"=" + token not in (entry / "environ").read_bytes().split(b"\0"):
                continue
            if "State:\tZ" in (entry / "status").read_text():
                continue  # already dead, waiting for its parent to reap it
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
        except (FileNotFoundError, ProcessLookupError, PermissionError):
            continue
        found.append((int(entry.name), command))
    return found


def main() -> int:
    token = os.environ.get("MAGNA_TEST_RUN", "").encode()
    if not token:
        print("leftover_processes: MAGNA_TEST_RUN is not set", file=sys.stderr)
        return 2
    mine = ancestors(os.getpid())
    leaked = [(pid, command) for pid, command in carrying(token) if pid not in mine]
    for pid, command in leaked:
        print(f"still running: {pid} {command}", file=sys.stderr)
    return 1 if leaked else 0


if __name__ == "__main__":
    sys.exit(main())
