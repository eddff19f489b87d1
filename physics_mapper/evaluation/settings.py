"""Search settings of a batch run: ``--set KEY=VALUE`` overrides, ``--grid KEY=V1,V2,...`` sweeps, and
the node parameters file of a chosen setting.

Keys are the fields of :class:`~physics_mapper.model.scene.SearchParams` and, for a grid, those of the
association of detections to instances as ``association.<field>``
(:class:`~physics_mapper.mapping.association.AssociationSettings`: ``gate``, ``confirm_hits``,
``tentative_misses``, ``process_noise``, ``measurement_noise``, ``max_age``). Search values are checked by
the scene files' own reader (:func:`~physics_mapper.model.scene_files.search_with_overrides`), so a
field added to the search is accepted here with the ranges a scene file has. A value is read as a
scene file's YAML is (:func:`~physics_mapper.model.yaml_files.parse_yaml`: ``1e-4`` is a number).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import yaml

from physics_mapper.mapping.association import AssociationSettings
from physics_mapper.mapping.inputs import InputSettings
from physics_mapper.mapping.mapper import DEFAULT_RATE_HZ, MapperSettings, mapper_settings_problem
from physics_mapper.model.errors import InputError
from physics_mapper.model.scene import SearchParams
from physics_mapper.model.scene_files import search_with_overrides
from physics_mapper.model.yaml_files import FileError, parse_yaml

#: Key of a parameters file's section: every node it is given to, whatever its name and namespace
#: (a key naming the node would be silently ignored by a node renamed with ``-r __node:=...``).
PARAMS_FILE_NODE_KEY = "/**"
#: A node tick's period is at least its deadline divided by this (see :func:`node_rate_hz`).
DEADLINE_SHARE_OF_TICK = 0.9


@dataclass(frozen=True)
class Setting:
    """One search setting of a run: the values a grid gives it (``varied``: key, value in grid order),
    over the scene's ``search:`` values and the ``--set`` overrides, and the validated result."""

    varied: tuple[tuple[str, Any], ...]
    params: SearchParams
    association: AssociationSettings = field(default_factory=AssociationSettings)

    @property
    def label(self) -> str:
        """``key=value, ...`` of the varied values, or ``search values of the scene`` for none."""
        if not self.varied:
            return "search values of the scene"
        return ", ".join(f"{key}={value_text(value)}" for key, value in self.varied)


def value_text(value: Any) -> str:
    """A parameter value for people: floats in their shortest form (``%g``)."""
    return f"{value:g}" if isinstance(value, float) else str(value)


def parse_value(text: str, option: str) -> Any:
    """A command-line value as a scene file would give it (YAML, float spellings of YAML 1.2 included);
    InputError naming ``option`` for text that is not YAML."""
    try:
        return parse_yaml(text, option)
    except FileError as error:
        raise InputError(str(error)) from None


def _assignment(text: str, option: str) -> tuple[str, str]:
    key, equals, value = text.partition("=")
    if not equals or not key.strip():
        raise InputError(f"{option} {text!r}: expected KEY=VALUE")
    return key.strip(), value.strip()


def with_overrides(params: SearchParams, assignments: Sequence[str]) -> SearchParams:
    """``params`` with ``--set KEY=VALUE`` assignments applied and checked; InputError or SceneError names the key."""
    overrides: dict[str, Any] = {}
    for text in assignments:
        key, value = _assignment(text, "--set")
        if key in overrides:
            raise InputError(f"--set {key} is given twice")
        overrides[key] = parse_value(value, f"--set {key}")
    return search_with_overrides(params, overrides, "--set")


def grid_settings(base: SearchParams, grid: Sequence[str], fixed: Sequence[str] = ()) -> list[Setting]:
    """Every combination of the ``--grid KEY=V1,V2,...`` values over ``base``, the first key varying slowest.

    ``fixed`` are the ``--set`` keys, which a grid may not vary too. Each combination is checked as a
    scene file's ``search:`` section would be; an error names the combination.
    """
    axes: dict[str, list[Any]] = {}
    for text in grid:
        key, values = _assignment(text, "--grid")
        if key in axes:
            raise InputError(f"--grid {key} is given twice")
        if key in fixed:
            raise InputError(f"--grid {key}: the key is also given with --set")
        axes[key] = [parse_value(value.strip(), f"--grid {key}") for value in values.split(",")]
    settings = []
    for combination in itertools.product(*axes.values()):
        varied = tuple(zip(axes, combination, strict=True))
        label = ", ".join(f"{key}={value}" for key, value in varied)
        searched = {key: value for key, value in varied if not key.startswith(ASSOCIATION_PREFIX)}
        params = search_with_overrides(base, searched, f"--grid {label}")
        association = _association(dict(varied), f"--grid {label}")
        given = tuple((key, getattr(params, key) if key in searched else value) for key, value in varied)
        settings.append(Setting(given, params, association))
    if len({(setting.params, setting.association) for setting in settings}) < len(settings):
        raise InputError("--grid: a value is repeated (two combinations give the same search parameters)")
    return settings


