"""Search results as plain data (for JSON) and as text for people."""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import Fallback
from physics_mapper.physics.refine import OVERLAP_TOLERANCE, RefinedMap
from physics_mapper.search.results import Code, Counters, GroupResult, RuledOut, SearchResult, SearchStats, TraceEntry

#: The search parts' own counters (:attr:`SearchStats.part_counters`) in words: the diagnostics' keys and
#: the summary's (a counter not named here is shown by its own name).
COUNTER_WORDS = {
    "conflicts": "conflicts learned",
    "conflicts_kept": "conflicts kept",
    "skipped": "candidates skipped by conflicts",
    "ruled_out": "ranks ruled out before the search",
    "searched_again": "groups searched again under the chain rule",
    "local_settlings": "local settlings",
    "full_settlings": "full settlings",
}


def code_text(code: Code | None) -> str:
    """The paper's notation: ``(2, 1, 1)`` -> ``C211``; ranks above 9 are comma-separated."""
    if code is None:
        return "none"
    if all(rank < 10 for rank in code):
        return "C" + "".join(str(rank) for rank in code)
    return "C(" + ",".join(str(rank) for rank in code) + ")"


def counter_values(counters: Counters) -> list[tuple[str, str]]:
    """The parts' counters as (words, value) in their order, e.g. ``("conflicts learned", "3")``."""
    return [(COUNTER_WORDS.get(name, name), str(value)) for name, value in counters.items()]


def counters_text(counters: Counters) -> str:
    """The parts' counters on one line, e.g. ``3 conflicts learned, 0 conflicts kept``."""
    return ", ".join(f"{value} {words}" for words, value in counter_values(counters))


def pose_dict(pose: Pose) -> dict[str, list[float]]:
    return {"position": list(pose.position), "orientation": list(pose.orientation)}


def _poses(poses: tuple[Pose, ...] | None, names: tuple[str, ...]) -> dict[str, Any] | None:
    if poses is None:
        return None
    return {name: pose_dict(pose) for name, pose in zip(names, poses, strict=True)}


def trace_entry_dict(entry: TraceEntry) -> dict[str, Any]:
    """A trace entry with only the fields that apply to its outcome."""
    data = {key: value for key, value in asdict(entry).items() if value is not None}
    data["code"] = list(entry.code)
    if entry.parent is not None:
        data["parent"] = list(entry.parent)
    if entry.pair is not None:
        data["pair"] = list(entry.pair)
    return data


def ruled_out_text(ruling: RuledOut) -> str:
    """Why a rank was ruled out before the search, e.g. ``mug #1: collision with floor, 21 mm``."""
    if ruling.reason == "floating":
        return f"{ruling.object} #{ruling.rank}: floating, nothing within reach to rest on"
    depth = f"{ruling.depth * 1000:.0f} mm"
    if ruling.every_rank:
        return (
            f"{ruling.object} #{ruling.rank}: {ruling.reason} with {ruling.other} at each of its ranks, {depth} or more"
        )
    return f"{ruling.object} #{ruling.rank}: {ruling.reason} with {ruling.other}, {depth}"


def refinement_dict(refined: RefinedMap, names: tuple[str, ...]) -> dict[str, Any]:
    """How a refined map was made: start and depenetrated poses keyed by object name, iterations, overlaps (m)."""
    refined_names = tuple(names[index] for index in refined.objects)
    return {
        "start_poses": _poses(refined.start_poses, refined_names),
        "depenetrated_poses": _poses(refined.depenetrated_poses, refined_names),
        "iterations": refined.iterations,
        "converged": refined.converged,
        "initial_overlap": refined.initial_overlap,
        "remaining_overlap": refined.remaining_overlap,
        "settled": refined.settled,
    }


def stats_dict(stats: SearchStats) -> dict[str, Any]:
    """A search's counters, its parts' beside the others (``conflicts``, ... of the default search), how it
    ended (``end``; ``exhausted`` when every configuration was visited) and its speed."""
    data = asdict(stats)
    data.update(data.pop("part_counters"))
    data["exhausted"] = stats.exhausted
    data["configurations_per_second"] = stats.configurations_per_second
    return data


