"""The reports of a batch run: ``evaluate`` (one setting) and ``sweep`` (a grid), as JSON, Markdown and PNG.

A report's JSON holds the results (per bag and overall, :mod:`physics_mapper.evaluation.summary`) and,
under ``run``, how the run went: the command, the executor, when, the wall-clock figures and the
search times ("time to answer": how long each snapshot's search took, as a node's tick would).
Everything outside ``run`` depends only on the bags, the scene and the settings when every
search runs to its end (``search_mode: exhaustive``), so it is the same whatever executor and
however many workers ran it. Errors in the JSON are metres, in the Markdown centimetres.
"""

from __future__ import annotations

import platform
import socket
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

from physics_mapper.evaluation.outputs import ReportFiles, write_outputs
from physics_mapper.evaluation.plots import evaluation_figure, sweep_figure
from physics_mapper.evaluation.runner import BatchRun
from physics_mapper.evaluation.scoring import ObjectClasses
from physics_mapper.evaluation.settings import Setting, node_parameters_yaml, value_text
from physics_mapper.evaluation.summary import bag_summary, overall_summary, time_summary
from physics_mapper.evaluation.tasks import TaskOutput
from physics_mapper.model.errors import InputError
from physics_mapper.model.limits import printable

Criterion = Literal["settled", "chosen", "valid"]
#: What each ``--criterion`` picks, for the reports.
CRITERIA: dict[Criterion, str] = {
    "settled": "lowest mean total position error of the settled map over every snapshot with ground truth, "
    "a snapshot without a map counting with C11..1's error (map_error_m.settled_or_top); ties: "
    "higher valid share, then the earlier setting",
    "chosen": "lowest mean total position error of the chosen hypotheses over every snapshot with ground truth, "
    "a snapshot without a map counting with C11..1's error (map_error_m.chosen_or_top); ties: "
    "higher valid share, then the earlier setting",
    "valid": "highest share of snapshots with a valid map; ties: lower map_error_m.settled_or_top, "
    "then the earlier setting",
}


#: The names of :data:`~physics_mapper.evaluation.snapshot_results.ESTIMATES` for people.
ESTIMATE_NAMES = ("C11..1", "chosen", "settled")
#: How the searches of each ``search_mode`` ran, for people.
SEARCH_MODES = {"exhaustive": "exhaustive", "deadline": "each to its setting's deadline"}
#: A table cell without a value.
MISSING = "-"
#: The node parameters file of a sweep's best setting, in the report folder.
PARAMS_FILE = "best_params.yaml"


@dataclass(frozen=True)
class ReportContext:
    """What a report says about its run beyond the results: the command line and the scene file."""

    command: str
    scene_file: Path


def _mode(run: BatchRun) -> str:
    return "exhaustive" if run.exhaustive else "deadline"


def _evaluated(run: BatchRun, setting: int) -> list[tuple[int, TaskOutput]]:
    """(bag index, output) of each bag evaluated with ``setting``, in bag order."""
    found = ((b, run.evaluated((setting, b))) for b in range(len(run.bags)))
    return [(b, output) for b, output in found if output is not None]


def _bag_records(run: BatchRun, setting: int) -> list[list[dict[str, Any]]]:
    """The records of each bag evaluated with ``setting``, in bag order."""
    return [list(output.records) for _, output in _evaluated(run, setting)]


def _search_times(run: BatchRun, setting: int) -> list[float]:
    return [time for _, output in _evaluated(run, setting) for time in output.search_times]


def _bag_entry(run: BatchRun, setting: int, bag: int, *, records: bool) -> dict[str, Any]:
    surveyed, output = run.bags[bag], run.evaluated((setting, bag))
    status, error = run.status((setting, bag))
    entry: dict[str, Any] = {
        "path": str(surveyed.path),
        "storage": surveyed.storage,
        "status": status,
        "error": error,
        "snapshots": None if output is None else len(output.records),
        "summary": None if output is None else bag_summary(output.records, ObjectClasses.of(run.scene)),
    }
    if records and output is not None:
        entry["records"] = list(output.records)
    return entry


