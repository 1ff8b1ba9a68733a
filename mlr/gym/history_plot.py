"""The success rate of a `magna learn rl` run against its training time, as a picture (success.png)."""
from __future__ import annotations

from pathlib import Path

from magna_common.files import write_atomically


def draw_history(history: list[dict], path: Path, title: str) -> Path:
    """Success rate (whole missions flown in the gym) at each checkpoint against training minutes; headless."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(6.0, 3.2))
    FigureCanvasAgg(figure)
    axes = figure.subplots()
    minutes = [entry["wall_seconds"] / 60.0 for entry in history]
    axes.plot(minutes, [entry["success_rate"] for entry in history], marker="o", color="tab:green")
    for entry, x in zip(history, minutes, strict=True):
        axes.annotate(f"{entry['steps'] // 1000}k", (x, entry["success_rate"]), xytext=(0, 5),
                      textcoords="offset points", ha="center", fontsize=7)
    axes.set_xlabel("training time (min)")
    axes.set_ylabel("success rate")
    axes.set_ylim(0.0, 1.08)
    axes.set_xlim(left=0.0)
    axes.grid(alpha=0.3)
    flights = history[-1]["flights"] if history else 0
    axes.set_title(f"{title}: whole missions flown in the gym ({flights} per point)", fontsize=9)
    figure.tight_layout()
    return write_atomically(Path(path), lambda out: figure.savefig(out, format="png", dpi=100), overwrite=True,
                            binary=True)
