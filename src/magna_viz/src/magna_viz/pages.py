"""The HTML both pages share: one stylesheet, escaping, pictures inlined as data URIs, atomic writes.

A report must open from anywhere (mailed, copied off a headless machine), so its pictures travel
inside it as base64 PNGs; the dataset index only links to the reports beside it.
"""
from __future__ import annotations

import base64
import html
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from magna_common.files import write_text_atomically

STYLE = """
body { font-family: Helvetica, Arial, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; } h2 { font-size: 1.15em; margin-top: 1.6em; }
.sub { color: #666; margin-top: 0; }
table { border-collapse: collapse; margin: 0.6em 0; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; font-size: 0.92em; }
th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.ok { color: #1a7f37; font-weight: bold; } .bad { color: #c62828; font-weight: bold; }
.swatch { display: inline-block; width: 0.9em; height: 0.9em; border: 1px solid #555; vertical-align: middle; }
figure { margin: 0.8em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { color: #555; font-size: 0.9em; }
code { background: #f4f4f4; padding: 0 0.25em; }
.missing { color: #8a6d00; }
"""


def escape(value: object) -> str:
    return html.escape(str(value), quote=True)


def data_uri(png: Path) -> str:
    """A PNG as a data URI, so the page needs no file beside it."""
    return "data:image/png;base64," + base64.b64encode(Path(png).read_bytes()).decode("ascii")


def figure(png: Path, caption: str, inline: bool = True, base: Path | None = None) -> str:
    """An <img> with its caption: inlined, or linked relative to `base` (the page's folder)."""
    source = data_uri(png) if inline else escape(os.path.relpath(png, base or Path.cwd()))
    return (f'<figure><img src="{source}" alt="{escape(caption)}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>")


def swatch(rgb: Sequence[float]) -> str:
    """A small square of a colour given as r, g, b in 0..1."""
    r, g, b = (max(0, min(255, round(255 * float(c)))) for c in rgb[:3])
    return f'<span class="swatch" style="background: rgb({r}, {g}, {b})"></span>'


def table(header: Sequence[str] | None, rows: Iterable[Sequence[str]], numeric: Iterable[int] = ()) -> str:
    """A table whose cells are already HTML; columns listed in `numeric` align right; no header row if None."""
    numeric = set(numeric)
    head = "<thead><tr>" + "".join(f"<th>{escape(h)}</th>" for h in header) + "</tr></thead>" if header else ""
    body = "".join("<tr>" + "".join(f'<td class="num">{c}</td>' if i in numeric else f"<td>{c}</td>"
                                    for i, c in enumerate(row)) + "</tr>" for row in rows)
    return f"<table>{head}<tbody>{body}</tbody></table>"


def page(title: str, body: str) -> str:
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{escape(title)}</title>'
            f"<style>{STYLE}</style></head><body>\n{body}\n</body></html>\n")


def write_page(path: Path, text: str) -> Path:
    """Write `path` all or nothing: a reader sees the old page or the new one, never half of one."""
    return write_text_atomically(path, text, overwrite=True)