def _counts(run: BatchRun, setting: int) -> dict[str, int]:
    statuses = [run.status((setting, b))[0] for b in range(len(run.bags))]
    return {"bags": len(statuses)} | {
        status.replace(" ", "_"): statuses.count(status)
        for status in ("evaluated", "unreadable", "unusable", "failed", "not evaluated")
    }


def _run_section(run: BatchRun, context: ReportContext, times: dict[str, Any]) -> dict[str, Any]:
    outputs = run.outputs.values()
    snapshots = sum(len(output.records) for output in outputs)
    workers = sorted({output.worker for output in outputs})
    return {
        "command": context.command,
        "executor": run.executor,
        "started": run.started,
        "host": socket.gethostname(),
        "python": platform.python_version(),
        "survey_time_s": run.survey_time,
        "wall_time_s": run.wall_time,
        "snapshots_evaluated": snapshots,
        "snapshots_per_second": snapshots / run.wall_time if run.wall_time > 0.0 else None,
        "busy_time_s": sum(output.busy_time for output in outputs),
        "worker_processes": len(workers),
        "worker_hosts": sorted({worker.rsplit(":", 1)[0] for worker in workers}),
        "time_to_answer": times,
    }


def _header(run: BatchRun, context: ReportContext, tool: str) -> dict[str, Any]:
    return {
        "tool": tool,
        "scene": str(context.scene_file),
        "objects": list(run.scene.object_names),
        # Each object's class for scoring: identical instances share one (matched to true objects, not by name).
        "classes": list(ObjectClasses.of(run.scene).classes),
        "search_mode": _mode(run),
        "interrupted": run.interrupted,
    }


# --- evaluate -----------------------------------------------------------------------------------------


def evaluation_data(run: BatchRun, context: ReportContext) -> dict[str, Any]:
    """The ``evaluate`` report (the run's only setting) as plain data."""
    bags = [_bag_entry(run, 0, b, records=True) for b in range(len(run.bags))]
    evaluated = _bag_records(run, 0)
    times = {
        "overall": time_summary(_search_times(run, 0)),
        "bags": {str(run.bags[b].path): time_summary(output.search_times) for b, output in _evaluated(run, 0)},
    }
    return _header(run, context, "physics-mapper evaluate") | {
        "search": asdict(run.settings[0].params),
        "counts": _counts(run, 0),
        "overall": overall_summary(evaluated, ObjectClasses.of(run.scene)) if evaluated else None,
        "bags": bags,
        "run": _run_section(run, context, times),
    }


def _cm(metres: float | None) -> str:
    return MISSING if metres is None else f"{100.0 * metres:.2f}"


def _ms(seconds: float | None) -> str:
    return MISSING if seconds is None else f"{1000.0 * seconds:.0f}"


def _share(part: int, whole: int) -> str:
    return f"{100.0 * part / whole:.0f} % ({part})" if whole else MISSING


def _p(test: dict[str, Any] | None) -> str:
    return MISSING if test is None else f"{test['p_value']:.2g}"


def _search_text(search: dict[str, Any]) -> str:
    return ", ".join(f"{key} {value_text(value)}" for key, value in search.items())


def _mode_text(data: dict[str, Any], stopped: int, searches: int, deadline: float | None) -> str:
    if data["search_mode"] == "exhaustive":
        return "exhaustive (`--exhaustive`: every reachable configuration; the results do not depend on the machine)"
    return (
        f"deadline {value_text(deadline)} s per snapshot, as the node's tick ({stopped} of {searches} searches "
        "stopped at the deadline; where any did, the results depend on this machine's speed and load)"
    )


def deadline_note(times: dict[str, Any] | None, deadline: float) -> str | None:
    """A warning when exhaustive searches took longer than the node's deadline (at the 90th percentile)."""
    if times is None or times["p90_s"] <= deadline:
        return None
    return (
        f"the exhaustive searches took longer than the deadline ({_ms(times['p90_s'])} ms at the 90th percentile, "
        f"deadline {_ms(deadline)} ms): a node stopping at its deadline may choose otherwise; run without "
        "--exhaustive to see what it chooses in time, or give it a longer deadline (and a slower rate_hz)"
    )


