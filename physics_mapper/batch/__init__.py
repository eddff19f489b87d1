"""Evaluating many bags at once (ROS-free): ``evaluate`` and ``sweep``'s tasks, executors and reports.

``sources`` finds and reads the bags, ``settings`` turns ``--set``/``--grid`` into search settings
(and the best into a node parameters file), ``tasks`` is one task as a worker runs it (the offline
replay's search and scoring), ``executors`` runs tasks in this process, on a local process pool or
on a Ray cluster, ``runner`` drives a run, ``summary`` computes the figures, ``reports`` and ``plots``
write them, ``progress`` shows the run on stderr.
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
from physics_mapper.batch.reports import (
    CRITERIA,
    PARAMS_FILE,
    Criterion,
    ReportContext,
    best_setting,
    evaluation_data,
    sweep_data,
    write_evaluation,
    write_sweep,
)
from physics_mapper.batch.runner import BatchRun, read_bags, run_batch
from physics_mapper.batch.settings import (
    Setting,
    grid_settings,
    node_parameters_yaml,
    node_rate_hz,
    parse_value,
    with_overrides,
)
from physics_mapper.batch.sources import LoadedBag, find_bags, load_bag
from physics_mapper.batch.summary import bag_summary, overall_summary, time_summary
from physics_mapper.batch.tasks import TaskOutput, evaluate_snapshots

__all__ = [
    "ATTEMPTS",
    "CRITERIA",
    "PARAMS_FILE",
    "BatchRun",
    "Criterion",
    "Events",
    "Executor",
    "InProcess",
    "LoadedBag",
    "ProcessPool",
    "Progress",
    "ProgressMode",
    "RayCluster",
    "RayUnavailable",
    "ReportContext",
    "Setting",
    "TaskFailure",
    "TaskOutput",
    "bag_summary",
    "best_setting",
    "evaluate_snapshots",
    "evaluation_data",
    "find_bags",
    "grid_settings",
    "load_bag",
    "node_parameters_yaml",
    "node_rate_hz",
    "overall_summary",
    "parse_value",
    "read_bags",
    "run_batch",
    "sweep_data",
    "time_summary",
    "with_overrides",
    "write_evaluation",
    "write_sweep",
]
