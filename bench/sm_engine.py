"""Benchmark of the magna_sm engine core: per-transition overhead and a wide Concurrence.

Prints figures; never fails on a time. Target (issue 3): <= 50 us per transition.
    python bench/sm_engine.py [--transitions N] [--repeats R]
"""
import argparse
import statistics
import sys
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/sm_engine.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("magna_sm",))

from magna_sm.examples import chain, wide_concurrence  # noqa: E402


def per_transition_us(length: int, repeats: int, observed: bool) -> list[float]:
    machine = chain(length)
    if observed:
        events = []
        machine.register_observer(events.append)
    machine.execute()  # validation and warm-up
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        machine.execute()
        samples.append((time.perf_counter() - start) / length * 1e6)
    return samples


def concurrence_ms(children: int, repeats: int) -> list[float]:
    machine = wide_concurrence(children)
    machine.execute()
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        assert machine.execute() == "done"
        samples.append((time.perf_counter() - start) * 1e3)
    return samples


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transitions", type=int, default=2000, help="states in the chain (default: %(default)s)")
    parser.add_argument("--repeats", type=int, default=20, help="runs per figure (default: %(default)s)")
    args = parser.parse_args()
    plain = per_transition_us(args.transitions, args.repeats, observed=False)
    observed = per_transition_us(args.transitions, args.repeats, observed=True)
    wide = concurrence_ms(50, args.repeats)
    single = concurrence_ms(1, args.repeats)
    print(f"{'measure':<44} {'p50':>10} {'min':>10}  target")
    print(f"{'transition, no observer (us)':<44} {statistics.median(plain):>10.2f} {min(plain):>10.2f}  <= 50")
    print(f"{'transition, with an observer (us)':<44} {statistics.median(observed):>10.2f} {min(observed):>10.2f}")
    print(f"{'Concurrence of 50 children, one run (ms)':<44} {statistics.median(wide):>10.2f} {min(wide):>10.2f}")
    print(f"{'Concurrence of 1 child, one run (ms)':<44} {statistics.median(single):>10.2f} {min(single):>10.2f}")
    print(f"ratio 50 children / 1 child: {statistics.median(wide) / statistics.median(single):.1f}x")


if __name__ == "__main__":
    main()