def _run_text(run: dict[str, Any]) -> str:
    executor = run["executor"]
    size = ", ".join(f"{key} {value}" for key, value in executor.items() if key != "executor")
    rate = run["snapshots_per_second"]
    return (
        f"{executor['executor']} ({size}) on {run['host']}, started {run['started']}: "
        f"{run['snapshots_evaluated']} snapshots in {run['wall_time_s']:.1f} s"
        + (f" ({rate:.2f} snapshots/s)" if rate else "")
        + f", bags surveyed in {run['survey_time_s']:.1f} s"
    )


def _note_lines(data: dict[str, Any], times: dict[str, Any] | None, deadline: float) -> list[str]:
    note = deadline_note(times, deadline) if data["search_mode"] == "exhaustive" else None
    return [] if note is None else [f"- Note: {note}."]


def _times_text(times: dict[str, Any] | None) -> str:
    if times is None:
        return "no search"
    return ", ".join(f"{name} {_ms(times[f'{name}_s'])} ms" for name in ("p50", "p90", "p99", "max"))


def _tests_text(tests: dict[str, Any]) -> str:
    unit = tests["unit"]
    parts = []
    for estimate in ("chosen", "settled"):
        total = tests[f"{estimate}_vs_top"]["total"]
        parts.append(
            f"{estimate} p = {total['p_value']:.2g} (lower in {total['pairs_lower']} of {total['pairs']} "
            f"{unit}s, higher in {total['pairs_higher']})"
        )
    pairs = "the bags' mean errors" if unit == "bag" else "the scored snapshots (not independent: a guide)"
    return f"Paired Wilcoxon signed-rank tests of the total error against C11..1, pairs: {pairs}: " + "; ".join(parts)


def _error_table(summary: dict[str, Any], names: Sequence[str]) -> list[str]:
    mean = summary["mean_m"]
    lines = ["| object | C11..1 | chosen | settled |", "| --- | ---: | ---: | ---: |"]
    for name in names:
        lines.append(f"| {name} | " + " | ".join(_cm(mean[e]["per_object"][name]) for e in mean) + " |")
    lines.append("| **total** | " + " | ".join(f"**{_cm(mean[e]['total'])}**" for e in mean) + " |")
    return lines


def _summary_lines(summary: dict[str, Any], names: Sequence[str], classes: Sequence[str]) -> list[str]:
    """An overall summary for people: map shares, error table, tests, errors over every snapshot."""
    n = summary["snapshots"]
    lines = [
        f"{n} snapshots in {summary['bags']} bag(s): valid map {_share(summary['valid'], n)}, "
        f"fallback {_share(summary['fallback'], n)}, no map {_share(summary['no_map'], n)}; "
        f"C11..1 kept in {summary['top_kept']}.",
        "",
    ]
    if summary["mean_m"] is None:
        return [*lines, "No error against ground truth (no `/ground_truth` in the bags, or no map)."]
    matched = " (identical instances against the true object matched to them in each)" if classes != names else ""
    lines += [
        f"Mean position error over the {summary['scored']} snapshots with a map and ground truth{matched} [cm]:",
        "",
    ]
    lines += [*_error_table(summary, names), "", _tests_text(summary["tests"]) + " (per object: in the JSON).", ""]
    maps = summary["map_error_m"]
    lines.append(
        f"Over all {maps['snapshots']} snapshots with ground truth, a snapshot without a map counting with "
        f"C11..1: mean total error C11..1 {_cm(maps['top'])} cm, chosen {_cm(maps['chosen_or_top'])} cm, "
        f"settled {_cm(maps['settled_or_top'])} cm."
    )
    return [*lines, "", _identity_text(summary["identity"])]


