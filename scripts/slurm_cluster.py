"""MAGNA's Dask workers as Slurm jobs (dask-jobqueue's SLURMCluster), for `magna run --cluster`.

Run it on a machine that can submit jobs (a login node), inside this checkout's environment. It starts a
Dask scheduler there, submits --jobs Slurm jobs of --cores-per-job cores each, and prints the address to
give `magna run --cluster`. Each job runs cores/2 worker processes of one thread: a 2-UAV simulation keeps
about two cores busy. The jobs start the workers with this checkout's venv Python and devel space, so the
nodes must see this checkout at the same path (a shared home or project folder). Ctrl-C cancels the jobs
and stops the scheduler. --dry-run prints the job script and submits nothing.

    scripts/with_env.sh python scripts/slurm_cluster.py --jobs 4 --cores-per-job 8 --partition short
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="scripts/with_env.sh python scripts/slurm_cluster.py",
                                     description=__doc__.split("\n\n")[0],
                                     epilog="\n\n".join(__doc__.split("\n\n")[1:]),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--jobs", type=int, default=2, metavar="J", help="Slurm jobs to submit (default 2)")
    parser.add_argument("--cores-per-job", type=int, default=8, metavar="C",
                        help="cores of each job; it runs C/2 single-thread workers (default 8)")
    parser.add_argument("--memory", default="16GB", help="memory of each job (default 16GB; 2 GB per worker is ample)")
    parser.add_argument("--walltime", default="02:00:00", help="each job's time limit (default 02:00:00)")
    parser.add_argument("--partition", default=None, help="the Slurm partition (queue); default: Slurm's")
    parser.add_argument("--account", default=None, help="the Slurm account to charge, if your site needs one")
    parser.add_argument("--port", type=int, default=8786, help="the scheduler's port (default 8786)")
    parser.add_argument("--dry-run", action="store_true", help="print the job script, submit nothing")
    return parser


def make_cluster(args):
    from dask_jobqueue import SLURMCluster

    if args.cores_per_job < 2:
        raise SystemExit("--cores-per-job must be >= 2: a 2-UAV simulation keeps about two cores busy")
    workers = args.cores_per_job // 2
    return SLURMCluster(
        cores=workers, processes=workers,  # one thread per worker process: one simulation at a time each
        job_cpu=args.cores_per_job, memory=args.memory, walltime=args.walltime, queue=args.partition,
        account=args.account, python=str(ROOT / ".venv" / "bin" / "python"),
        job_script_prologue=[f"source {ROOT / 'devel' / 'setup.bash'}", f"export MAGNA_ROOT={ROOT}"],
        scheduler_options={"host": "0.0.0.0", "port": 0 if args.dry_run else args.port,
                           "dashboard_address": ":0"},
    )


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    cluster = make_cluster(args)
    try:
        if args.dry_run:
            print(cluster.job_script())
            return 0
        cluster.scale(jobs=args.jobs)
        address = cluster.scheduler_address.replace("0.0.0.0", "THIS_HOST")
        print(f"submitted {args.jobs} job(s) of {args.cores_per_job // 2} worker(s) each; scheduler {address}\n"
              f"  ./magna doctor --cluster {address}\n  ./magna run ... --cluster {address}\n"
              "Ctrl-C cancels the jobs.", flush=True)
        stop = threading.Event()
        signal.signal(signal.SIGTERM, lambda *_: stop.set())
        try:
            stop.wait()
        except KeyboardInterrupt:
            pass
        return 0
    finally:
        cluster.close()


if __name__ == "__main__":
    sys.exit(main())