#: Grid keys of the association of detections to instances: ``association.<field>`` of AssociationSettings.
ASSOCIATION_PREFIX = "association."
#: Association settings that count something: whole numbers of at least 1.
WHOLE_ASSOCIATION_SETTINGS = ("confirm_hits", "tentative_misses")


def _association(varied: dict[str, Any], where: str) -> AssociationSettings:
    """The association settings with the grid's ``association.<field>`` values; InputError for an unknown
    field or a value that is not a non-negative number (``confirm_hits``, ``tentative_misses``: a whole number
    of at least 1)."""
    names = {f.name for f in fields(AssociationSettings)}
    values: dict[str, Any] = {}
    for key, value in varied.items():
        if not key.startswith(ASSOCIATION_PREFIX):
            continue
        name = key.removeprefix(ASSOCIATION_PREFIX)
        if name not in names:
            raise InputError(f"{where}: {key} is no association setting (one of: {', '.join(sorted(names))})")
        whole = name in WHOLE_ASSOCIATION_SETTINGS
        number = isinstance(value, int) if whole else isinstance(value, int | float)
        if isinstance(value, bool) or not number or not math.isfinite(value) or value < (1 if whole else 0):
            kind = "a whole number of at least 1" if whole else "a non-negative number"
            raise InputError(f"{where}: {key} must be {kind}, got {value!r}")
        values[name] = int(value) if whole else float(value)
    return replace(AssociationSettings(), **values)


def node_rate_hz(deadline: float) -> float:
    """The node's default tick rate, or a slower one whose period leaves room for ``deadline`` seconds.

    The node requires deadline < 1 / rate_hz; a slower rate is rounded down to two significant
    digits of DEADLINE_SHARE_OF_TICK / deadline.
    """
    if deadline < 1.0 / DEFAULT_RATE_HZ:
        return DEFAULT_RATE_HZ
    rate = DEADLINE_SHARE_OF_TICK / deadline
    digits = 1 - math.floor(math.log10(rate))
    return float(math.floor(rate * 10**digits) / 10**digits)


#: Association settings the node takes as parameters, and their names there (the others stay at their defaults).
NODE_ASSOCIATION_PARAMETERS = {
    "gate": "association_gate",
    "confirm_hits": "confirm_hits",
    "tentative_misses": "tentative_misses",
}


def node_parameters_yaml(
    scene_file: Path, params: SearchParams, header: Sequence[str], association: AssociationSettings | None = None
) -> str:
    """A node parameters file (``--params-file``) that runs the node on ``scene_file`` with ``params``.

    Every search parameter is written (each is a node parameter of the same name), with ``rate_hz``
    from :func:`node_rate_hz`, and the ``association`` settings that differ from the defaults and the
    node takes (:data:`NODE_ASSOCIATION_PARAMETERS`); ``header`` lines become comments. Raises
    InputError if the node would refuse the values.
    """
    rate_hz = node_rate_hz(params.deadline)
    problem = mapper_settings_problem(MapperSettings(params, InputSettings(), rate_hz))
    if problem is not None:
        raise InputError(f"the node would refuse these parameters: {problem}")
    values: dict[str, Any] = {"scene_file": str(scene_file.resolve()), "rate_hz": rate_hz, **asdict(params)}
    defaults = AssociationSettings()
    for field_name, parameter in NODE_ASSOCIATION_PARAMETERS.items():
        value = getattr(association or defaults, field_name)
        if value != getattr(defaults, field_name):
            values[parameter] = value
    document = {PARAMS_FILE_NODE_KEY: {"ros__parameters": values}}
    comments = "".join(f"# {line}\n" for line in header)
    return comments + yaml.safe_dump(document, sort_keys=False, default_flow_style=False)
