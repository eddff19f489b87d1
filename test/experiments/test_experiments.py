"""The paper's experiments: each runs at a reduced size and writes a real plot and a consistent summary.

One run of ``physics-mapper experiment all`` (3 runs, 300 particles) feeds the per-figure checks;
the full-size outputs are in ``reports/`` (``make paper``).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from conftest import SCENES
from core_builders import cli
from matplotlib.image import imread

from physics_mapper.model.geometry import make_pose
from physics_mapper.model.scene_files import load_scene
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.world import TIME_STEP

RUNS = 3
PARTICLES = 300
#: Seconds per search of the clutter experiment: a first answer on the tabletop and the tray, not the tower.
SEARCH_BUDGET = 0.05
ITERATIONS = 10
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """The output folder of one reduced ``experiment all`` run, and its stderr."""
    output = tmp_path_factory.mktemp("reports")
    sizes = ["--runs", str(RUNS), "--particles", str(PARTICLES), "--search-budget", str(SEARCH_BUDGET)]
    done = cli("experiment", "all", "-o", str(output), *sizes)
    assert done.returncode == 0, done.stderr
    return output, done.stderr


def summary(reports: tuple[Path, str], name: str) -> dict[str, Any]:
    return dict(json.loads((reports[0] / f"{name}.json").read_text()))


def all_numbers(data: Any) -> list[float]:
    if isinstance(data, bool) or data is None or isinstance(data, str):
        return []
    if isinstance(data, int | float):
        return [float(data)]
    values = data.values() if isinstance(data, dict) else data
    return [number for value in values for number in all_numbers(value)]


@pytest.mark.parametrize("name", ["fig4", "fig6", "fig8", "peg", "clutter"])
def test_each_experiment_writes_a_real_png_and_summaries(reports: tuple[Path, str], name: str) -> None:
    output, stderr = reports
    png = output / f"{name}.png"
    assert png.read_bytes()[:8] == PNG_MAGIC
    assert png.stat().st_size > 30_000
    height, width = imread(png).shape[:2]
    assert width >= 1000 and height >= 400
    data = summary(reports, name)
    assert data["experiment"] == name
    assert all(math.isfinite(v) for v in all_numbers(data))
    markdown = (output / f"{name}.md").read_text()
    assert markdown.startswith("# ") and f"({name}.png)" in markdown
    assert "Compared with the paper" in markdown
    assert f"physics-mapper experiment {name}" in markdown
    assert f"{name}: wrote" in stderr  # progress goes to stderr


def test_fig4_tree_is_visited_in_non_increasing_probability_like_the_papers(reports: tuple[Path, str]) -> None:
    data = summary(reports, "fig4")
    trace = data["trace"]
    probabilities = [entry["probability"] for entry in trace]
    assert probabilities == sorted(probabilities, reverse=True)
    assert data["root"]["outcome"] != "valid" and "parent" not in trace[0]
    visited: set[tuple[int, ...]] = set()
    for entry in trace:
        if "parent" in entry:
            assert tuple(entry["parent"]) in visited  # parents are visited before their children
        visited.add(tuple(entry["code"]))
    assert len(visited) == len(trace) == data["visited"]
    assert data["collisions"] + data["unstable"] + data["valid"] == data["visited"]
    assert data["queue_emptied"] is True
    assert all(entry["bounded"] == (entry["probability"] < data["probability_threshold"]) for entry in trace)
    valid = [entry for entry in trace if entry["outcome"] == "valid"]
    best = min(valid, key=lambda entry: entry["jitter"])
    assert data["chosen"]["code"] == best["code"] and data["chosen"]["jitter"] == best["jitter"]
    # As in the paper's Fig. 4: both rules reject nodes, and the first solution is later replaced.
    assert data["collisions"] > 0 and data["unstable"] > 0
    assert data["first_valid"] == valid[0] and valid[0]["code"] != best["code"]
    assert data["visiting_order"][0] == "C111"
    for hypotheses in data["hypotheses"].values():
        assert len(hypotheses) == 5
        assert math.isclose(sum(h["weight"] for h in hypotheses), 1.0)


def test_fig4_is_reproducible_from_its_seed(reports: tuple[Path, str], tmp_path: Path) -> None:
    seed = summary(reports, "fig4")["seed_used"]
    done = cli("experiment", "fig4", "-o", str(tmp_path), "--seed", str(seed))
    assert done.returncode == 0, done.stderr
    again = json.loads((tmp_path / "fig4.json").read_text())
    assert again["seed_used"] == seed and again["seeds_tried"] == 1
    assert again["visiting_order"] == summary(reports, "fig4")["visiting_order"]


def check_comparison(part: dict[str, Any], overall_mean_cm: dict[str, float]) -> None:
    """The paired test (one pair per run) and the paper's pooled test of one comparison of two estimates."""
    searches = RUNS * ITERATIONS
    pooled = part["kruskal_wallis_pooled"]
    assert pooled["samples_per_group"] == searches and 0.0 <= pooled["p_value"] <= 1.0
    assert math.isfinite(pooled["statistic"])
    paired = part["wilcoxon_paired_by_run"]
    assert paired["test"].startswith("Wilcoxon signed-rank")
    assert paired["pairs"] == RUNS and 0 <= paired["nonzero_pairs"] <= RUNS
    assert paired["runs_physics_lower"] + paired["runs_physics_higher"] == paired["nonzero_pairs"]
    assert math.isfinite(paired["statistic"]) and math.isfinite(paired["p_value"])
    # Exact and two-sided: n nonzero pairs cannot give p below 2 / 2^n; no nonzero pair gives p = 1.
    assert min(1.0, 2.0 / 2 ** paired["nonzero_pairs"]) <= paired["p_value"] <= 1.0
    for estimate, means in paired["per_run_mean_cm"].items():
        assert len(means) == RUNS
        # Every run has the same number of iterations: the mean of the per-run means is the overall mean.
        assert math.isclose(sum(means) / RUNS, overall_mean_cm[estimate])
    assert part["physics_lower"] + part["physics_higher"] + part["equal"] == searches


