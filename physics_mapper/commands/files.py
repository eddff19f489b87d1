"""What the subcommands share: input files named by path or URL, problem and scene files loaded with their
warnings, and the output files users name."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from physics_mapper.model.atomic_files import write_atomically
from physics_mapper.model.errors import InputError
from physics_mapper.model.limits import printable
from physics_mapper.model.resources import ResourceError, file_problem, resolve_resource
from physics_mapper.model.scene import Problem, Scene
from physics_mapper.model.scene_files import load_problem, load_scene
from physics_mapper.model.scene_loading import load_stoppably


def input_file(text: str) -> Path:
    """An argparse type: a scene or problem file by path or ``package://<package>/<path>`` URL, as the
    node's ``scene_file`` takes it (argparse's ``Path`` would fold the URL's ``//``)."""
    try:
        return resolve_resource(text, None)
    except ResourceError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def load_problem_file(path: Path, command: str) -> Problem:
    """Load a problem file for subcommand ``command``, stoppable by a signal at any moment (in a thread
    of its own); what loading changed goes to stderr as warnings."""
    problem = load_stoppably(path, load_problem)
    _warn(command, problem.notes)
    return problem


def load_scene_file(path: Path, command: str) -> Scene:
    """Load a scene file for subcommand ``command`` as :func:`load_problem_file` loads a problem file, its
    warnings (a mass ratio Bullet cannot stack, a mesh too large to be in metres) on stderr."""
    scene = load_stoppably(path, load_scene)
    _warn(command, scene.notes)
    return scene


def _warn(command: str, notes: Sequence[str]) -> None:
    for note in notes:
        print(f"physics-mapper {command}: warning: {printable(note)}", file=sys.stderr)


def check_output_folder(path: Path) -> None:
    """Refuse (InputError), before any work is done, an output file whose folder does not exist (or is a
    file, or a symbolic link loop)."""
    if not path.parent.is_dir():
        problem = file_problem(path.parent)
        reasons = {
            None: "is a file, not a folder",
            "not a file": "is not a folder",
            "a symbolic link loop": "is a symbolic link loop",
        }
        reason = reasons.get(problem) or "does not exist"
        raise InputError(f"cannot write {path}: folder {path.parent} {reason}")


def write_output(path: Path, text: str) -> None:
    """Write an output file the user named, whole or not at all; InputError (one line) if it cannot be written.

    Written beside it first and renamed into place: on failure a previous file of that name is untouched.
    """
    try:
        write_atomically(path, text)
    except OSError as error:
        raise InputError(f"cannot write {path}: {error.strerror or error}") from None
