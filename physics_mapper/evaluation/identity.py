"""Identity metrics of maps over a bag: does each name stay on its object? (ROS-free)

Maps name their objects; the ground truth knows which true object is which only by its index (a
bin's identical boxes have no names of their own). Frame by frame, each named map object is matched
to the true objects by position, as multiple-object-tracking benchmarks do, with ``motmetrics``
(the CLEAR MOT and ID measures of the MOTChallenge):

* **Matching**: a map object and a true object may match when they are of one class (a named object
  is its own class, identical instances share theirs: :class:`~physics_mapper.evaluation.scoring.ObjectClasses`)
  and their centres are at most the *gate* apart; within a frame, pairs that matched in the frame
  before are kept while inside the gate, the rest are matched by minimum total distance (Hungarian).
* **Gate** (:func:`identity_gate`): :data:`IDENTITY_GATE`, or half the least distance between two true
  objects of one class in any frame where that is less. IDF1 counts a frame as an identity's when the
  name is within the gate of the object; were a name within the gate of two true objects of its class,
  any permutation of neighbours would score alike (parts 3 cm apart with a 5 cm gate), and the error by
  identity would be the spacing, not the map's.
* **Identity switches**: a true object matched to another map name than the last time it was matched
  (a swap of two names counts once for each of the two objects).
* **MOTA** = 1 - (misses + false positives + switches) / true objects summed over frames; a *miss*
  is a true object matched by no map object (frames without a map miss every object), a *false
  positive* a map object matched to none (a false detection or a second instance of one object).
* **MOTP**: the mean distance (m) of matched pairs.
* **IDF1**: the F1 score of the best one-to-one assignment of map names to true objects over the
  whole bag (IDTP: frames in which an object is matched to its assigned name; IDF1 = 2 IDTP /
  (true objects + map objects, summed over frames)). 1.0 when every name stays on one object.
* **Position error by identity**: for each true object, the map name that global assignment gives it
  and their mean centre distance (m) over the frames in which both are present, gate or not.

Frames without a ground truth are not scored.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import motmetrics
import numpy as np

from physics_mapper.evaluation.scoring import ObjectClasses

#: Metres between a map object's and a true object's centres beyond which they are never matched (at most:
#: :func:`identity_gate`).
IDENTITY_GATE = 0.05

#: motmetrics' names of the figures reported, and ours.
_FIGURES = {
    "num_frames": "frames",
    "num_objects": "true_objects",
    "num_predictions": "map_objects",
    "num_matches": "matches",
    "num_switches": "switches",
    "num_misses": "misses",
    "num_false_positives": "false_positives",
    "mota": "mota",
    "motp": "motp_m",
    "idf1": "idf1",
    "idp": "idp",
    "idr": "idr",
}

#: Our figures that are counts (whole numbers).
_COUNTS = {"frames", "true_objects", "map_objects", "matches", "switches", "misses", "false_positives"}

Position = Sequence[float]


@dataclass(frozen=True)
class IdentityFrame:
    """One snapshot: the true positions (m; the index is the object's identity) and the map's positions
    by name (None: no map)."""

    truth: Sequence[Position]
    estimate: Mapping[str, Position] | None


def identity_gate(frames: Sequence[IdentityFrame], objects: ObjectClasses | None = None) -> float:
    """Metres within which a map object matches a true one (module docstring): :data:`IDENTITY_GATE`, or half the
    least distance between two true objects' centres of one class (``objects``; None: all of one) in any frame."""
    least = 2.0 * IDENTITY_GATE
    for frame in frames:
        truth = np.asarray(frame.truth, dtype=float).reshape(-1, 3)
        groups = [tuple(range(len(truth)))] if objects is None else objects.groups
        for group in groups:
            members = [i for i in group if i < len(truth)]
            if len(members) > 1:
                centres = truth[members]
                distances = np.linalg.norm(centres[:, None, :] - centres[None, :, :], axis=2)
                least = min(least, float(np.min(distances[np.triu_indices(len(members), 1)])))
    return least / 2.0


def _distances(truth: np.ndarray, estimate: np.ndarray, gate: float, apart: np.ndarray | None = None) -> np.ndarray:
    """[true object, map object] centre distances in metres, NaN beyond ``gate`` or where ``apart`` (the
    same shape) is True: never matched."""
    if len(truth) == 0 or len(estimate) == 0:
        return np.empty((len(truth), len(estimate)))
    distances: np.ndarray = np.linalg.norm(truth[:, None, :] - estimate[None, :, :], axis=2)
    distances[distances > gate] = np.nan
    if apart is not None:
        distances[apart] = np.nan
    return distances


def _accumulate(
    frames: Sequence[IdentityFrame], gate: float, objects: ObjectClasses | None
) -> tuple[motmetrics.MOTAccumulator, list[str]]:
    """The frames as motmetrics events; map names are numbered in order of first appearance (motmetrics
    takes numbers), the list gives each number's name. With ``objects``, a name matches only true objects of
    its class."""
    accumulator = motmetrics.MOTAccumulator(auto_id=True)
    names: list[str] = []
    number: dict[str, int] = {}
    for frame in frames:
        estimate = dict(frame.estimate or {})
        for name in estimate:
            number.setdefault(name, len(number))
            if len(names) < len(number):
                names.append(name)
        truth = np.asarray(frame.truth, dtype=float).reshape(-1, 3)
        positions = np.asarray(list(estimate.values()), dtype=float).reshape(-1, 3)
        apart = None if objects is None else _apart(objects, len(truth), estimate)
        accumulator.update(
            list(range(len(truth))), [number[name] for name in estimate], _distances(truth, positions, gate, apart)
        )
    return accumulator, names


def objects_lain_on(
    truth: np.ndarray, estimate: Mapping[str, Sequence[float]], objects: ObjectClasses | None, gate: float
) -> dict[str, int | None]:
    """Each map object's nearest true object (index into ``truth``, N x 3, m) of its class (any, without
    ``objects``) within ``gate`` metres, the one it lies on; None where none is."""
    names = list(estimate)
    truth = np.asarray(truth, dtype=float).reshape(-1, 3)
    positions = np.asarray([estimate[name] for name in names], dtype=float).reshape(-1, 3)
    apart = None if objects is None else _apart(objects, len(truth), names)
    distances = _distances(truth, positions, gate, apart)
    return {
        name: None if np.isnan(column).all() else int(np.nanargmin(column))
        for name, column in zip(names, distances.T, strict=True)
    }


def _apart(objects: ObjectClasses, truth_count: int, names: Iterable[str]) -> np.ndarray:
    """[true object, map object] True where the two are of different classes."""
    class_of = objects.class_of
    true_classes = np.array(objects.classes[:truth_count], dtype=object)
    map_classes = np.array([class_of.get(name) for name in names], dtype=object)
    return np.asarray(true_classes[:, None] != map_classes[None, :], dtype=bool)


def _figures(computed: Mapping[str, Any]) -> dict[str, Any]:
    figures: dict[str, Any] = {}
    for theirs, ours in _FIGURES.items():
        value = float(computed[theirs])
        figures[ours] = None if np.isnan(value) else (int(value) if ours in _COUNTS else value)
    return figures


def _identities(
    frames: Sequence[IdentityFrame],
    names: Sequence[str],
    assignment: Mapping[str, Any],
    objects: ObjectClasses | None,
) -> list[dict[str, Any]]:
    """Per true object: its globally assigned map name (of its class) and their mean distance (m) where both are
    present."""
    truth_count = max((len(frame.truth) for frame in frames), default=0)
    class_of = {} if objects is None else objects.class_of
    assigned: dict[int, str] = {}
    for row, column in zip(assignment["rids"], assignment["cids"], strict=True):
        if row < truth_count and column < len(names):
            named = names[int(column)]
            if objects is None or class_of.get(named) == objects.classes[int(row)]:
                assigned[int(row)] = named
    identities = []
    for index in range(truth_count):
        name = assigned.get(index)
        errors = [
            float(np.linalg.norm(np.subtract(frame.estimate[name], frame.truth[index])))
            for frame in frames
            if name is not None and frame.estimate is not None and name in frame.estimate and index < len(frame.truth)
        ]
        identities.append(
            {
                "truth": index,
                "name": name,
                "frames": len(errors),
                "mean_error_m": float(np.mean(errors)) if errors else None,
            }
        )
    return identities


def identity_metrics(
    frames: Iterable[IdentityFrame], objects: ObjectClasses | None = None, gate: float | None = None
) -> dict[str, Any] | None:
    """The module's figures over ``frames`` (None without any): counts, MOTA, MOTP (m), IDF1 with its
    precision and recall, and per true object (``identities``) its name and position error by identity,
    with their mean (``identity_error_m``, over true objects that have a name). ``objects``: the scene's
    classes (None: any name may be any true object); ``gate`` (m): :func:`identity_gate` unless given."""
    scored = list(frames)
    if not scored:
        return None
    gate = identity_gate(scored, objects) if gate is None else gate
    accumulator, names = _accumulate(scored, gate, objects)
    computed = motmetrics.metrics.create().compute(
        accumulator, metrics=[*_FIGURES, "id_global_assignment"], return_dataframe=False
    )
    figures = _figures(computed)
    figures["gate_m"] = gate
    figures["identities"] = _identities(scored, names, computed["id_global_assignment"], objects)
    errors = [i["mean_error_m"] for i in figures["identities"] if i["mean_error_m"] is not None]
    figures["identity_error_m"] = float(np.mean(errors)) if errors else None
    return figures


def record_frames(records: Iterable[Mapping[str, Any]]) -> list[IdentityFrame]:
    """The identity frames of snapshot records (``positions`` of
    :func:`~physics_mapper.evaluation.snapshot_results.snapshot_result_dict`): those with a ground truth."""
    return [
        IdentityFrame(r["positions"]["truth"], r["positions"]["map"])
        for r in records
        if r["positions"]["truth"] is not None
    ]


def identity_text(figures: Mapping[str, Any] | None) -> str:
    """The figures in two lines for people (distances in cm)."""
    if figures is None:
        return "no identity metrics (no /ground_truth in the bag)"

    def value(name: str, scale: float = 1.0, unit: str = "") -> str:
        figure = figures[name]
        return "-" if figure is None else f"{figure * scale:.2f}{unit}"

    return (
        f"identity over {figures['frames']} snapshots with ground truth (matched within "
        f"{figures['gate_m'] * 100:.3g} cm): {figures['switches']} identity switches, IDF1 {value('idf1')}, "
        f"MOTA {value('mota')}, MOTP {value('motp_m', 100.0, ' cm')}\n"
        f"  {figures['misses']} misses, {figures['false_positives']} false positives in "
        f"{figures['true_objects']} true object-snapshots; position error by identity "
        f"{value('identity_error_m', 100.0, ' cm')} (mean over true objects)"
    )


def overall_identity_metrics(
    bags: Sequence[Sequence[IdentityFrame]], objects: ObjectClasses | None = None
) -> dict[str, Any] | None:
    """The figures of several bags together: counts summed, MOTA, MOTP and IDF1 over every frame (each bag
    its own sequence: a name in two bags is two tracks), ``identity_error_m`` the mean over every bag's true
    objects; ``switches_max`` the most switches in one bag. One gate for all: :func:`identity_gate` of every
    bag's frames."""
    gate = identity_gate([frame for frames in bags for frame in frames], objects)
    per_bag = [(list(frames), _accumulate(list(frames), gate, objects)) for frames in bags if frames]
    if not per_bag:
        return None
    host = motmetrics.metrics.create()
    computed = host.compute_many(
        [accumulator for _, (accumulator, _) in per_bag],
        metrics=list(_FIGURES),
        names=[str(i) for i in range(len(per_bag))],
        generate_overall=True,
    )
    figures = _figures(computed.loc["OVERALL"].to_dict())
    figures["gate_m"] = gate
    errors: list[float] = []
    switches: list[int] = []
    for frames, (accumulator, names) in per_bag:
        one = host.compute(accumulator, metrics=["num_switches", "id_global_assignment"], return_dataframe=False)
        switches.append(int(one["num_switches"]))
        errors += [
            i["mean_error_m"]
            for i in _identities(frames, names, one["id_global_assignment"], objects)
            if i["mean_error_m"] is not None
        ]
    figures["identity_error_m"] = float(np.mean(errors)) if errors else None
    figures["switches_max"] = max(switches)
    return figures
