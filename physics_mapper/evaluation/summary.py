"""A batch run's figures, per bag and overall, from its snapshots' records (ROS-free).

A record is one snapshot's :func:`~physics_mapper.evaluation.snapshot_results.snapshot_result_dict`. Its map is
*valid* (both rules hold), a *fallback* (nothing valid; ``fallback`` chose one) or there is *no map*.
Errors are position errors in metres against ``/ground_truth`` of the three estimates of
:data:`~physics_mapper.evaluation.snapshot_results.ESTIMATES` (``top`` = C11..1, ``chosen``, ``settled``):

* ``mean_m``: per object and in total (the sum over objects), averaged over the *scored* snapshots
  (a ground truth and a map), as ``replay`` does; overall, over every scored snapshot of every bag.
* ``tests``: chosen and settled against C11..1, paired Wilcoxon signed-rank tests
  (:func:`~physics_mapper.evaluation.statistics.paired_wilcoxon`, as the experiments test): within a
  bag the pairs are its scored snapshots (``unit: snapshot``; they follow one another in time, so
  they are not independent: read p as a guide); overall, the pairs are the bags' mean errors
  (``unit: bag``, independent), or the snapshots when a single bag is scored.
* ``map_error_m``: the mean total error over *every* snapshot with a ground truth (whose C11..1 holds
  every object), a snapshot without a map (or with one leaving an object out) counting with C11..1's
  error (the hypotheses a user has without the mapper), so that settings which leave different
  snapshots without a map compare fairly (``chosen_or_top``, ``settled_or_top``).
* ``identity``: whether each map name stays on one true object (identity switches, IDF1, MOTA, MOTP, the
  position error by identity: :mod:`physics_mapper.evaluation.identity`); overall, every bag's frames
  together, each bag a sequence of its own.

Everything here is computed from records alone, so it is the same whatever ran the searches;
search times (wall clock) are summarised apart, by :func:`time_summary`.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from physics_mapper.evaluation.identity import identity_metrics, overall_identity_metrics, record_frames
from physics_mapper.evaluation.scoring import ObjectClasses
from physics_mapper.evaluation.snapshot_results import ESTIMATES, is_complete, is_scored, mean_scored_errors
from physics_mapper.evaluation.statistics import paired_wilcoxon

Record = Mapping[str, Any]
#: The estimates compared with C11..1 (the estimate without physics) in the tests.
COMPARED = ("chosen", "settled")


def _counts(records: Sequence[Record]) -> dict[str, Any]:
    snapshots = len(records)
    valid = sum(1 for r in records if r["valid"])
    fallback = sum(1 for r in records if r["fallback_used"])
    visited = [r["visited"] for r in records]
    return {
        "snapshots": snapshots,
        "valid": valid,
        "fallback": fallback,
        "no_map": snapshots - valid - fallback,
        "valid_share": valid / snapshots if snapshots else None,
        "fallback_share": fallback / snapshots if snapshots else None,
        "top_kept": sum(1 for r in records if r["code"] is not None and set(r["code"]) == {1}),
        "stopped_at_deadline": sum(1 for r in records if r["stopped_at_deadline"]),
        "visited_mean": float(np.mean(visited)) if visited else None,
        "visited_max": max(visited, default=None),
        "ground_truth": sum(1 for r in records if r["errors"] is not None),
    }


def _errors_by_object(means: Mapping[str, Sequence[float]], names: Sequence[str]) -> dict[str, Any]:
    return {
        estimate: {
            "per_object": dict(zip(names, map(float, means[estimate]), strict=True)),
            "total": sum(means[estimate]),
        }
        for estimate in ESTIMATES
    }


def _tests(paired: Mapping[str, NDArray[np.float64]], unit: str, names: Sequence[str]) -> dict[str, Any]:
    """Each of :data:`COMPARED` against ``top``, in total and per object; ``paired[estimate]`` is [pair, object]."""
    top = paired["top"]
    tests: dict[str, Any] = {"unit": unit}
    for estimate in COMPARED:
        other = paired[estimate]
        tests[f"{estimate}_vs_top"] = {
            "total": paired_wilcoxon(top.sum(axis=1), other.sum(axis=1)),
            "per_object": {name: paired_wilcoxon(top[:, i], other[:, i]) for i, name in enumerate(names)},
        }
    return tests


def _scored_arrays(records: Sequence[Record]) -> dict[str, NDArray[np.float64]]:
    """Per estimate, the errors of the scored snapshots, [snapshot, object]."""
    scored = [r["errors"] for r in records if is_scored(r["errors"])]
    return {estimate: np.array([e[estimate] for e in scored], dtype=float) for estimate in ESTIMATES}


def _map_errors(records: Sequence[Record]) -> dict[str, Any] | None:
    """Mean total errors over every snapshot with a ground truth, C11..1's where there is no map."""
    truthful = [r["errors"] for r in records if r["errors"] is not None and is_complete(r["errors"]["top"])]
    if not truthful:
        return None
    top = [sum(e["top"]) for e in truthful]
    result: dict[str, Any] = {"snapshots": len(truthful), "top": float(np.mean(top))}
    for estimate in COMPARED:
        totals = [sum(e[estimate]) if is_complete(e[estimate]) else t for e, t in zip(truthful, top, strict=True)]
        result[f"{estimate}_or_top"] = float(np.mean(totals))
    return result


