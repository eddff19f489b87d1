"""The plots of a batch run's reports (matplotlib, Agg): ``evaluate``'s four panels, ``sweep``'s heat maps."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.patches import Rectangle

from physics_mapper.evaluation.outputs import COLOR_WITH_PHYSICS, COLOR_WITHOUT_PHYSICS, new_figure
from physics_mapper.evaluation.scoring import ObjectClasses
from physics_mapper.evaluation.settings import value_text

#: Colours of the three estimates (C11..1 and chosen as in the paper's plots) and of the map kinds.
ESTIMATE_COLORS = {"top": COLOR_WITHOUT_PHYSICS, "chosen": COLOR_WITH_PHYSICS, "settled": "tab:green"}
ESTIMATE_LABELS = {"top": "C11..1 (no physics)", "chosen": "chosen", "settled": "settled"}
MAP_COLORS = {"valid": "tab:green", "fallback": "tab:orange", "no_map": "0.75"}
#: Above this many bags, the per-bag map shares are drawn as a histogram instead of one bar per bag.
MAX_BAG_BARS = 40
#: Heat-map panels (combinations of the third and further grid keys) drawn at most.
MAX_FACETS = 6
#: A heat map's cells are labelled with their values only up to this many cells: matplotlib lays out
#: every label, so a 100 x 100 grid's 20,000 labels took about 25 s (and could not be read).
MAX_LABELLED_CELLS = 400
#: Tick labels per heat-map axis at most (every k-th value is named beyond it).
MAX_TICK_LABELS = 25
#: Grid rows a facet's height grows with at most (inches per row below).
MAX_ROWS_HIGH = 30


def _short(path: str, width: int = 28) -> str:
    return path if len(path) <= width else "…" + path[-(width - 1) :]


def _map_shares(axes: Axes, bags: Sequence[dict[str, Any]]) -> None:
    summaries = [(bag["path"], bag["summary"]) for bag in bags if bag["summary"] is not None]
    if len(summaries) > MAX_BAG_BARS:
        shares = [100.0 * summary["valid_share"] for _, summary in summaries]
        axes.hist(shares, bins=20, range=(0.0, 100.0), color=MAP_COLORS["valid"])
        axes.set_xlabel("snapshots with a valid map (%)")
        axes.set_ylabel("bags")
        axes.set_title(f"valid maps per bag ({len(summaries)} bags)", fontsize=9)
        return
    positions = np.arange(len(summaries))
    left = np.zeros(len(summaries))
    for kind, label in (("valid", "valid"), ("fallback", "fallback"), ("no_map", "no map")):
        bar_shares = np.array([100.0 * summary[kind] / summary["snapshots"] for _, summary in summaries])
        axes.barh(positions, bar_shares, left=left, color=MAP_COLORS[kind], label=label)
        left += bar_shares
    axes.set_yticks(positions, [_short(path) for path, _ in summaries], fontsize=7)
    axes.set_ylim(max(len(summaries), 4) - 0.5, -0.5)  # first bag on top; a few bags stay bar-shaped
    axes.set_xlim(0.0, 100.0)
    axes.set_xlabel("snapshots (%)")
    axes.set_title("map per snapshot, by bag", fontsize=9)
    axes.legend(fontsize=7, loc="lower right")


def _mean_errors(axes: Axes, overall: dict[str, Any], names: Sequence[str]) -> None:
    mean = overall["mean_m"]
    if mean is None:
        axes.text(0.5, 0.5, "no ground truth or no map", ha="center", va="center", transform=axes.transAxes)
        axes.set_axis_off()
        return
    groups = [*names, "total"]
    positions = np.arange(len(groups))
    width = 0.8 / len(mean)
    for offset, (estimate, errors) in enumerate(mean.items()):
        values = [100.0 * errors["per_object"][name] for name in names] + [100.0 * errors["total"]]
        shift = (offset - (len(mean) - 1) / 2.0) * width
        axes.bar(positions + shift, values, width, color=ESTIMATE_COLORS[estimate], label=ESTIMATE_LABELS[estimate])
    axes.set_xticks(positions, groups, fontsize=7, rotation=20)
    axes.set_ylabel("mean position error (cm)")
    axes.set_title(f"error over the {overall['scored']} snapshots with a map and ground truth", fontsize=9)
    axes.legend(fontsize=7)
    axes.grid(axis="y", alpha=0.3)


def _per_bag_errors(axes: Axes, bags: Sequence[dict[str, Any]]) -> None:
    means = [bag["summary"]["mean_m"] for bag in bags if bag["summary"] is not None and bag["summary"]["mean_m"]]
    if not means:
        axes.set_axis_off()
        return
    top = [100.0 * mean["top"]["total"] for mean in means]
    for estimate in ("chosen", "settled"):
        values = [100.0 * mean[estimate]["total"] for mean in means]
        axes.scatter(top, values, s=14, color=ESTIMATE_COLORS[estimate], label=ESTIMATE_LABELS[estimate])
    high = 1.05 * max(100.0 * mean[estimate]["total"] for mean in means for estimate in mean)
    axes.plot([0.0, high], [0.0, high], color="0.5", linewidth=1, linestyle="--", label="no change")
    axes.set_xlim(0.0, high)
    axes.set_ylim(0.0, high)
    axes.set_xlabel("C11..1 mean total error (cm)")
    axes.set_ylabel("with physics (cm)")
    axes.set_title("mean total error per bag (below the line: physics helps)", fontsize=9)
    axes.legend(fontsize=7)
    axes.grid(alpha=0.3)


def _time_to_answer(axes: Axes, search_times: Sequence[float], deadline: float | None) -> None:
    if not search_times:
        axes.set_axis_off()
        return
    times = np.sort(1000.0 * np.asarray(search_times))
    axes.step(times, np.arange(1, times.size + 1) / times.size * 100.0, where="post", color="black")
    if deadline is not None:
        axes.axvline(1000.0 * deadline, color="tab:red", linestyle="--", linewidth=1, label="deadline")
        axes.legend(fontsize=7)
    axes.set_xscale("log")
    axes.set_xlabel("search time per snapshot (ms)")
    axes.set_ylabel("snapshots answered (%)")
    axes.set_ylim(0.0, 100.0)
    axes.set_title("time to answer", fontsize=9)
    axes.grid(alpha=0.3)


def evaluation_figure(data: dict[str, Any], search_times: Sequence[float]) -> Figure:
    """``evaluate``'s plots: map shares per bag, mean errors, per-bag errors with and without physics, answer times."""
    figure = new_figure(12.0, 8.0)
    grid = figure.subplots(2, 2)
    _map_shares(grid[0, 0], data["bags"])
    overall = data["overall"]
    if overall is not None:
        _mean_errors(grid[0, 1], overall, data["objects"])
    else:
        grid[0, 1].set_axis_off()
    _per_bag_errors(grid[1, 0], data["bags"])
    deadline = None if data["search_mode"] == "exhaustive" else data["search"]["deadline"]
    _time_to_answer(grid[1, 1], search_times, deadline)
    return figure