def check_tracking_counts(data: dict[str, Any], sigma_rotation_degrees: float) -> None:
    searches = RUNS * ITERATIONS
    assert data["runs"] == RUNS and data["particles"] == PARTICLES and data["iterations"] == ITERATIONS
    assert data["searches"] == data["searches_finished"] == searches
    assert sum(data["root_outcomes"].values()) == searches
    assert math.isclose(data["sigma_rotation_rad"], math.radians(sigma_rotation_degrees))
    assert math.isclose(data["sigma_rotation_deg"], sigma_rotation_degrees)
    spread = data["hypothesis_spread_cm"]
    top_m = data["top_m"]
    # Over M points, the mean squared distance between pairs is 2M / (M - 1) times the mean squared from the mean.
    assert math.isclose(spread["rms_pairwise"], math.sqrt(2 * top_m / (top_m - 1)) * spread["rms_from_mean"])


def test_fig6_summary_is_consistent(reports: tuple[Path, str]) -> None:
    data = summary(reports, "fig6")
    check_tracking_counts(data, sigma_rotation_degrees=3.0)
    check_comparison(data, data["mean_total_cm"])  # the tests compare total errors
    check_comparison(data["loosened_rules"], data["loosened_rules"]["mean_total_cm"])
    searches = data["searches"]
    assert data["root_valid_searches"] <= data["valid_searches"] <= data["collision_free_searches"] <= searches
    # Without a valid configuration the physics-chosen map is C111 itself.
    assert data["equal"] >= searches - data["valid_searches"]
    for table in (data["without_physics"], data["with_physics"]):
        assert len(table["total_cm"]) == len(table["mean_per_object_cm"]) == ITERATIONS
        for name in data["objects"]:
            assert len(table["per_object_cm"][name]) == ITERATIONS
        for iteration in range(ITERATIONS):
            per_object = [table["per_object_cm"][name][iteration] for name in data["objects"]]
            assert math.isclose(table["total_cm"][iteration], sum(per_object))
            assert math.isclose(table["mean_per_object_cm"][iteration], sum(per_object) / len(per_object))
    totals = data["mean_total_cm"]
    assert math.isclose(totals["without_physics"], sum(data["without_physics"]["total_cm"]) / ITERATIONS)
    assert math.isclose(totals["with_physics"], sum(data["with_physics"]["total_cm"]) / ITERATIONS)
    assert math.isclose(data["mean_per_object_cm"]["without_physics"] * 3, totals["without_physics"])
    heights = data["cube_heights"]
    assert heights["cases"] == searches * len(data["objects"])
    assert heights["all_hypotheses_too_low"] <= heights["c111_too_low"]
    assert heights["all_hypotheses_too_high"] <= heights["c111_too_high"]
    assert heights["c111_too_low"] + heights["c111_too_high"] <= heights["cases"]
    assert heights["too_low_m"] == data["penetration_threshold_m"]
    assert heights["too_high_m"] == data["jitter_threshold_m"]
    markdown = (reports[0] / "fig6.md").read_text()
    assert f"{heights['all_hypotheses_too_low']} of these" in markdown
    assert "3° (0.0524 rad) per rotation axis" in markdown