def bag_summary(records: Sequence[Record], objects: ObjectClasses) -> dict[str, Any]:
    """One bag's figures (see the module's docstring)."""
    names = objects.names
    summary = _counts(records)
    means = mean_scored_errors(r["errors"] for r in records)
    summary["scored"] = sum(1 for r in records if is_scored(r["errors"]))
    summary["mean_m"] = None if means is None else _errors_by_object(means, names)
    summary["tests"] = None if means is None else _tests(_scored_arrays(records), "snapshot", names)
    summary["map_error_m"] = _map_errors(records)
    summary["identity"] = identity_metrics(record_frames(records), objects)
    return summary


def overall_summary(bags: Sequence[Sequence[Record]], objects: ObjectClasses) -> dict[str, Any]:
    """The figures of several bags together (see the module's docstring); ``bags`` holds each bag's records."""
    names = objects.names
    records = list(itertools.chain.from_iterable(bags))
    summary = _counts(records)
    summary["bags"] = len(bags)
    means = mean_scored_errors(r["errors"] for r in records)
    summary["scored"] = sum(1 for r in records if is_scored(r["errors"]))
    summary["mean_m"] = None if means is None else _errors_by_object(means, names)
    bag_means = [m for m in (mean_scored_errors(r["errors"] for r in bag) for bag in bags) if m is not None]
    if len(bag_means) >= 2:
        paired = {estimate: np.array([m[estimate] for m in bag_means], dtype=float) for estimate in ESTIMATES}
        summary["tests"] = _tests(paired, "bag", names)
    else:
        summary["tests"] = None if means is None else _tests(_scored_arrays(records), "snapshot", names)
    summary["map_error_m"] = _map_errors(records)
    summary["identity"] = overall_identity_metrics([record_frames(bag) for bag in bags], objects)
    return summary


#: Percentiles of the search time reported, in percent.
PERCENTILES = (50, 90, 99)


def time_summary(search_times: Sequence[float]) -> dict[str, Any] | None:
    """Percentiles, mean and maximum of snapshots' search times (seconds); None for none."""
    if not search_times:
        return None
    times = np.asarray(search_times, dtype=float)
    summary: dict[str, Any] = {f"p{p}_s": float(np.percentile(times, p)) for p in PERCENTILES}
    summary |= {"max_s": float(times.max()), "mean_s": float(times.mean()), "snapshots": int(times.size)}
    return summary
