"""Meshes settled locally agree with full settling: every verdict of a reduced suite of mesh bins."""

from __future__ import annotations

from dataclasses import replace

import pytest

from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.scenarios.crowded_suite import CrowdedCase, crowded_problem, full_verdicts, truth_is_valid
from physics_mapper.search.strategy import make_search

#: Bins of pybullet_data's random meshes small enough to search to the end in a test.
REDUCED_MESH_SUITE = (
    CrowdedCase("mesh_bin", 6, 3, 0),
    CrowdedCase("mesh_bin", 8, 3, 1),
    CrowdedCase("mesh_bin", 8, 3, 2),
)


@pytest.mark.parametrize("case", REDUCED_MESH_SUITE, ids=lambda case: case.label)
def test_local_settlings_of_meshes_agree_with_full_settlings(case: CrowdedCase) -> None:
    """Searched to the end with the trace kept: local settlings happened, every unstable and every valid
    verdict is the same when its configuration is settled again in full in a fresh world, and the
    answer is the configuration valid by construction."""
    problem = crowded_problem(case)
    assert truth_is_valid(problem)
    params = replace(problem.problem.scene.search, trace_limit=None)
    with PhysicsChecker(problem.problem.scene) as checker:
        result = make_search(checker, problem.problem.hypotheses, params).run(None)
    assert result.stats.part_counters["local_settlings"] > 0
    verdicts = full_verdicts(problem, result)
    assert verdicts["unstable"][0] > 0 and verdicts["unstable"][0] == verdicts["unstable"][1]
    assert verdicts["valid"][0] == verdicts["valid"][1]
    assert result.valid
