"""A tick's report -> ``diagnostic_msgs/DiagnosticArray``.

One status for the search (name ``<node>: search``) with the key-values users debug with and,
from the node, how its ticks kept time since the previous message, then one status per object
(name ``<node>: hypotheses/<object>``) saying what its input is.
Every status's ``hardware_id`` is the node's fully qualified name, which tells apart nodes
of the same name in different namespaces on the shared ``/diagnostics`` topic.
Times are in seconds, p(C) and J as in the paper. Every message and value is clipped to
:data:`~physics_mapper.model.limits.MAX_DIAGNOSTIC_TEXT` characters, so no input can swell the
messages on the shared ``/diagnostics`` topic.
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from std_msgs.msg import Header

from physics_mapper.mapping.inputs import Level, ObjectStatus
from physics_mapper.mapping.mapper import TickReport
from physics_mapper.mapping.tick_statistics import TickPeriod
from physics_mapper.model.limits import MAX_DIAGNOSTIC_TEXT, clipped
from physics_mapper.msg_adapters.hypotheses import stamp_from_nanoseconds
from physics_mapper.search.report import code_text, counter_values, counters_text, refinement_text
from physics_mapper.search.results import GroupResult, SearchEnd, SearchResult, SearchStats

LEVELS = {Level.OK: DiagnosticStatus.OK, Level.WARN: DiagnosticStatus.WARN, Level.ERROR: DiagnosticStatus.ERROR}


def _number(value: float | None) -> str:
    return "" if value is None else f"{value:.6g}"


#: How a search (or a group's) ended, for people; None: nodes are still queued.
_ENDINGS: dict[SearchEnd | None, str] = {
    "exhausted": "exhausted (every node visited)",
    "bounded": "bounded (the queue emptied; nodes below the bound were not expanded)",
    "truncated": "truncated (the queue emptied after the queue limit dropped nodes)",
    None: "stopped at the deadline",
}


def _search_state(report: TickReport) -> str:
    result = report.result
    if report.engine_fault is not None:
        return "physics engine failed"
    if result is None:
        return "waiting for inputs"
    state = _ENDINGS[result.stats.end]
    if report.settling_in_progress is not None:
        group = "" if report.settling_group is None else f" of group {report.settling_group}"
        state += f", settling {code_text(report.settling_in_progress)}{group} continues next tick"
    kept = sum(group.kept for group in result.groups)
    if report.resumed:
        start = "resumed"
    elif kept:
        start = f"partly resumed ({kept} of {len(result.groups)} groups kept)"
    else:
        start = "new"
    return f"{start}, {state}"


def _group_key(group: GroupResult) -> str:
    return "group" if group.id is None else f"group {group.id}"


def _group_state(group: GroupResult, names: tuple[str, ...]) -> str:
    """``<objects>: <best so far>, <how its search stands>, <visited>, kept|new``."""
    if group.valid:
        best = f"solved {code_text(group.code)} (J={group.jitter:.4g})"
    elif group.code is not None:
        best = f"no valid configuration, fallback {code_text(group.code)}"
    else:
        best = "no valid configuration"
    progress = "searching" if group.end is None else _ENDINGS[group.end].split(" (")[0]
    objects = ", ".join(names[i] for i in group.objects)
    return f"{objects}: {best}, {progress}, {group.visited} visited, {'kept' if group.kept else 'new'}"


def _search_level_and_message(report: TickReport) -> tuple[Level, str]:
    result = report.result
    if report.engine_fault is not None:
        return Level.ERROR, report.engine_fault
    if result is None and not report.snapshot.missing:
        return Level.OK, "hypotheses of every object received; the next tick searches"
    if result is None:  # waiting is the normal state before an estimator starts: not an error
        return Level.WARN, f"waiting for hypotheses of: {', '.join(report.snapshot.missing)}"
    if result.valid:
        left_out = f"; left out: {', '.join(report.absent)}" if report.absent else ""
        text = f"valid {code_text(result.code)}, p(C)={result.probability:.4g}, J={result.jitter:.4g}{left_out}"
        if result.previous_map:
            text += "; the previous map's configuration (the search found no valid one of its own)"
        return Level.OK, text
    if result.refinement is not None:
        settled = "and settled" if result.refinement.settled else "(the deadline came before its settling)"
        refined = f"{code_text(result.code)} refined ({refinement_text(result.refinement)}) {settled}"
        return Level.WARN, f"no valid configuration; fallback refine: {refined}, J={result.jitter:.4g}"
    if result.code is not None:
        return Level.WARN, f"no valid configuration; fallback settled {code_text(result.code)}"
    ending = "" if result.stats.finished else " yet"
    fallback = report.settings.search.fallback
    if fallback == "settled":
        why = "fallback: settled, but no collision-free configuration to settle"
    elif fallback == "refine":
        why = "fallback: refine, its map is not ready yet"
    else:
        why = "fallback: none"
    groups = result.groups
    solved = f"; {sum(g.valid for g in groups)} of {len(groups)} groups solved" if len(groups) > 1 else ""
    return Level.WARN, f"no valid configuration found{ending} ({why}{solved}; nothing published)"


def search_values(report: TickReport) -> list[tuple[str, str]]:
    """The search status's key-values, in display order."""
    result: SearchResult | None = report.result
    stats = result.stats if result is not None else SearchStats()
    values = [
        ("best code", code_text(result.code) if result is not None else "none"),
        ("valid", str(result is not None and result.valid).lower()),
        ("fallback used", str(result is not None and result.fallback_used).lower()),
        ("fallback", report.settings.search.fallback),
        ("previous map", str(result is not None and result.previous_map).lower()),
        ("p(C)", _number(result.probability if result is not None else None)),
        ("J", _number(result.jitter if result is not None else None)),
        ("nodes visited", str(stats.visited)),
        ("nodes expanded", str(stats.expanded)),
        ("nodes bounded", str(stats.bounded)),
        ("nodes queued", str(stats.queued)),
        ("rejected by collision", str(stats.collisions)),
        ("rejected by stability", str(stats.unstable)),
        ("valid configurations", str(stats.valid)),
        *counter_values(stats.part_counters),  # what the search's parts count of their own (none: the paper's)
        ("search time [s]", f"{report.search_time:.6f}"),
        ("total search time [s]", f"{stats.search_time:.6f}"),
        ("deadline [s]", f"{report.settings.search.deadline:g}"),
        ("configurations per second", f"{stats.configurations_per_second:.1f}"),
        ("search", _search_state(report)),
        ("finished", str(result is not None and stats.finished).lower()),
        ("exhausted", str(result is not None and stats.exhausted).lower()),
    ]
    if result is not None:
        groups = result.groups
        values += [
            ("groups", str(len(groups))),
            ("groups solved", str(sum(group.valid for group in groups))),
            ("groups kept", str(sum(group.kept for group in groups))),
        ]
        names = tuple(o.name for o in report.snapshot.objects)
        values += [(_group_key(group), _group_state(group, names)) for group in groups]
        values += [
            (f"conflicts of {_group_key(group)}", counters_text(group.part_counters))
            for group in groups
            if group.part_counters
        ]
    values += instance_values(report)
    values += [(f"input {o.name}", f"{o.level.name}: {o.message}") for o in report.snapshot.objects]
    return values


