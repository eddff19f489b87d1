"""Files written whole or not at all: a temporary file beside the target, renamed into place when complete.

A reader (another node, a user's editor, a second run) sees the old file or the new one, never half
of one; a write that fails (a full disk, a signal) leaves the old file as it was and removes its
temporary file. New files get the permissions the user's umask gives (``0o666 & ~umask``, as any
program's files do), so a cache or report another user is meant to read is readable.
"""

from __future__ import annotations

import os
import secrets
import shutil
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

Contents = bytes | str | Callable[[BinaryIO], None]


def temporary_sibling(path: Path, kind: str = "tmp") -> Path:
    """A fresh hidden name beside ``path`` for it to be written under first."""
    return path.parent / f".{path.name}.{kind}-{secrets.token_hex(4)}"


def _write_new(path: Path, contents: Contents) -> None:
    # Mode 0o666 before the umask, as open() would: the kernel applies the user's umask.
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
    with os.fdopen(descriptor, "wb") as file:
        if callable(contents):
            contents(file)
        else:
            file.write(contents.encode("utf-8") if isinstance(contents, str) else contents)
        file.flush()
        os.fsync(file.fileno())


def write_atomically(path: Path, contents: Contents) -> None:
    """Write ``contents`` (text as UTF-8, bytes, or a function writing to the open file) to ``path`` atomically.

    Raises OSError as the write does; the old ``path`` is then untouched.
    """
    write_all_atomically([(path, contents)])


def write_all_atomically(files: Sequence[tuple[Path, Contents]]) -> None:
    """Write several files, each atomically, renamed into place only once every one is complete.

    A failure while writing leaves every old file untouched (a report's plot, numbers and page stay
    one run's). Raises OSError.
    """
    temporaries: list[tuple[Path, Path]] = []
    try:
        for path, contents in files:
            temporary = temporary_sibling(path)
            temporaries.append((temporary, path))
            _write_new(temporary, contents)
        for temporary, path in temporaries:
            os.replace(temporary, path)
    finally:
        for temporary, _ in temporaries:
            temporary.unlink(missing_ok=True)


@contextmanager
def directory_atomically(path: Path) -> Iterator[Path]:
    """A folder to fill in place of ``path`` (which must not exist): moved to ``path`` when the block ends normally.

    Yields a path inside a hidden temporary folder beside ``path``, with ``path``'s own name (tools
    that name files after their folder, as rosbag2 writers do, name them as for ``path``). On an
    exception the partial folder is removed and ``path`` never appears.
    """
    holder = temporary_sibling(path, "partial")
    holder.mkdir(mode=0o777)
    inner = holder / path.name
    try:
        yield inner
        os.rename(inner, path)  # refuses a ``path`` created meanwhile (a non-empty folder)
    finally:
        shutil.rmtree(holder, ignore_errors=True)
