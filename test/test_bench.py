"""``physics-mapper bench``: the physics cost figures of a problem, and its input errors."""

from __future__ import annotations

import re

from conftest import PROBLEMS
from core_builders import cli

from physics_mapper.bench.physics_costs import measure
from physics_mapper.model.scene_files import load_problem


def test_measure_times_every_operation_and_searches_exhaustively() -> None:
    problem = load_problem(PROBLEMS / "stack.yaml")
    costs = measure(problem, repeats=2)
    # Figures only, no timing assertions: the machines are noisy.
    assert min(costs.collision_check, costs.settle, costs.rebuilt_world_check, costs.search) > 0.0
    assert costs.persistent_world_check == costs.collision_check + costs.settle
    assert costs.search_stats.finished and costs.search_stats.visited > 0  # the queue emptied (T bounds the stack)


def test_bench_prints_each_figure() -> None:
    completed = cli("bench", str(PROBLEMS / "pyramid.yaml"), "--repeats", "2")
    assert completed.returncode == 0, completed.stderr
    out = completed.stdout
    for label in (
        "collision check (Rule 1)",
        "settle (Rule 2)",
        "world rebuilt each time",
        "persistent world speed-up",
    ):
        assert re.search(rf"{re.escape(label)}.*: +[0-9.]+ (us|ms|x)", out), label
    assert re.search(r"exhaustive search .* 125 visited", out)


def test_bench_refuses_bad_repeats_and_missing_files() -> None:
    completed = cli("bench", "--repeats", "0")
    assert completed.returncode == 2
    assert completed.stderr.strip() == "physics-mapper bench: error: --repeats must be at least 1, got 0"
    completed = cli("bench", "no/such.yaml")
    assert completed.returncode == 2
    assert completed.stderr.strip().endswith("no/such.yaml: cannot read file: No such file or directory")