def test_fig6_loosened_rules_use_the_same_hypotheses_and_accept_more(reports: tuple[Path, str]) -> None:
    data = summary(reports, "fig6")
    loosened = data["loosened_rules"]
    assert loosened["penetration_threshold_m"] > data["penetration_threshold_m"]
    assert loosened["jitter_threshold_m"] > data["jitter_threshold_m"]
    # Same seeds, same filters: the same C111 errors; every configuration valid under the scene's rules is
    # valid under looser ones.
    assert loosened["mean_total_cm"]["without_physics"] == data["mean_total_cm"]["without_physics"]
    per_run = "wilcoxon_paired_by_run", "per_run_mean_cm", "without_physics"
    assert loosened[per_run[0]][per_run[1]][per_run[2]] == data[per_run[0]][per_run[1]][per_run[2]]
    assert loosened["valid_searches"] >= data["valid_searches"]
    assert loosened["collision_free_searches"] >= data["collision_free_searches"]


def test_fig6_refined_map_exists_in_every_search_from_the_same_hypotheses(reports: tuple[Path, str]) -> None:
    data = summary(reports, "fig6")
    refine = data["refine"]
    searches = data["searches"]
    assert refine["fallback"] == "refine" and refine["maps"] == searches
    assert refine["valid_searches"] == data["valid_searches"]  # the same search, only the fallback differs
    assert refine["mean_total_cm"]["without_physics"] == data["mean_total_cm"]["without_physics"]
    check_comparison(refine, refine["mean_total_cm"])
    totals = refine["mean_total_cm"]
    assert math.isclose(refine["reduction_percent"], 100 * (1 - totals["with_physics"] / totals["without_physics"]))
    assert math.isclose(totals["with_physics"], sum(refine["with_physics"]["total_cm"]) / ITERATIONS)
    assert refine["start_at_most_likely"]["weighted_mean_start_vs_most_likely_start"]["pairs"] == data["runs"]
    assert "A map in" in (reports[0] / "fig6.md").read_text()


def test_fig8_refined_map_exists_in_every_search_from_the_same_hypotheses(reports: tuple[Path, str]) -> None:
    data = summary(reports, "fig8")
    refine = data["refine"]
    searches = data["searches"]
    assert refine["maps"] == searches and refine["in_groove"] <= searches
    assert refine["valid_searches"] == data["valid_searches"]
    assert refine["valid_searches"] + refine["fallback_searches"] == searches
    assert refine["mean_error_cm"]["without_physics"] == data["mean_error_cm"]["without_physics"]
    per_iteration = refine["per_iteration_cm"]
    assert all(
        xz <= e + 1e-9
        for xz, e in zip(per_iteration["with_physics_cross_section"], per_iteration["with_physics"], strict=True)
    )
    assert math.isclose(refine["mean_error_cm"]["with_physics"], sum(per_iteration["with_physics"]) / ITERATIONS)


