"""YAML input files, read so that any file gives a value or one clear :class:`FileError`, never a traceback.

Reading is bounded: at most :data:`~physics_mapper.model.limits.MAX_FILE_BYTES` bytes, UTF-8 text,
lists and mappings nested at most :data:`~physics_mapper.model.limits.MAX_YAML_DEPTH` deep (PyYAML
composes nodes recursively, so deeper nesting would exhaust Python's stack).

Numbers are read as people write them. PyYAML follows YAML 1.1, where a float needs a dot and
a signed exponent, so ``1e-4``, ``1E+9`` and ``1.0e5`` are strings there. The loader here also
reads YAML 1.2's float spellings (:data:`FLOAT_SPELLING`), as rcl's own parameter-file parser
(C's ``strtod``) does; integers stay integers.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path
from typing import Any

import yaml
from yaml.composer import ComposerError
from yaml.constructor import ConstructorError
from yaml.nodes import MappingNode, Node

from physics_mapper.model.limits import MAX_FILE_BYTES, MAX_KEY_TEXT, MAX_YAML_DEPTH, clipped, printable

#: A YAML 1.2 (core schema) float without the special values: ``.5``, ``1.``, ``1e-4``, ``-2.5E+3``.
FLOAT_SPELLING = re.compile(r"^[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?$")


class FileError(ValueError):
    """An input file cannot be used: names the file, the key path (if any) and the problem, on one line.

    Text taken from the file (a key, a quoted value) is shown escaped if it holds line breaks or
    other unprintable characters, and a key path is clipped to
    :data:`~physics_mapper.model.limits.MAX_KEY_TEXT` characters.
    """

    def __init__(self, source: str, key: str, problem: str) -> None:
        key, problem = clipped(printable(key), MAX_KEY_TEXT), printable(problem)
        super().__init__(f"{source}: {key}: {problem}" if key else f"{source}: {problem}")
        self.source = source
        self.key = key
        self.problem = problem


class _BoundedLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 float spellings and a nesting limit."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Node | None, index: Any) -> Node | None:
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                mark = self.peek_event().start_mark  # type: ignore[no-untyped-call]  # untyped in the stubs
                raise ComposerError(None, None, f"nested deeper than {MAX_YAML_DEPTH} levels", mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node: MappingNode, deep: bool = False) -> dict[Any, Any]:
        """A mapping whose keys are all different: a second ``objects:`` would silently drop the first."""
        seen: dict[Any, Node] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue  # ``<<: *base`` merges, and keys given beside it override the merged ones
            key = self.construct_object(key_node, deep=True)
            try:
                first = seen.get(key)
            except TypeError:  # an unhashable key: PyYAML's own error says so
                continue
            if first is not None:
                where = f"line {first.start_mark.line + 1}, column {first.start_mark.column + 1}"
                raise ConstructorError(None, None, f"duplicate key {key!r} (first at {where})", key_node.start_mark)
            seen[key] = key_node
        return super().construct_mapping(node, deep=deep)


# Tried after YAML 1.1's own int and float patterns, so integers stay integers.
_BoundedLoader.add_implicit_resolver("tag:yaml.org,2002:float", FLOAT_SPELLING, list("-+.0123456789"))


def parse_yaml(text: str, source: str) -> Any:
    """Parse YAML ``text``; ``source`` names it in a :class:`FileError`."""
    try:
        return yaml.load(text, Loader=_BoundedLoader)  # a SafeLoader: builds plain data only
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise FileError(source, "", f"not valid YAML{where}: {error.problem}") from None
    except yaml.YAMLError as error:  # the reader's: a character YAML does not allow
        raise FileError(source, "", f"not valid YAML: {str(error).splitlines()[0]}") from None


def read_regular_file(path: Path, limit: int) -> bytes:
    """At most ``limit`` + 1 bytes of ``path``, which must be a regular file; OSError or ValueError otherwise.

    Opened without blocking and checked on the open descriptor: a FIFO, a device or a socket
    named as an input would otherwise block the reader forever (or stream without end).
    """
    descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        mode = os.fstat(descriptor).st_mode
        if not stat.S_ISREG(mode):
            kind = "a directory" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else "a special file"
            raise ValueError(f"not a regular file ({kind})")
        os.set_blocking(descriptor, True)
        with os.fdopen(descriptor, "rb", closefd=False) as file:
            return file.read(limit + 1)
    finally:
        os.close(descriptor)


def read_yaml(path: Path) -> Any:
    """Read and parse a YAML file; raises :class:`FileError` naming it."""
    source = str(path)
    try:
        content = read_regular_file(path, MAX_FILE_BYTES)
    except OSError as error:
        raise FileError(source, "", f"cannot read file: {error.strerror or error}") from None
    except ValueError as error:
        raise FileError(source, "", f"cannot read file: {error}") from None
    if len(content) > MAX_FILE_BYTES:
        raise FileError(source, "", f"larger than the {MAX_FILE_BYTES // 2**20} MiB allowed for a YAML input file")
    try:
        text = content.decode("utf-8-sig")  # a byte-order mark, as some editors write, is dropped
    except UnicodeDecodeError as error:
        line = content.count(b"\n", 0, error.start) + 1
        column = error.start - content.rfind(b"\n", 0, error.start)
        byte = content[error.start]
        raise FileError(source, "", f"not UTF-8 text (byte {byte:#04x} at line {line}, column {column})") from None
    return parse_yaml(text, source)
