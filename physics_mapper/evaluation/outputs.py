"""Report files: a plot, its numbers and a page for people, written side by side.

Every report (an experiment, an ``evaluate`` or ``sweep`` run) writes ``<name>.png`` (the plot),
``<name>.json`` (every number, machine-readable) and ``<name>.md`` (the same for people); plots
share the colours of the estimates so that a figure reads the same in every report.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

#: The colours of the two estimates, as in the paper's plots: without physics blue, with black;
#: the refined map (``fallback: refine``) orange, as the node's markers draw a fallback's map.
COLOR_WITHOUT_PHYSICS = "tab:blue"
COLOR_WITH_PHYSICS = "black"
COLOR_REFINED = "tab:orange"
#: Resolution of every PNG report, dots per inch.
PNG_DPI = 110


@dataclass(frozen=True)
class ReportFiles:
    """The files one report wrote, and its summary."""

    png: Path
    json: Path
    markdown: Path
    summary: dict[str, Any]


def new_figure(width_inches: float, height_inches: float) -> Figure:
    """A matplotlib figure drawn by the Agg backend (no display, no global pyplot state)."""
    figure = Figure(figsize=(width_inches, height_inches), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def check_finite(data: Any, key: str = "summary") -> None:
    """Raise ValueError naming the key of the first NaN or infinite number in nested data."""
    if isinstance(data, float) and not math.isfinite(data):
        raise ValueError(f"{key} is {data}")
    if isinstance(data, dict):
        for name, value in data.items():
            check_finite(value, f"{key}.{name}")
    elif isinstance(data, list | tuple):
        for index, value in enumerate(data):
            check_finite(value, f"{key}[{index}]")


def write_outputs(output_dir: Path, name: str, figure: Figure, summary: dict[str, Any], markdown: str) -> ReportFiles:
    """Write ``<name>.png``, ``<name>.json`` and ``<name>.md`` into ``output_dir`` (created if missing)."""
    check_finite(summary)
    output_dir.mkdir(parents=True, exist_ok=True)
    png, json_path, markdown_path = (output_dir / f"{name}.{ext}" for ext in ("png", "json", "md"))
    figure.savefig(png, dpi=PNG_DPI)
    json_path.write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    markdown_path.write_text(markdown.rstrip() + "\n", encoding="utf-8")
    return ReportFiles(png, json_path, markdown_path, summary)