def _heat_map(
    axes: Axes,
    values: np.ndarray[Any, np.dtype[np.float64]],
    rows: tuple[str | None, Sequence[Any]],
    columns: tuple[str, Sequence[Any]],
    title: str,
    best: tuple[int, int] | None,
    *,
    low_is_good: bool,
    unit: str,
    decimals: int,
) -> None:
    image = axes.imshow(values, cmap="viridis_r" if low_is_good else "viridis", aspect="auto")
    axes.figure.colorbar(image, ax=axes, shrink=0.8)
    if values.size <= MAX_LABELLED_CELLS:
        _label_cells(axes, image, values, unit, decimals)
    if best is not None:
        axes.add_patch(Rectangle((best[1] - 0.5, best[0] - 0.5), 1, 1, fill=False, edgecolor="tab:red", linewidth=2))
    axes.set_xticks(*_ticks(columns[1]), fontsize=7)
    axes.set_xlabel(columns[0])
    axes.set_yticks(*_ticks(rows[1]), fontsize=7)
    if rows[0] is not None:
        axes.set_ylabel(rows[0])
    axes.set_title(title, fontsize=8)


def _ticks(values: Sequence[Any]) -> tuple[range, list[str]]:
    """Positions and labels of at most :data:`MAX_TICK_LABELS` of an axis's ``values``, evenly spaced."""
    step = -(-len(values) // MAX_TICK_LABELS)  # ceiling division
    positions = range(0, len(values), step)
    return positions, [value_text(values[position]) for position in positions]


def _label_cells(
    axes: Axes, image: AxesImage, values: np.ndarray[Any, np.dtype[np.float64]], unit: str, decimals: int
) -> None:
    """Each cell's value written on it, black or white by the cell's perceived brightness."""
    for (row, column), value in np.ndenumerate(values):
        text = "-" if np.isnan(value) else f"{value:.{decimals}f}{unit}"
        red, green, blue, _ = image.cmap(image.norm(value))
        light = np.isnan(value) or 0.299 * red + 0.587 * green + 0.114 * blue > 0.5  # perceived brightness
        axes.text(column, row, text, ha="center", va="center", fontsize=7, color="black" if light else "white")


def sweep_figure(data: dict[str, Any]) -> Figure:
    """Heat maps of each setting's map error and valid share over the first two grid keys, one pair per
    combination of the other keys (at most :data:`MAX_FACETS`); the best setting is framed in red.

    A large grid (an interrupted 10,000-setting sweep writes its report within a kill grace) is drawn
    without cell labels, with at most :data:`MAX_TICK_LABELS` tick labels per axis, and a height
    that stops growing at :data:`MAX_ROWS_HIGH` rows."""
    grid: dict[str, list[Any]] = data["grid"]
    keys = list(grid)
    row_key, column_key = (keys[0], keys[1]) if len(keys) > 1 else (None, keys[0])
    rows = grid[row_key] if row_key is not None else [""]
    facet_keys = keys[2:]
    facets = list(itertools.product(*(grid[key] for key in facet_keys)))[:MAX_FACETS]
    by_values = {tuple(s["varied"][key] for key in keys): s for s in data["settings"]}
    best = data["best"]["index"] if data["best"] is not None else None
    figure = new_figure(11.0, 0.6 + (1.2 + 0.45 * min(len(rows), MAX_ROWS_HIGH)) * len(facets))
    panels = figure.subplots(len(facets), 2, squeeze=False)
    for facet, (error_axes, valid_axes) in zip(facets, panels, strict=True):
        errors = np.full((len(rows), len(grid[column_key])), np.nan)
        valid = np.full_like(errors, np.nan)
        framed = None
        for (r, row), (c, column) in itertools.product(enumerate(rows), enumerate(grid[column_key])):
            values = ((row,) if row_key is not None else ()) + (column, *facet)
            setting = by_values[values]
            overall = setting["overall"]
            if overall is not None:
                maps = overall["map_error_m"]
                errors[r, c] = np.nan if maps is None else 100.0 * maps["settled_or_top"]
                valid[r, c] = 100.0 * overall["valid_share"]
            if setting["index"] == best:
                framed = (r, c)
        suffix = ", ".join(f"{key}={value_text(value)}" for key, value in zip(facet_keys, facet, strict=True))
        title = "map error, settled or C11..1 (cm)" + (f"; {suffix}" if suffix else "")
        axis_rows, axis_columns = (row_key, rows), (column_key, grid[column_key])
        _heat_map(error_axes, errors, axis_rows, axis_columns, title, framed, low_is_good=True, unit=" cm", decimals=2)
        title = "snapshots with a valid map (%)" + (f"; {suffix}" if suffix else "")
        _heat_map(valid_axes, valid, axis_rows, axis_columns, title, framed, low_is_good=False, unit=" %", decimals=0)
    return figure


def identity_timeline(records: Sequence[dict[str, Any]], objects: ObjectClasses, title: str) -> Figure:
    """Frames on one axis, instances on the other: each cell coloured by the detection the instance took in
    that frame's array (its index there, which changes as the estimator reorders them), and labelled with
    the true object its map pose lies on (the nearest of its class within the identity gate,
    :func:`~physics_mapper.evaluation.identity.identity_gate`; ``x``: none). Grey: the instance took no
    detection in that frame; no label: the map leaves it out (or there is no map). A row with one label is
    an identity kept whatever the order; a label changing within a row is an identity switch."""
    from matplotlib.colors import ListedColormap

    from physics_mapper.evaluation.identity import identity_gate, objects_lain_on, record_frames

    scored = [r for r in records if r["positions"]["truth"] is not None]
    gate = identity_gate(record_frames(scored), objects)
    names = objects.names
    most = max((max(r["detections"].values(), default=-1) for r in scored), default=-1) + 1
    palette = [(0.85, 0.85, 0.85)] + [tuple(float(c) for c in colour[:3]) for colour in _qualitative(most)]
    cells = np.zeros((len(names), len(scored)), dtype=int)  # 0: no detection taken, 1 + i: detection i
    for column, record in enumerate(scored):
        for row, name in enumerate(names):
            index = record["detections"].get(name)
            cells[row, column] = 0 if index is None else 1 + index
    figure = new_figure(max(4.0, 0.3 * len(scored) + 2.0), max(2.5, 0.3 * len(names) + 1.4))
    axes = figure.add_subplot()
    axes.imshow(cells, aspect="auto", interpolation="nearest", cmap=ListedColormap(palette), vmin=0,
                vmax=len(palette) - 1)  # fmt: skip
    for column, record in enumerate(scored):
        lain_on = objects_lain_on(record["positions"]["truth"], record["positions"]["map"] or {}, objects, gate)
        for row, name in enumerate(names):
            if name in lain_on:
                label = "x" if (true := lain_on[name]) is None else str(true + 1)
                axes.text(column, row, label, ha="center", va="center", fontsize=7)
    axes.set_yticks(range(len(names)), list(names))
    axes.set_xticks(range(len(scored)), [str(i + 1) for i in range(len(scored))])
    axes.set_xlabel("frame (snapshot)")
    axes.set_ylabel("instance")
    axes.set_title(f"{title}: colour = detection taken, label = true object (within {gate * 100:.3g} cm)", fontsize=8)
    return figure


def _qualitative(count: int) -> list[Any]:
    """``count`` distinguishable colours (matplotlib's tab20, repeated beyond 20)."""
    from matplotlib import colormaps

    table = colormaps["tab20"]
    return [table(i % 20) for i in range(count)]