def instance_values(report: TickReport) -> list[tuple[str, str]]:
    """What the map left out and what the association of instances did: ``absent`` (the objects the map
    leaves out, ``none``), and where the scene has classes of instances, ``instances <class>`` (instances
    with a track), ``births`` and ``ends`` (since the previous tick), ``detections outside every gate`` and
    ``second detections of an instance`` (since the start), and ``poses moved out of static bodies`` (this
    tick's, :mod:`~physics_mapper.mapping.seen_too_deep`)."""
    tracking = report.tracking
    values = [("absent", ", ".join(report.absent) or "none")]
    if not tracking.instances:
        return values
    values += [(f"instances {class_id}", str(count)) for class_id, count in tracking.instances]
    values += [
        ("births", ", ".join(tracking.births) or "none"),
        ("ends", ", ".join(tracking.ends) or "none"),
        ("detections outside every gate", str(tracking.outside)),
        ("second detections of an instance", str(tracking.doubles)),
        ("poses moved out of static bodies", str(report.moved_out)),
    ]
    return values


def tick_values(ticks: TickPeriod) -> list[tuple[str, str]]:
    """How the ticks kept time: counts since the node started, and the longest times since the last message."""
    return [
        ("ticks", str(ticks.ticks)),
        ("ticks since the last diagnostics", str(ticks.period_ticks)),
        ("search overruns", str(ticks.overruns)),
        ("late ticks", str(ticks.late)),
        ("max search time [s]", f"{ticks.max_search_time:.6f}"),
        ("max tick time [s]", f"{ticks.max_tick_time:.6f}"),
    ]


def _status(level: Level, name: str, message: str, hardware_id: str, values: list[tuple[str, str]]) -> DiagnosticStatus:
    return DiagnosticStatus(
        level=LEVELS[level],
        name=name,
        message=clipped(message, MAX_DIAGNOSTIC_TEXT),
        hardware_id=hardware_id,
        values=[KeyValue(key=key, value=clipped(value, MAX_DIAGNOSTIC_TEXT)) for key, value in values],
    )


def _object_status(status: ObjectStatus, node_name: str, hardware_id: str) -> DiagnosticStatus:
    return _status(
        status.level, f"{node_name}: hypotheses/{status.name}", status.message, hardware_id, list(status.details)
    )


def diagnostics_msg(
    report: TickReport, *, node_name: str, hardware_id: str, stamp_ns: int, ticks: TickPeriod | None = None
) -> DiagnosticArray:
    """The search status (its level the worst of search and inputs), then one status per object.

    ``stamp_ns``: the header stamp, integer nanoseconds (the node's clock). ``ticks``: the node's
    tick timing since the previous message (:func:`tick_values`), appended to the search status.
    """
    level, message = _search_level_and_message(report)
    level = max([level, *(o.level for o in report.snapshot.objects)])
    values = search_values(report) + ([] if ticks is None else tick_values(ticks))
    statuses = [_status(level, f"{node_name}: search", message, hardware_id, values)]
    statuses += [_object_status(o, node_name, hardware_id) for o in report.snapshot.objects]
    return DiagnosticArray(header=Header(stamp=stamp_from_nanoseconds(stamp_ns)), status=statuses)