def test_fig8_summary_is_consistent(reports: tuple[Path, str]) -> None:
    data = summary(reports, "fig8")
    check_tracking_counts(data, sigma_rotation_degrees=10.0)
    check_comparison(data, data["mean_error_cm"])
    searches = data["searches"]
    assert data["valid_searches"] + data["fallback_searches"] + data["no_estimate_searches"] == searches
    settled = searches - data["no_estimate_searches"]
    assert data["settled_in_groove"] + data["settled_elsewhere"] == settled
    assert data["equal"] >= data["no_estimate_searches"]  # nothing to settle: C1 is kept
    # One object: when all its hypotheses collide, so does C1.
    assert data["no_estimate_searches"] <= data["root_collision_searches"] <= searches
    collisions = sum(count for kind, count in data["root_outcomes"].items() if kind.startswith("collision "))
    assert data["root_collision_searches"] == collisions
    markdown = (reports[0] / "fig8.md").read_text()
    assert f"in {data['root_collision_searches']} of {searches} searches, and in" in markdown
    assert "10° (0.1745 rad) per rotation axis" in markdown
    per_iteration = data["per_iteration_cm"]
    for estimate in ("without_physics", "with_physics"):
        assert len(per_iteration[estimate]) == ITERATIONS
        # The cross-section error is a part of the position error.
        assert all(
            xz <= e + 1e-9
            for xz, e in zip(per_iteration[f"{estimate}_cross_section"], per_iteration[estimate], strict=True)
        )
        mean = sum(per_iteration[estimate]) / ITERATIONS
        assert math.isclose(data["mean_error_cm"][estimate], mean)


def test_clutter_summary_is_consistent(reports: tuple[Path, str]) -> None:
    data = summary(reports, "clutter")
    assert set(data["scenes"]) == {"tabletop", "tray_pile", "jenga_tower"}
    assert data["particles"] == PARTICLES and data["iterations"] == ITERATIONS
    for name, part in data["scenes"].items():
        scene = load_scene(SCENES / f"{name}.yaml")
        assert part["objects"] == list(scene.object_names)
        assert part["runs"] == RUNS and part["searches"] == RUNS * ITERATIONS
        assert part["search_budget_s"] == SEARCH_BUDGET
        # Every answer is a valid map or the fallback's, and each was timed when it appeared; so was
        # a map that a merge of groups withdrew before the budget ended.
        answered = part["searches"] - part["no_map"]
        assert part["valid"] + part["fallback_used"] == answered
        assert answered + part["map_withdrawn"] == part["first_map_s"]["count"]
        assert 0 <= part["map_withdrawn"] <= part["no_map"]
        assert part["first_valid_s"]["count"] == part["valid"] >= part["root_valid"]
        assert 0 <= part["root_bounded"] <= part["searches"]
        for estimate in ("C11..1", "chosen", "settled"):
            per_object = part["per_object_cm"][estimate]
            assert list(per_object) == part["objects"] and all(e >= 0.0 for e in per_object.values())
            assert math.isclose(part["mean_total_cm"][estimate], sum(per_object.values()))
            assert len(part["total_per_iteration_cm"][estimate]) == ITERATIONS
    markdown = (reports[0] / "clutter.md").read_text()
    assert f"--search-budget {SEARCH_BUDGET:g}" in markdown
    assert markdown.count("| total |") == 3


