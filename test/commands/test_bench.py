"""``physics-mapper bench``: the benchmarks of ``benchmarks/``, their input errors, and where they write."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import PROBLEMS, REPO
from core_builders import PHYSICS_MAPPER, cli

from physics_mapper.model.scene_files import load_problem

sys.path.insert(0, str(REPO / "benchmarks"))  # the benchmarks import each other by name, as scripts do
from crowded import (
    ProblemRun,
    ReferenceSettling,
    Runner,
    SearchRun,
    beside_reference,
    chosen_cases,
    suite_cases,
    targets_text,
)
from instances import bag_deadline, spans
from mesh_scenes import TimedValid, counts, late
from physics_costs import measure
from with_package import run_with_package

#: What a benchmark run may change in the checkout: nothing but caches and build folders.
NOT_CHECKOUT = {".git", ".venv", "build", "install", "log", ".mypy_cache", ".ruff_cache", ".pytest_cache"}


def test_measure_times_every_operation_and_searches_exhaustively() -> None:
    problem = load_problem(PROBLEMS / "stack.yaml")
    costs = measure(problem, repeats=2)
    # Figures only, no timing assertions: the machines are noisy.
    assert min(costs.collision_check, costs.settle, costs.rebuilt_world_check, costs.search) > 0.0
    assert costs.persistent_world_check == costs.collision_check + costs.settle
    assert costs.search_stats.finished and costs.search_stats.visited > 0  # the queue emptied (T bounds the stack)


def test_bench_lists_the_benchmarks_and_not_the_modules_they_share() -> None:
    completed = cli("bench")
    assert completed.returncode == 0, completed.stderr
    listed = completed.stdout.split()
    assert {"physics_costs", "scale", "crowded", "mesh_costs", "deadline_slack"} <= set(listed)
    assert not {"live_node", "crowded_picture"} & set(listed)
    assert listed == sorted(path.stem for path in (REPO / "benchmarks").glob("*.py") if path.stem in listed)


def test_bench_physics_costs_prints_each_figure() -> None:
    completed = cli("bench", "physics_costs", str(PROBLEMS / "pyramid.yaml"), "--repeats", "2")
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


def test_bench_refuses_bad_repeats_missing_files_and_unknown_benchmarks() -> None:
    completed = cli("bench", "physics_costs", "--repeats", "0")
    assert completed.returncode == 2
    assert completed.stderr.strip() == "physics-mapper bench: error: --repeats must be at least 1, got 0"
    completed = cli("bench", "physics_costs", "no/such.yaml")
    assert completed.returncode == 2
    assert completed.stderr.strip().endswith("no/such.yaml: cannot read file: No such file or directory")
    completed = cli("bench", "no_such_benchmark")
    assert completed.returncode == 2
    assert completed.stderr.startswith("physics-mapper bench: error: no benchmark 'no_such_benchmark'; the benchmarks")
    completed = cli("bench", "scale", "--no-such-option")
    assert completed.returncode == 2
    assert "unrecognized arguments: --no-such-option" in completed.stderr
    completed = cli("bench", "mesh_scenes", "--runs", "0")
    assert completed.returncode == 2
    assert "--runs must be at least 1 and --budget positive (got 0 and 4)" in completed.stderr


def test_each_search_is_judged_against_the_deadline_scaled_to_the_reference_measured_beside_it() -> None:
    with ReferenceSettling() as reference:
        outcome, measured = beside_reference(reference, lambda: "searched")
    assert outcome == "searched" and measured > 0.0
    case = suite_cases(["bin"], sizes=[10], hypotheses=[5], seeds=1)[0]

    def problem(reference_s: float) -> ProblemRun:
        run = SearchRun(0.3, 0.3, 1, 0, 0, 0, 1)  # answered after 300 ms
        runs: dict[Runner, SearchRun] = {"conflict": run, "grouped": run, "joint": run}
        references: dict[Runner, float] = dict.fromkeys(runs, reference_s)
        return ProblemRun(case, references, True, runs, 0, 0, 0, 0, False, None)

    # 0.2 s x 12.6 / 6.3 ms = 400 ms on a machine as slow as that then; 200 ms at 6.3 ms.
    slow, fast = problem(0.0126), problem(0.0063)
    assert slow.answered_in_time("conflict") and not fast.answered_in_time("conflict")
    text = targets_text([slow, fast], [])
    assert "worst layout: 50%" in text
    # The miss is named, with its time and its deadline; the one in time is not.
    assert text.count(f"{case.label} (") == 1 and f"{case.label} (300 ms / 200 ms)" in text
    # Both problems have N = 10: no line through one size.
    assert "least-squares line: not fitted" in text


def test_a_bin_s_bags_are_searched_to_the_deadline_scaled_to_a_reference_measured_beside_each() -> None:
    assert bag_deadline(None, 0.35) == 0.35  # --deadline, or the node's 0.2 s: as given
    with ReferenceSettling() as reference:
        deadlines = {bag_deadline(reference, 0.35) for _ in range(3)}
    # Each bag's is measured anew: 0.2 s x its reference / 6.3 ms, whatever the fixed deadline.
    assert 0.35 not in deadlines and all(deadline > 0.0 for deadline in deadlines)


def test_a_bin_s_snapshots_without_a_valid_map_are_listed_in_spans() -> None:
    assert spans([0, 1, 2, 3, 4, 12, 14]) == "0-4, 12, 14"
    assert spans([7]) == "7" and spans([]) == "none"


def test_a_mesh_scene_s_searches_are_judged_against_its_tick_scaled_to_the_reference_beside_each() -> None:
    searches = [
        TimedValid(0.3, 0.0042, "run 1 iteration 1"),  # 0.4 s x 4.2 / 6.3 ms: 267 ms on a machine this fast, too late
        TimedValid(0.3, 0.0126, "run 1 iteration 2"),  # 800 ms on a machine this slow: in time
        TimedValid(0.45, 0.0126, "run 1 iteration 3"),  # beyond the fixed 0.4 s, within the scaled
        TimedValid(None, 0.0063, "run 1 iteration 4"),  # no valid map within the budget
    ]
    assert counts(0.4, searches) == (4, 3, 2, 2)
    assert late(0.4, searches) == ["run 1 iteration 1 (300 ms / 267 ms)"]


def test_bench_crowded_searches_only_the_layouts_asked_for() -> None:
    meshes = chosen_cases(2, False, ["mesh_bin"])
    assert [(case.layout, case.objects) for case in meshes] == [("mesh_bin", n) for n in (10, 10, 20, 20, 30, 30)]
    rows = chosen_cases(1, False, ["row", "mesh_bin"])
    assert {case.layout for case in rows} == {"row", "mesh_bin"}
    assert {case.weights for case in rows if case.layout == "row"} == {"drawn", "uniform"}
    assert chosen_cases(1, False, None) == suite_cases(seeds=1)
    completed = cli("bench", "crowded", "--layouts", "pile")
    assert completed.returncode == 2
    assert "--layouts: invalid choice: 'pile'" in completed.stderr


def test_a_side_by_side_runs_the_package_given_even_from_the_checkout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(REPO)  # "python -c" puts the working directory first: the checkout's own package
    copy = tmp_path / "copy"
    (copy / "physics_mapper").mkdir(parents=True)
    (copy / "physics_mapper" / "__init__.py").write_text('ROUND = "last"\n')
    script = (
        "import json, pickle, sys, physics_mapper\n"
        "print(json.dumps([physics_mapper.ROUND, pickle.load(sys.stdin.buffer)]))"
    )
    assert run_with_package(script, copy, 7, "the copy failed") == ["last", 7]
    with pytest.raises(RuntimeError, match=r"physics_mapper was imported from .*, not from"):
        run_with_package("print(1)", tmp_path, None, "no package there")


def checkout_files() -> dict[Path, float]:
    """Every file of the checkout but caches and build folders, with its modification time."""
    files = {}
    for path in REPO.rglob("*"):
        relative = path.relative_to(REPO)
        if relative.parts[0] in NOT_CHECKOUT or "__pycache__" in relative.parts or not path.is_file():
            continue
        files[relative] = path.stat().st_mtime
    return files


def test_bench_without_o_writes_nothing_in_the_checkout_and_with_o_its_plots(tmp_path: Path) -> None:
    before = checkout_files()
    command = [PHYSICS_MAPPER, "bench", "scale", "--quick", "--node-minutes", "0"]
    completed = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=280, check=False)
    assert completed.returncode == 0, completed.stderr
    assert "plots:" not in completed.stdout
    assert checkout_files() == before
    completed = subprocess.run(
        [*command, "-o", "plots"], cwd=tmp_path, capture_output=True, text=True, timeout=280, check=False
    )
    assert completed.returncode == 0, completed.stderr
    assert sorted(path.name for path in (tmp_path / "plots").iterdir()) == ["scale.png", "scale_groups.png"]
    assert checkout_files() == before
