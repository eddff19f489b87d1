"""The conflict-free generator against an incremental optimiser, on the conflicts real ticks learned.

Run (OR-tools is not a dependency of the package: it goes into a folder of its own, pinned):
``.venv/bin/pip install --target /tmp/ortools_pkg --no-deps ortools==9.12.4544 protobuf==5.29.3 absl-py==2.1.0
immutabledict==4.2.1``, then ``PYTHONPATH=/tmp/ortools_pkg .venv/bin/python benchmarks/generator_vs_cpsat.py
SCENE BAG SNAPSHOT [--candidates 20]`` on a scene and a faulty bag that ``benchmarks/instances.py -o DIR`` wrote.

The bag is replayed offline as the node ticks (0.2 s a snapshot) up to snapshot ``SNAPSHOT``, whose
search then runs for 2 s with the default strategy; the conflicts its largest group learned are kept.
From scratch, with those conflicts known, the first ``--candidates`` conflict-free configurations are
then made twice, timed: by :class:`~physics_mapper.search.conflict_free.ConflictFreeCandidates` (the
search's generator), and by OR-tools' CP-SAT (one worker), as the most probable assignment avoiding
the conflicts (one Boolean per object and rank, exactly one rank per object, per conflict a clause that
some object leaves its rank set; the objective the sum of log w scaled by 1e6 and rounded) solved again
after each answer with a clause blocking it. Printed: the group's size, the conflicts, both times and
whether both gave the same codes in the same order (CP-SAT's objective rounds p(C), and it knows no tie
rule, so it may differ where p(C) ties).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from physics_mapper.bags.storage import read_bag
from physics_mapper.evaluation.snapshot_results import replay_offline
from physics_mapper.evaluation.snapshots import input_topics
from physics_mapper.model.scene_files import load_scene
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.best_first import weight_table
from physics_mapper.search.conflict_directed import ConflictDirectedCandidates
from physics_mapper.search.conflict_free import ConflictFreeCandidates
from physics_mapper.search.conflicts import ConflictStore
from physics_mapper.search.grouped import GroupedSearch
from physics_mapper.search.results import Code
from physics_mapper.search.strategy import make_search

#: log w is scaled by this and rounded: CP-SAT's objective is integral.
SCALE = 1_000_000


def learned(scene_file: Path, bag: Path, snapshot: int) -> tuple[list[list[float]], ConflictStore]:
    """Per object of the snapshot's largest group its weights by rank, and the conflicts its 2 s search learned."""
    scene = load_scene(scene_file)
    results = replay_offline(read_bag(bag, input_topics(scene)), scene, scene.search.deadline)
    with PhysicsChecker(scene) as checker:
        search = make_search(checker, results[snapshot].snapshot.hypotheses, scene.search)
        search.run(2.0)
        assert isinstance(search, GroupedSearch)
        group = max(search.groups(), key=lambda core: len(core.objects))
        assert isinstance(group.candidates, ConflictDirectedCandidates)
        return [list(w[1:]) for w in weight_table(group.hypotheses)], group.candidates.conflicts


def by_generator(weights: list[list[float]], store: ConflictStore, count: int) -> list[Code]:
    generator = ConflictFreeCandidates(weights, store, lambda _: False, queue_limit=1_000_000)
    codes: list[Code] = []
    while len(codes) < count and (found := generator.take()) is not None:
        codes.append(found[0])
    return codes


def by_cp_sat(weights: list[list[float]], store: ConflictStore, count: int) -> list[Code]:
    try:
        from ortools.sat.python import cp_model  # not a dependency: installed for this benchmark only
    except ImportError as error:
        raise SystemExit(f"OR-tools is needed here: see the module docstring ({error})") from error
    model = cp_model.CpModel()
    chosen = [[model.NewBoolVar(f"x{p}_{r}") for r in range(len(w))] for p, w in enumerate(weights)]
    for row in chosen:
        model.AddExactlyOne(row)
    for conflict in store:
        model.AddBoolOr(
            [
                chosen[p][r - 1]
                for p, ranks in zip(conflict.positions, conflict.ranks, strict=True)
                for r in range(1, len(weights[p]) + 1)
                if r not in ranks
            ]
        )
    model.Maximize(
        sum(
            round(SCALE * math.log(w)) * chosen[p][r] for p, ws in enumerate(weights) for r, w in enumerate(ws) if w > 0
        )
    )
    solver = cp_model.CpSolver()
    solver.parameters.num_workers = 1
    codes: list[Code] = []
    while len(codes) < count and solver.Solve(model) == cp_model.OPTIMAL:
        code = tuple(next(r + 1 for r, x in enumerate(row) if solver.Value(x)) for row in chosen)
        codes.append(code)
        model.AddBoolOr([chosen[p][r - 1].Not() for p, r in enumerate(code)])
    return codes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", type=Path, help="scene file that benchmarks/instances.py -o DIR wrote")
    parser.add_argument("bag", type=Path, help="its faulty bag")
    parser.add_argument("snapshot", type=int, help="the snapshot whose search's conflicts are kept (from 0)")
    parser.add_argument(
        "--candidates", type=int, default=20, help="conflict-free configurations made each way (default: 20)"
    )
    args = parser.parse_args()
    weights, store = learned(args.scene, args.bag, args.snapshot)
    timed = {}
    for name, make in (("generator", by_generator), ("CP-SAT", by_cp_sat)):
        started = time.perf_counter()
        codes = make(weights, store, args.candidates)
        timed[name] = (codes, time.perf_counter() - started)
    (ours, ours_s), (theirs, theirs_s) = timed["generator"], timed["CP-SAT"]
    print(
        f"{len(weights)} objects, {sum(map(len, weights))} ranks, {len(store)} conflicts: first {len(ours)} "
        f"candidates, generator {ours_s * 1000:.1f} ms, CP-SAT {theirs_s * 1000:.1f} ms "
        f"({theirs_s / ours_s:.1f}x); same codes in the same order: {ours == theirs}"
    )


if __name__ == "__main__":
    main()
