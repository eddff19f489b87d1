"""What generating candidates costs: the conflict-free generator's work for the same candidates, this code's
and last round's side by side.

The conflict-free generator (``physics_mapper/search/conflict_free.py``) makes the default search's candidates in
the paper's order; a cheaper one makes the same candidates with fewer nodes taken up and less time. For each
problem (the crowded suite's layouts, N = 20, 30 and 50, M = 5 and 10, both weightings, and its bins of meshes,
N = 20 and 30, M = 5; seed ``--seed``), the default search runs from scratch until it has visited ``--visits``
candidates or ended, in this process and, with last round's package (``--previous DIR``, e.g. ``git archive main
physics_mapper | tar -x -C DIR``), in a subprocess given the same problem (pickled). Counted in each: the
nodes the generator took off its queue (calls of its ``_take_up``: a region of configurations, or in generators
before it a prefix of ranks), and the CPU seconds spent finding candidates (``ConflictDirectedCandidates.ready``).
Whether both
searches visit the same candidates of each group, in the same order, is checked and printed: where they do, the
figures compare the same work. Nodes are a count: they do not depend on the machine. Between groups the
interleaving may differ (the grouped search steps the group whose next candidate's bound is highest, and bounds
are a generator's own), so agreement is judged per group, over the shorter trace; a group that learned a conflict
elsewhere first (a collision, before its candidate holding it came) then visits other candidates.

Run: ``physics-mapper bench generator_cost [--visits N] [--seed N] --previous DIR``. Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from with_package import run_with_package

import physics_mapper
from physics_mapper.model.scene import Problem
from physics_mapper.scenarios.crowded_suite import CROWDED_LAYOUTS, CrowdedCase, crowded_problem

SIZES = (20, 30, 50)
HYPOTHESES = (5, 10)
#: The bins of meshes: N and M (the crowded suite's largest).
MESH_SIZES = (20, 30)
MESH_HYPOTHESES = 5
#: (group, code, outcome) of every trace entry, in order.
Visits = list[tuple[int | None, tuple[int, ...], str]]

SEARCH = """
import json, pickle, sys, time
from dataclasses import replace
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.conflict_directed import ConflictDirectedCandidates
from physics_mapper.search.conflict_free import ConflictFreeCandidates
from physics_mapper.search.strategy import make_search

work = {"taken_up": 0, "seconds": 0.0}
take_up, ready = ConflictFreeCandidates._take_up, ConflictDirectedCandidates.ready


def counted_take_up(self, node):
    work["taken_up"] += 1
    return take_up(self, node)


def timed_ready(self, stop_at):
    started = time.process_time()
    try:
        return ready(self, stop_at)
    finally:
        work["seconds"] += time.process_time() - started


ConflictFreeCandidates._take_up, ConflictDirectedCandidates.ready = counted_take_up, timed_ready
problem, visits = pickle.load(sys.stdin.buffer)
params = replace(problem.scene.search, strategy="conflict", trace_limit=None)
with PhysicsChecker(problem.scene) as checker:
    search = make_search(checker, problem.hypotheses, params)
    result = search.run(SLICE)
    while len(result.trace) < visits and not search.done:
        result = search.run(SLICE)
trace = [[e.group, list(e.code), e.outcome] for e in result.trace[:visits]]
print(json.dumps([work["taken_up"], work["seconds"], trace]))
"""
#: Seconds of search between two looks at the trace's length.
SLICE = 0.02


@dataclass(frozen=True)
class GeneratorWork:
    """One search's first visits (group, code, outcome), the nodes its generator took up and the CPU
    seconds it spent finding candidates."""

    visits: Visits
    taken_up: int
    seconds: float


def generator_work(problem: Problem, visits: int, package: Path) -> GeneratorWork:
    """The default search of ``problem`` with the ``physics_mapper`` package in folder ``package``, to
    ``visits`` candidates or its end, in a subprocess."""
    script = SEARCH.replace("SLICE", repr(SLICE))
    taken_up, seconds, trace = run_with_package(script, package, (problem, visits), f"the search with {package} failed")
    return GeneratorWork([(group, tuple(code), outcome) for group, code, outcome in trace], taken_up, seconds)


def agree_by_group(first: Visits, second: Visits) -> bool:
    """Whether each group's visits in ``first`` and ``second`` are the same over the shorter of the two."""
    by_group: dict[int | None, list[list[tuple[tuple[int, ...], str]]]] = defaultdict(lambda: [[], []])
    for index, trace in enumerate((first, second)):
        for group, code, outcome in trace:
            by_group[group][index].append((code, outcome))
    return all(a[: len(b)] == b[: len(a)] for a, b in by_group.values())


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="physics-mapper bench generator_cost", description=__doc__)
    parser.add_argument("--visits", type=int, default=100, help="candidates visited per search (default: 100)")
    parser.add_argument("--seed", type=int, default=0, help="the problems' seed (default: 0)")
    parser.add_argument("--previous", type=Path, required=True, help="folder holding last round's physics_mapper")
    args = parser.parse_args(argv)
    cases = [
        CrowdedCase(layout, objects, count, args.seed, weights)
        for weights in ("drawn", "uniform")
        for layout in CROWDED_LAYOUTS
        for objects in SIZES
        for count in HYPOTHESES
    ]
    cases += [CrowdedCase("mesh_bin", objects, MESH_HYPOTHESES, args.seed) for objects in MESH_SIZES]
    here = Path(physics_mapper.__file__).resolve().parent.parent
    print(f"default search, to {args.visits} candidates; now / last round's")
    print("| problem | visited | nodes taken up | ratio | generator CPU time | ratio | same candidates |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | --- |")
    totals = [0, 0, 0.0, 0.0]
    for index, case in enumerate(cases):
        problem = crowded_problem(case).problem
        now, before = generator_work(problem, args.visits, here), generator_work(problem, args.visits, args.previous)
        same = agree_by_group(now.visits, before.visits) and len(now.visits) == len(before.visits)
        print(
            f"| {case.label} | {len(now.visits)} | {now.taken_up} / {before.taken_up} | "
            f"{now.taken_up / max(before.taken_up, 1):.2f} | {now.seconds * 1e3:.0f} / {before.seconds * 1e3:.0f} ms | "
            f"{now.seconds / max(before.seconds, 1e-9):.2f} | {'yes' if same else 'no'} |",
            flush=True,
        )
        print(f"[{index + 1}/{len(cases)}] {case.label}", file=sys.stderr)
        for k, value in enumerate((now.taken_up, before.taken_up, now.seconds, before.seconds)):
            totals[k] += value
    print(
        f"\nin all: nodes taken up {totals[0]} / {totals[1]} ({totals[0] / max(totals[1], 1):.2f}), "
        f"generator CPU time {totals[2]:.2f} / {totals[3]:.2f} s ({totals[2] / max(totals[3], 1e-9):.2f})"
    )


if __name__ == "__main__":
    main()
