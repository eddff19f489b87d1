"""Report files: a plot, its numbers and a page for people, written side by side.

Every report (an experiment, an ``evaluate`` or ``sweep`` run) writes ``<name>.png`` (the plot),
``<name>.json`` (every number, machine-readable) and ``<name>.md`` (the same for people); plots
share the colours of the estimates so that a figure reads the same in every report.

The three are written whole or not at all (:func:`~physics_mapper.model.atomic_files.write_all_atomically`):
on a full disk the previous report's files stay as they were, and the error is one line. A command
filling a report folder holds its lock (:func:`lock_report_folder`), so a second one is refused.
"""

from __future__ import annotations

import fcntl
import io
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from physics_mapper.model.atomic_files import Contents, write_all_atomically
from physics_mapper.model.errors import InputError

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


def write_outputs(
    output_dir: Path,
    name: str,
    figure: Figure,
    summary: dict[str, Any],
    markdown: str,
    extra: Sequence[tuple[Path, Contents]] = (),
) -> ReportFiles:
    """Write ``<name>.png``, ``<name>.json`` and ``<name>.md`` into ``output_dir`` (created if missing),
    and the ``extra`` files (a sweep's parameters file) with them.

    All or none: InputError (one line) if they cannot be written, the old ones untouched.
    """
    check_finite(summary)
    png, json_path, markdown_path = (output_dir / f"{name}.{ext}" for ext in ("png", "json", "md"))
    plot = io.BytesIO()
    figure.savefig(plot, format="png", dpi=PNG_DPI)
    try:
        output_dir.mkdir(parents=True, exist_ok=True)
        write_all_atomically(
            [
                (png, plot.getvalue()),
                (json_path, json.dumps(summary, indent=1) + "\n"),
                (markdown_path, markdown.rstrip() + "\n"),
                *extra,
            ]
        )
    except OSError as error:
        raise InputError(
            f"cannot write the report into {output_dir}: {error.strerror or error} (its previous files are untouched)"
        ) from None
    return ReportFiles(png, json_path, markdown_path, summary)


#: The file in a report folder whose lock its writer holds.
LOCK_FILE_NAME = ".physics-mapper.lock"


def lock_report_folder(output_dir: Path, command: str) -> IO[str]:
    """Hold the lock of report folder ``output_dir`` until the returned file is closed (or the process ends).

    InputError (one line) if another process holds it: two runs writing one report would mix their
    files. The lock is the kernel's (``flock``), so a run that was killed leaves none behind.
    """
    path = output_dir / LOCK_FILE_NAME
    try:
        file = path.open("a+", encoding="utf-8")
    except OSError as error:
        raise InputError(f"cannot write into {output_dir}: {error.strerror or error}") from None
    try:
        fcntl.flock(file.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        file.seek(0)
        holder = file.read().strip() or "another process"
        file.close()
        raise InputError(
            f"{output_dir} is in use by {holder}: choose another folder with -o, or wait for it to finish"
        ) from None
    try:  # who holds it, for the message of a second writer; the lock itself needs no space on the disk
        file.seek(0)
        file.truncate()
        file.write(f"physics-mapper {command} (pid {os.getpid()})\n")
        file.flush()
    except OSError:
        pass
    return file
