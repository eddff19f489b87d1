"""Evaluating many bags at once (ROS-free): ``evaluate`` and ``sweep``'s tasks, executors and reports.

``sources`` finds and surveys the bags (the workers read them), ``settings`` turns ``--set`` and
``--grid`` into search settings (and the best into a node parameters file), ``tasks`` is one task
as a worker runs it (a bag read, the offline replay's search and scoring), ``executors`` runs tasks
in this process, on a local process pool or on a Ray cluster, ``runner`` drives a run, ``progress``
shows it on stderr, ``summary`` computes the figures, ``reports`` and ``plots`` write them.

Re-exported here: what a worker process needs. ``summary``, ``reports`` and ``plots`` (scipy.stats,
matplotlib: a second of imports, which every worker would pay at its start) are imported from
their modules.
"""

from __future__ import annotations

from physics_mapper.batch.executors import (
    ATTEMPTS,
    Events,
    Executor,
    InProcess,
    ProcessPool,
    RayCluster,
    RayUnavailable,
    TaskFailure,
)
from physics_mapper.batch.progress import Progress, ProgressMode
from physics_mapper.batch.runner import BatchRun, run_batch, survey_bags
from physics_mapper.batch.settings import (
    Setting,
    grid_settings,
    node_parameters_yaml,
    node_rate_hz,
    parse_value,
    with_overrides,
)
from physics_mapper.batch.sources import (
    SurveyedBag,
    UnreadableBag,
    find_bags,
    load_snapshots,
    read_inputs,
    survey_bag,
)
from physics_mapper.batch.tasks import TaskOutput, evaluate_bag

__all__ = [
    "ATTEMPTS",
    "BatchRun",
    "Events",
    "Executor",
    "InProcess",
    "ProcessPool",
    "Progress",
    "ProgressMode",
    "RayCluster",
    "RayUnavailable",
    "Setting",
    "SurveyedBag",
    "TaskFailure",
    "TaskOutput",
    "UnreadableBag",
    "evaluate_bag",
    "find_bags",
    "grid_settings",
    "load_snapshots",
    "node_parameters_yaml",
    "node_rate_hz",
    "parse_value",
    "read_inputs",
    "run_batch",
    "survey_bag",
    "survey_bags",
    "with_overrides",
]