def group_dict(group: GroupResult, names: tuple[str, ...]) -> dict[str, Any]:
    """One interaction group of a result: its objects by name and its part of the answer."""
    return {
        "id": group.id,
        "objects": [names[i] for i in group.objects],
        "valid": group.valid,
        "code": None if group.code is None else list(group.code),
        "probability": group.probability,
        "jitter": group.jitter,
        "visited": group.visited,
        "end": group.end,
    }


def result_dict(result: SearchResult, names: tuple[str, ...]) -> dict[str, Any]:
    """Machine-readable result: poses keyed by object name."""
    return {
        "valid": result.valid,
        "code": None if result.code is None else list(result.code),
        "probability": result.probability,
        "jitter": result.jitter,
        "fallback_used": result.fallback_used,
        "fallback": result.fallback,
        "refinement": None if result.refinement is None else refinement_dict(result.refinement, names),
        "poses": _poses(result.poses, names),
        "settled_poses": _poses(result.settled_poses, names),
        "object_jitters": None
        if result.object_jitters is None
        else dict(zip(names, result.object_jitters, strict=True)),
        "stats": stats_dict(result.stats),
        "groups": [group_dict(group, names) for group in result.groups],
        "ruled_out": [asdict(ruling) for ruling in result.ruled_out],
        "trace": [trace_entry_dict(entry) for entry in result.trace],
    }


def outcome_kind(entry: TraceEntry) -> str:
    """A node's outcome with who caused it: ``collision a-b``, ``unstable (a moved)`` or ``valid``."""
    if entry.outcome == "collision":
        assert entry.pair is not None
        return f"collision {entry.pair[0]}-{entry.pair[1]}"
    if entry.outcome == "unstable":
        return f"unstable ({entry.moved} moved)"
    return "valid"


def describe_entry(entry: TraceEntry) -> str:
    """One line: outcome and its evidence, e.g. ``collision cube_a-cube_b 3.1 cm``."""
    if entry.outcome == "collision":
        assert entry.depth is not None
        evidence = f"{entry.depth * 100:.1f} cm"
    else:
        evidence = f"J={entry.jitter:.4f}"
        if entry.settle_stop is not None:
            evidence += f" (settling stopped {_STOPS[entry.settle_stop]} at {entry.settled_time:.3f} s)"
    if entry.conflict is not None:
        evidence += " conflict {" + ", ".join(f"{name}:{rank}" for name, rank in entry.conflict) + "}"
    return f"{outcome_kind(entry)} {evidence}" + (" [bounded]" if entry.bounded else "")


_STOPS = {"rest": "at rest", "beyond_threshold": "beyond the jitter threshold"}


def search_ending(stats: SearchStats) -> str:
    """How a search's last run ended, for people."""
    if stats.end is None:
        return "stopped at the deadline"
    return {
        "exhausted": "exhausted: all nodes visited",
        "bounded": "bounded: the queue emptied; nodes below the bound were not expanded",
        "truncated": f"truncated: the queue emptied after the queue limit dropped {stats.dropped} nodes",
    }[stats.end]


