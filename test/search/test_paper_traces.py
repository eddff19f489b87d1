"""The shipped paper problems give the traces recorded before the search was rebuilt from parts.

Each problem is solved to its end with ``joint``, ``grouped`` and the default strategy; every visited
node's decisions (code, outcome, bounded, parent, group, the colliding pair, the object that moved most,
how its settling stopped, the conflict it taught) must be the recorded ones, one by one, and its numbers
(p(C), depth, J, simulated time) within a tolerance: the recordings were made on another machine.
``python test/search/test_paper_traces.py`` writes the recordings anew (only to capture a deliberate
change).
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from physics_mapper.model.scene import Strategy

REPO = Path(__file__).resolve().parents[2]
RECORDINGS = REPO / "test" / "data" / "paper_traces"
PROBLEMS = ("stack", "pyramid", "peg_in_hole", "sphere_groove")
STRATEGIES: tuple[Strategy, ...] = ("joint", "grouped", "conflict")
#: Numbers of a trace entry, compared within these tolerances (p(C) relative, the others in m and s).
NUMBERS = {"probability": 1e-9, "depth": 2e-4, "jitter": 5e-4, "settled_time": 0.05}


def solved(problem: str, strategy: Strategy) -> dict[str, Any]:
    """The problem's result under ``strategy`` (the problem's other search keys as shipped), as JSON data."""
    from physics_mapper.model.scene_files import load_problem
    from physics_mapper.physics.checker import PhysicsChecker
    from physics_mapper.search.report import result_dict
    from physics_mapper.search.strategy import make_search

    loaded = load_problem(REPO / "config" / "problems" / f"{problem}.yaml", lambda _: None)
    params = replace(loaded.scene.search, strategy=strategy)
    with PhysicsChecker(loaded.scene) as checker:
        result = make_search(checker, loaded.hypotheses, params).run(None)
    data = json.loads(json.dumps(result_dict(result, loaded.scene.object_names)))  # tuples as JSON lists
    return {"valid": data["valid"], "code": data["code"], "end": data["stats"]["end"], "trace": data["trace"]}


def recording(problem: str, strategy: Strategy) -> Path:
    return RECORDINGS / f"{problem}_{strategy}.json"


@pytest.mark.parametrize("strategy", STRATEGIES)
@pytest.mark.parametrize("problem", PROBLEMS)
def test_the_paper_problems_give_the_recorded_traces(problem: str, strategy: Strategy) -> None:
    expected = json.loads(recording(problem, strategy).read_text())
    got = solved(problem, strategy)
    assert (got["valid"], got["code"], got["end"]) == (expected["valid"], expected["code"], expected["end"])
    assert len(got["trace"]) == len(expected["trace"])
    for index, (entry, wanted) in enumerate(zip(got["trace"], expected["trace"], strict=True)):
        decisions = {key: value for key, value in entry.items() if key not in NUMBERS}
        assert decisions == {key: value for key, value in wanted.items() if key not in NUMBERS}, index
        assert entry.keys() == wanted.keys(), index
        for key, tolerance in NUMBERS.items():
            if key in wanted:
                relative = tolerance if key == "probability" else None
                absolute = None if key == "probability" else tolerance
                assert entry[key] == pytest.approx(wanted[key], rel=relative, abs=absolute), (index, key)


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    RECORDINGS.mkdir(parents=True, exist_ok=True)
    for name in PROBLEMS:
        for search in STRATEGIES:
            recording(name, search).write_text(json.dumps(solved(name, search), indent=1) + "\n")