def test_peg_overlaps_are_rejected_with_the_wall_named_and_the_dropped_peg_ends_in_the_hole(
    reports: tuple[Path, str],
) -> None:
    data = summary(reports, "peg")
    overlapping = [h for h in data["hypotheses"] if h["label"] != "hovering above the hole"]
    assert overlapping and all(h["outcome"] == "collision" for h in overlapping)
    assert all(h["pair"][0] == "peg" and h["pair"][1].startswith("wall_") for h in overlapping)
    assert all(h["depth"] > data["penetration_threshold_m"] for h in overlapping)
    hovering = next(h for h in data["hypotheses"] if h["label"] == "hovering above the hole")
    assert hovering["outcome"] == "unstable"
    assert data["valid"] is False and data["fallback_used"] is True and data["chosen"] == hovering["code"]
    assert data["settled_in_hole"] is True and data["settled_error_cm"] < 1.0
    trajectory = data["trajectory"]
    times = [sample["time"] for sample in trajectory]
    assert times[0] == 0.0 and times == sorted(times) and math.isclose(times[-1], data["settle_time_s"])
    assert trajectory[-1]["position"] == data["settled_position"]
    assert trajectory[0]["position"][2] - trajectory[-1]["position"][2] > 0.05  # it fell
    assert 0.0 < data["entered_hole_at_s"] < data["settle_time_s"]


def test_trajectory_ends_where_settle_ends() -> None:
    scene = load_scene(SCENES / "sphere_groove.yaml")
    start = (make_pose((0.08, 0.0, 0.25)),)
    with PhysicsChecker(scene) as checker:
        snapshots = checker.trajectory(start, 0.5, 10 * TIME_STEP)
        settling = checker.settle(start, 0.5, 0.0)
    assert settling is not None
    assert len(snapshots) == 1 + round(0.5 / TIME_STEP) // 10
    assert snapshots[0].time == 0.0 and snapshots[0].poses == start
    assert snapshots[-1].poses == settling.settled_poses
    heights = [snapshot.poses[0].position[2] for snapshot in snapshots]
    assert heights[-1] < heights[0]


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["fig6", "--runs", "0"], "--runs must be at least 1"),
        (["fig8", "--particles", "2"], "--particles must be at least"),
        (["fig4", "--seed", "-1"], "--seed must not be negative"),
        # Below /dev/null nothing can exist, whatever else this machine holds.
        (["peg", "--scenes", "/dev/null/scenes"], "--scenes /dev/null/scenes is not a folder"),
        (["peg", "-o", "/dev/null/reports"], "cannot create /dev/null/reports: Not a directory"),
    ],
)
def test_bad_arguments_give_one_clear_line_and_exit_2(arguments: list[str], message: str, tmp_path: Path) -> None:
    done = cli("experiment", "-o", str(tmp_path), *arguments)  # a later -o wins
    assert done.returncode == 2
    errors = [line for line in done.stderr.splitlines() if line.startswith("physics-mapper experiment: error:")]
    assert len(errors) == 1 and message in errors[0]
    assert "Traceback" not in done.stderr
    assert not list(tmp_path.iterdir())


def test_an_output_path_that_is_a_file_is_refused(tmp_path: Path) -> None:
    blocker = tmp_path / "reports"
    blocker.write_text("not a folder")
    done = cli("experiment", "peg", "-o", str(blocker))
    assert done.returncode == 2 and "is not a folder" in done.stderr and "Traceback" not in done.stderr


def test_the_experiments_import_no_ros() -> None:
    probe = (
        "import importlib, sys\n"
        "for name in ('common', 'tracking', 'fig4', 'fig6', 'fig8', 'peg'):\n"
        "    importlib.import_module('physics_mapper.experiments.' + name)\n"
        "importlib.import_module('physics_mapper.commands.experiment')\n"
        "roots = {name.split('.')[0] for name in sys.modules}\n"
        "print(sorted(r for r in roots if r in ('rclpy', 'rmw') or r.endswith('_msgs') or r.startswith('rosidl')))\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True)
    assert done.stdout.strip().splitlines()[-1] == "[]"
