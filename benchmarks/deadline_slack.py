"""How far a node tick's search runs past its deadline, on a problem far too large to finish.

Run: ``.venv/bin/python benchmarks/deadline_slack.py [--ticks N] [--hypotheses M]``. Each
tick is :meth:`physics_mapper.mapping.mapper.Mapper.tick`, the very call whose ``search_time`` the
node reports in its diagnostics; inputs stay unchanged, so every tick resumes the search,
as in the node. Prints, per deadline, the overrun (search time - deadline) in milliseconds
beside the documented bound :data:`physics_mapper.mapping.mapper.DEADLINE_SLACK`.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

from physics_mapper.mapping.inputs import InputSettings, check_poses, check_weights
from physics_mapper.mapping.mapper import DEADLINE_SLACK, Mapper, MapperSettings
from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import SearchParams
from physics_mapper.model.scene_files import load_scene
from physics_mapper.scenarios.problems import COLUMN_SPACING

REPO = Path(__file__).resolve().parent.parent
DEADLINES = (0.02, 0.05, 0.1, 0.2)  # seconds


def feed_floating_cubes(mapper: Mapper, per_object: int) -> None:
    """``per_object`` hypotheses per cube, all floating apart: every configuration is simulated in full."""
    for column, name in enumerate(mapper.scene.object_names):
        raw = [((COLUMN_SPACING * column, 0.0, 0.3 + 0.01 * i), Pose((0, 0, 0)).orientation) for i in range(per_object)]
        scene = mapper.scene
        poses = check_poses(
            raw,
            frame_id=scene.frame_id,
            expected_frame=scene.frame_id,
            workspace=scene.workspace,
            stamp_ns=0,
            received=0,
        )
        mapper.inputs.add_poses(name, poses)
        mapper.inputs.add_weights(name, check_weights([1.0 / (i + 1) for i in range(per_object)], received=0.0))


def overruns_ms(deadline: float, ticks: int, per_object: int) -> list[float]:
    mapper = Mapper(load_scene(REPO / "config" / "scenes" / "pyramid.yaml"))
    settings = MapperSettings(SearchParams(deadline=deadline, probability_threshold=0.0), InputSettings(), 1.0)
    try:
        feed_floating_cubes(mapper, per_object)
        samples = []
        for _ in range(ticks):
            report = mapper.tick(0.0, settings)
            assert report.result is not None and not report.result.stats.finished, (
                "problem finished: raise --hypotheses"
            )
            samples.append((report.search_time - deadline) * 1000.0)
        return samples
    finally:
        mapper.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ticks", type=int, default=50, help="ticks per deadline (default 50)")
    parser.add_argument("--hypotheses", type=int, default=60, help="hypotheses per object (default 60)")
    args = parser.parse_args()
    print(f"{args.ticks} ticks per deadline, 3 objects x {args.hypotheses} hypotheses, every configuration simulated")
    print(f"documented bound DEADLINE_SLACK = {DEADLINE_SLACK * 1000:.0f} ms")
    print(f"{'deadline':>9} {'median':>9} {'p95':>9} {'max':>9}   overrun of the search time, ms")
    for deadline in DEADLINES:
        samples = sorted(overruns_ms(deadline, args.ticks, args.hypotheses))
        p95 = samples[min(len(samples) - 1, round(0.95 * (len(samples) - 1)))]
        print(f"{deadline * 1000:7.0f}ms {statistics.median(samples):9.2f} {p95:9.2f} {samples[-1]:9.2f}")


if __name__ == "__main__":
    main()