def _identity_text(identity: dict[str, Any] | None) -> str:
    """The identity metrics of a summary in a sentence (distances in cm)."""
    if identity is None:
        return "No identity metrics (no ground truth)."
    return (
        f"Identity (map names matched to true objects within {_cm(identity['gate_m'])} cm, "
        f"{identity['frames']} snapshots): {identity['switches']} identity switches, "
        f"IDF1 {_fraction(identity['idf1'])}, "
        f"MOTA {_fraction(identity['mota'])}, MOTP {_cm(identity['motp_m'])} cm, {identity['misses']} misses and "
        f"{identity['false_positives']} false positives in {identity['true_objects']} true object-snapshots, "
        f"position error by identity {_cm(identity['identity_error_m'])} cm."
    )


def _fraction(value: float | None) -> str:
    return MISSING if value is None else f"{value:.3f}"


def _cell(text: object) -> str:
    """Input-controlled text (an error naming a bag) in a Markdown table cell: one line, escaped, no ``|``."""
    return printable(str(text)).replace("|", "\\|")


def _code(text: str) -> str:
    """Input-controlled text (a path, a command line) as Markdown code in a table or a line: escaped as
    :func:`_cell`, in a span of two backticks if it holds one."""
    escaped = _cell(text)
    return f"`` {escaped} ``" if "`" in escaped else f"`{escaped}`"


def _problem_lines(bags: Sequence[dict[str, Any]]) -> list[str]:
    problems = [bag for bag in bags if bag["status"] != "evaluated"]
    if not problems:
        return []
    lines = ["", "## Bags not evaluated", "", "| bag | status | error |", "| --- | --- | --- |"]
    lines += [f"| {_code(bag['path'])} | {bag['status']} | {_cell(bag['error'])} |" for bag in problems]
    return lines


def evaluation_markdown(data: dict[str, Any], png_name: str) -> str:
    """The ``evaluate`` report for people."""
    names, counts, overall, run = data["objects"], data["counts"], data["overall"], data["run"]
    stopped = overall["stopped_at_deadline"] if overall else 0
    searches = overall["snapshots"] if overall else 0
    title = "Evaluation (interrupted: partial)" if data["interrupted"] else "Evaluation"
    lines = [
        f"# {title} of {counts['bags']} bag(s) on {_code(data['scene'])}",
        "",
        _code(run["command"]),
        "",
        f"- Objects: {', '.join(names)}; search: {_search_text(data['search'])}.",
        f"- Searches: {_mode_text(data, stopped, searches, data['search']['deadline'])}.",
        *_note_lines(data, run["time_to_answer"]["overall"], data["search"]["deadline"]),
        f"- Run: {_run_text(run)}.",
        f"- Bags: {counts['evaluated']} evaluated, {counts['unreadable']} unreadable, {counts['unusable']} unusable, "
        f"{counts['failed']} failed, "
        f"{counts['not_evaluated']} not evaluated.",
        "",
        "## Overall",
        "",
    ]
    if overall is None:
        lines.append("No bag was evaluated.")
    else:
        lines += _summary_lines(overall, names, data["classes"])
        lines += ["", f"Time to answer (search time per snapshot): {_times_text(run['time_to_answer']['overall'])}."]
        lines += ["", f"![evaluation plots]({png_name})", "", "## Per bag", ""]
        lines += _bag_table(data["bags"], run["time_to_answer"]["bags"])
    lines += _problem_lines(data["bags"])
    return "\n".join(lines)