def trace_tree(trace: tuple[TraceEntry, ...], groups: tuple[GroupResult, ...] = (), names: tuple[str, ...] = ()) -> str:
    """The search tree: each node under the node that queued it, in visiting order (one tree per group,
    headed by its objects when ``groups`` and the scene's object ``names`` are given).

    A node without a parent in the trace (the default search's candidate whose parents all hold a known
    conflict, or a node queued by one visited after the trace limit) heads a tree of its own. The ranks
    a group ruled out before its search come first, one line each, with why."""
    objects = {group.id: ", ".join(names[i] for i in group.objects) for group in groups} if names else {}
    lines = [
        f"{_group_head(group.id, objects)}ruled out before the search: {ruled_out_text(ruling)}"
        for group in groups
        for ruling in group.ruled_out
    ]
    traced = {(entry.group, entry.code) for entry in trace}
    children: dict[tuple[int | None, Code | None], list[tuple[int, TraceEntry]]] = {}
    tops: list[tuple[int, TraceEntry]] = []
    for index, entry in enumerate(trace, start=1):
        if entry.parent is None or (entry.group, entry.parent) not in traced:
            tops.append((index, entry))
        else:
            children.setdefault((entry.group, entry.parent), []).append((index, entry))

    def line(prefix: str, index: int, entry: TraceEntry) -> str:
        return f"{prefix}{code_text(entry.code)}  #{index}  p={entry.probability:.4g}  {describe_entry(entry)}"

    def walk(group: int | None, parent: Code, prefix: str) -> None:
        kids = children.get((group, parent), [])
        for position, (index, entry) in enumerate(kids):
            last = position == len(kids) - 1
            lines.append(line(prefix + ("└─ " if last else "├─ "), index, entry))
            walk(group, entry.code, prefix + ("   " if last else "│  "))

    for index, entry in tops:
        queued_by = "" if entry.parent is None else f"  (queued by {code_text(entry.parent)}, untraced)"
        lines.append(line(_group_head(entry.group, objects), index, entry) + queued_by)
        walk(entry.group, entry.code, "")
    return "\n".join(lines)


def _group_head(group: int | None, objects: dict[int | None, str]) -> str:
    """``group 3 (cube_a, cube_b): `` before a line of group 3 (empty for a search of every object)."""
    return "" if group is None else f"group {group}{f' ({objects[group]})' if group in objects else ''}: "


def refinement_text(refined: RefinedMap) -> str:
    """What the depenetration did, e.g. ``overlaps up to 3.0 cm resolved in 8 iterations``."""
    if refined.initial_overlap <= OVERLAP_TOLERANCE:
        return "no overlap"
    deepest = f"overlaps up to {refined.initial_overlap * 100:.1f} cm"
    if refined.converged:
        return f"{deepest} resolved in {refined.iterations} iterations"
    return f"{deepest}, {refined.remaining_overlap * 100:.1f} cm left after {refined.iterations} iterations"


def result_summary(result: SearchResult, fallback: Fallback) -> str:
    """A few lines: chosen code, p(C), J, validity, and how the search went (``fallback``: the search's)."""
    stats = result.stats
    if result.code is None:
        reason = "no collision-free configuration to settle" if fallback == "settled" else "nothing reported"
        head = f"no valid configuration (fallback: {fallback}, {reason})"
    elif result.valid:
        head = f"valid {code_text(result.code)}  p={result.probability:.4g}  J={result.jitter:.4f}"
    elif result.refinement is not None:
        head = (
            f"no valid configuration; fallback refine: {code_text(result.code)} refined "
            f"({refinement_text(result.refinement)}) and settled  J={result.jitter:.4f}"
        )
    else:
        head = f"no valid configuration; fallback settled {code_text(result.code)}  p={result.probability:.4g}"
    solved = sum(group.valid for group in result.groups)
    groups = f"{len(result.groups)} interaction groups, {solved} solved; " if len(result.groups) > 1 else ""
    counted = f"{counters_text(stats.part_counters)}\n" if any(stats.part_counters.values()) else ""
    if result.ruled_out:
        counted += f"ruled out before the search: {'; '.join(ruled_out_text(r) for r in result.ruled_out[:5])}"
        counted += f" (and {len(result.ruled_out) - 5} more)\n" if len(result.ruled_out) > 5 else "\n"
    return (
        f"{head}\n"
        f"{groups}visited {stats.visited} (expanded {stats.expanded}, bounded {stats.bounded}); "
        f"rejected: {stats.collisions} collision, {stats.unstable} unstable; valid {stats.valid}\n"
        f"{counted}"
        f"search time {stats.search_time * 1000:.1f} ms "
        f"({stats.configurations_per_second:.0f} configurations/s), {search_ending(stats)}"
    )