def _bag_table(bags: Sequence[dict[str, Any]], times: dict[str, Any]) -> list[str]:
    lines = [
        "| bag | storage | snapshots | valid | fallback | no map | total error C11..1 / chosen / settled [cm] "
        "| settled vs C11..1 p | identity switches | IDF1 | time p50 / p90 [ms] |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for bag in bags:
        summary = bag["summary"]
        if summary is None:
            continue
        n, mean, tests = summary["snapshots"], summary["mean_m"], summary["tests"]
        errors = MISSING if mean is None else " / ".join(_cm(mean[e]["total"]) for e in mean)
        p = MISSING if tests is None else _p(tests["settled_vs_top"]["total"])
        time, identity = times[bag["path"]], summary["identity"]
        switches, idf1 = (MISSING, MISSING) if identity is None else (identity["switches"], _fraction(identity["idf1"]))
        lines.append(
            f"| {_code(bag['path'])} | {bag['storage']} | {n} | {_share(summary['valid'], n)} | "
            f"{_share(summary['fallback'], n)} | {_share(summary['no_map'], n)} | {errors} | {p} | "
            f"{switches} | {idf1} | {_ms(time['p50_s'])} / {_ms(time['p90_s'])} |"
        )
    return lines


def overall_lines(data: dict[str, Any]) -> list[str]:
    """``evaluate``'s report in a few lines, for the terminal."""
    counts, overall = data["counts"], data["overall"]
    lines = [
        f"evaluated {counts['evaluated']} of {counts['bags']} bag(s) ({counts['unreadable']} unreadable, "
        f"{counts['unusable']} unusable, "
        f"{counts['failed']} failed, {counts['not_evaluated']} not evaluated)"
        + ("; interrupted" if data["interrupted"] else "")
    ]
    if overall is None:
        return lines
    n = overall["snapshots"]
    lines[0] += (
        f", {n} snapshots: valid map {_share(overall['valid'], n)}, fallback {_share(overall['fallback'], n)}, "
        f"no map {_share(overall['no_map'], n)}"
    )
    mean = overall["mean_m"]
    if mean is not None:
        lines.append(
            f"mean total position error over the {overall['scored']} snapshots with a map and ground truth: "
            + ", ".join(f"{label} {_cm(mean[e]['total'])} cm" for e, label in zip(mean, ESTIMATE_NAMES, strict=True))
        )
        test = overall["tests"]["settled_vs_top"]["total"]
        lines.append(
            f"settled vs C11..1: paired Wilcoxon p = {test['p_value']:.2g} over {test['pairs']} "
            f"{overall['tests']['unit']}s (lower in {test['pairs_lower']}, higher in {test['pairs_higher']})"
        )
    identity = overall["identity"]
    if identity is not None:
        lines.append(
            f"identity: {identity['switches']} switches, IDF1 {_fraction(identity['idf1'])}, "
            f"MOTA {_fraction(identity['mota'])}, position error by identity {_cm(identity['identity_error_m'])} cm"
        )
    return lines


def write_evaluation(run: BatchRun, context: ReportContext, output_dir: Path) -> ReportFiles:
    """Write ``report.json``, ``report.md`` and ``report.png`` into ``output_dir``."""
    data = evaluation_data(run, context)
    figure = evaluation_figure(data, _search_times(run, 0))
    return write_outputs(output_dir, "report", figure, data, evaluation_markdown(data, "report.png"))


# --- sweep --------------------------------------------------------------------------------------------


def _criterion_key(criterion: Criterion) -> Callable[[tuple[int, dict[str, Any]]], tuple[float, ...]]:
    """Sort key of (index, overall summary): smaller is better."""

    def key(item: tuple[int, dict[str, Any]]) -> tuple[float, ...]:
        index, overall = item
        maps = overall["map_error_m"]
        settled = maps["settled_or_top"] if maps else float("inf")
        if criterion == "valid":
            return (-overall["valid_share"], settled, index)
        return (maps[f"{criterion}_or_top"], -overall["valid_share"], index)

    return key


def best_setting(settings: Sequence[dict[str, Any]], criterion: Criterion) -> tuple[int | None, Criterion]:
    """The best complete setting by ``criterion`` (index) and the criterion used.

    Only settings evaluated on every readable bag compete (``complete``). Without any ground truth
    an error criterion cannot be used, and the valid share decides.
    """
    complete = [(s["index"], s["overall"]) for s in settings if s["complete"] and s["overall"] is not None]
    if not complete:
        return None, criterion
    if criterion != "valid" and any(overall["map_error_m"] is None for _, overall in complete):
        criterion = "valid"
    return min(complete, key=_criterion_key(criterion))[0], criterion


def grid_of(settings: Sequence[Setting]) -> dict[str, list[Any]]:
    """Each varied key's values, in the settings' order."""
    grid: dict[str, list[Any]] = {}
    for setting in settings:
        for key, value in setting.varied:
            if value not in grid.setdefault(key, []):
                grid[key].append(value)
    return grid


def sweep_data(run: BatchRun, context: ReportContext, criterion: Criterion) -> dict[str, Any]:
    """The ``sweep`` report as plain data; ``best`` names the best setting (``params_file`` added by the writer)."""
    readable = [b for b, bag in enumerate(run.bags) if bag.error is None]
    settings = []
    for index, setting in enumerate(run.settings):
        evaluated = _bag_records(run, index)
        settings.append(
            {
                "index": index,
                "label": setting.label,
                "varied": dict(setting.varied),
                "search": asdict(setting.params),
                "association": asdict(setting.association),
                "counts": _counts(run, index),
                "complete": all((index, b) in run.outputs for b in readable),
                "overall": overall_summary(evaluated, ObjectClasses.of(run.scene)) if evaluated else None,
                "bags": [_bag_entry(run, index, b, records=False) for b in range(len(run.bags))],
            }
        )
    best, used = best_setting(settings, criterion)
    times = {"settings": [time_summary(_search_times(run, index)) for index in range(len(run.settings))]}
    return _header(run, context, "physics-mapper sweep") | {
        "grid": grid_of(run.settings),
        "criterion": {"name": used, "asked": criterion, "text": CRITERIA[used]},
        "best": None if best is None else {"index": best, "label": settings[best]["label"]},
        "bags": [_sweep_bag(run, b) for b in range(len(run.bags))],
        "settings": settings,
        "run": _run_section(run, context, times),
    }


def _sweep_bag(run: BatchRun, bag: int) -> dict[str, Any]:
    """A bag of a sweep: its error if it cannot be used (the same for every setting), its snapshots."""
    surveyed = run.bags[bag]
    outputs = [run.outputs[(s, bag)] for s in range(len(run.settings)) if (s, bag) in run.outputs]
    error = surveyed.error or next((output.error for output in outputs if output.error is not None), None)
    snapshots = next((len(output.records) for output in outputs if output.error is None), None)
    return {"path": str(surveyed.path), "storage": surveyed.storage, "error": error, "snapshots": snapshots}


def sweep_markdown(data: dict[str, Any], png_name: str, params_file: str | None) -> str:
    """The ``sweep`` report for people: the table of settings, the best, the heat maps."""
    run, grid, keys = data["run"], data["grid"], list(data["grid"])
    title = "Sweep (interrupted: partial)" if data["interrupted"] else "Sweep"
    criterion = data["criterion"]
    lines = [
        f"# {title} of {len(data['settings'])} search settings over {len(data['bags'])} bag(s) "
        f"on {_code(data['scene'])}",
        "",
        _code(run["command"]),
        "",
        "- Grid: " + "; ".join(f"{key} = {', '.join(map(value_text, values))}" for key, values in grid.items()) + ".",
        f"- Searches: {SEARCH_MODES[data['search_mode']]}; run: {_run_text(run)}.",
        f"- Criterion ({criterion['name']}): {criterion['text']}."
        + (
            f" Asked for {criterion['asked']}, but no bag has a ground truth."
            if criterion["asked"] != criterion["name"]
            else ""
        ),
    ]
    best = data["best"]
    if best is None:
        lines.append("- Best: none (no setting has results from every usable bag).")
    elif params_file is None:
        reason = _cell(best["params_file_error"])
        lines.append(f"- Best: #{best['index']} ({best['label']}); no parameters file: {reason}.")
    else:
        lines.append(
            f"- Best: #{best['index']} ({best['label']}), as node parameters in {_code(params_file)}: "
            f"{_code(f'physics-mapper node --ros-args --params-file {params_file}')}."
        )
    if best is not None:
        times = run["time_to_answer"]["settings"][best["index"]]
        lines += _note_lines(data, times, data["settings"][best["index"]]["search"]["deadline"])
    header = [
        "#",
        *keys,
        "valid",
        "fallback",
        "no map",
        "C11..1",
        "chosen",
        "settled",
        "map error",
        "settled vs C11..1 p",
        "switches",
        "IDF1",
    ]
    lines += [
        "",
        'Total position errors [cm]: means over the snapshots with a map and ground truth; "map error": the '
        "settled map over every snapshot with ground truth, C11..1 where there is no map. Time: search time p50.",
        "",
        "| " + " | ".join([*header, "time p50 [ms]"]) + " |",
        "| " + " | ".join(["---:"] * (len(header) + 1)) + " |",
    ]
    for setting, times in zip(data["settings"], run["time_to_answer"]["settings"], strict=True):
        lines.append("| " + " | ".join(_setting_row(setting, keys, best, times)) + " |")
    lines += ["", f"![heat maps of error and validity]({png_name})"]
    lines += _problem_lines([bag | {"status": "unreadable"} for bag in data["bags"] if bag["error"] is not None])
    return "\n".join(lines)


def _setting_row(
    setting: dict[str, Any], keys: Sequence[str], best: dict[str, Any] | None, times: dict[str, Any] | None
) -> list[str]:
    marker = " **best**" if best is not None and best["index"] == setting["index"] else ""
    incomplete = "" if setting["complete"] else " (incomplete)"
    cells = [f"{setting['index']}{marker}{incomplete}", *(value_text(setting["varied"][key]) for key in keys)]
    overall = setting["overall"]
    if overall is None:
        return [*cells, *([MISSING] * 10), MISSING]
    n, mean, maps, tests = overall["snapshots"], overall["mean_m"], overall["map_error_m"], overall["tests"]
    cells += [_share(overall[kind], n) for kind in ("valid", "fallback", "no_map")]
    cells += [MISSING] * 3 if mean is None else [_cm(mean[e]["total"]) for e in mean]
    cells += [_cm(None if maps is None else maps["settled_or_top"])]
    cells += [_p(None if tests is None else tests["settled_vs_top"]["total"])]
    identity = overall["identity"]
    cells += [MISSING] * 2 if identity is None else [str(identity["switches"]), _fraction(identity["idf1"])]
    return [*cells, _ms(None if times is None else times["p50_s"])]


def write_sweep(
    run: BatchRun, context: ReportContext, criterion: Criterion, output_dir: Path
) -> tuple[ReportFiles, Path | None]:
    """Write ``sweep.json``, ``sweep.md``, ``sweep.png`` and, if a setting is best, its node parameters
    file ``best_params.yaml`` (returned; None when there is no best or the node would refuse it).

    The parameters file says of how many settings it is the best (those with results from every usable
    bag, and whether the run was interrupted), and is renamed into place with the report, never before.
    """
    data = sweep_data(run, context, criterion)
    best, params_path, params_text = data["best"], None, ""
    if best is not None:
        setting = run.settings[best["index"]]
        compared = sum(1 for entry in data["settings"] if entry["complete"])
        among = f"{len(run.settings)}" if compared == len(run.settings) else f"{compared} of {len(run.settings)}"
        stopped = " (interrupted: the others did not finish)" if run.interrupted else ""
        header = [
            f"physics-mapper sweep: the best of {among} search settings{stopped} ({setting.label}),",
            f"by {data['criterion']['name']}: {data['criterion']['text']};",
            f"over {_counts(run, best['index'])['evaluated']} bag(s), searches {data['search_mode']}.",
            f"Made by: {context.command}",
            f"Run the node with it: physics-mapper node --ros-args --params-file {output_dir / PARAMS_FILE}",
        ]
        note = deadline_note(data["run"]["time_to_answer"]["settings"][best["index"]], setting.params.deadline)
        if data["search_mode"] == "exhaustive" and note is not None:
            header.append(f"Note: {note}.")
        try:
            params_text = node_parameters_yaml(context.scene_file, setting.params, header, setting.association)
        except InputError as error:
            best["params_file_error"] = str(error)
        else:
            params_path = output_dir / PARAMS_FILE
            best["params_file"] = PARAMS_FILE
    markdown = sweep_markdown(data, "sweep.png", None if params_path is None else str(params_path))
    extra = [] if params_path is None else [(params_path, params_text)]
    return write_outputs(output_dir, "sweep", sweep_figure(data), data, markdown, extra), params_path
