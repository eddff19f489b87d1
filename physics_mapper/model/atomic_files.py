"""Files written whole or not at all: a temporary file beside the target, renamed into place when complete.

A reader (another node, a user's editor, a second run) sees the old file or the new one, never half
of one; a write that fails (a full disk, a signal) leaves the old file as it was and removes its
temporary file. New files get the permissions the user's umask gives (``0o666 & ~umask``, as any
program's files do), so a cache or report another user is meant to read is readable.

What the target path names is kept, as a shell's ``>`` keeps it:

- a symbolic link is written through: the file it points at is replaced, the link stays (a link that
  points nowhere creates the file it names; a loop is refused, ``ELOOP``);
- a regular file being overwritten keeps its mode and owner (its owner cannot be kept by a user who
  may not ``chown``: then it is refused, ``EPERM``, rather than taken over), and a file the user may
  not write is refused (``EACCES``) as ``open`` would refuse it;
- a character device or a FIFO (``/dev/null``, ``/dev/full``, a pipe) is written into, in place and
  not atomically, never replaced: a write error (``ENOSPC`` on ``/dev/full``) is raised;
- a directory, a block device or a socket is refused (``EISDIR``, ``EINVAL``), never replaced.
"""

from __future__ import annotations

import errno
import os
import secrets
import shutil
import stat
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

Contents = bytes | str | Callable[[BinaryIO], None]

_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


def temporary_sibling(path: Path, kind: str = "tmp") -> Path:
    """A fresh hidden name beside ``path`` for it to be written under first."""
    return path.parent / f".{path.name}.{kind}-{secrets.token_hex(4)}"


@dataclass(frozen=True)
class _Target:
    """Where one output goes: the file a path names once its links are followed, and what is there now."""

    path: Path
    existing: os.stat_result | None

    @property
    def is_stream(self) -> bool:
        """A character device or a FIFO: written into, never replaced."""
        return self.existing is not None and (
            stat.S_ISCHR(self.existing.st_mode) or stat.S_ISFIFO(self.existing.st_mode)
        )


def _target(path: Path) -> _Target:
    """Follow ``path``'s links and look at what is there; OSError for what must not be written or replaced."""
    resolved = Path(os.path.realpath(path)) if os.path.islink(path) else path
    if os.path.islink(resolved):  # realpath stops at a loop and returns a link
        raise OSError(errno.ELOOP, "a symbolic link loop", str(path))
    try:
        existing = os.stat(resolved)
    except FileNotFoundError:
        return _Target(resolved, None)
    mode = existing.st_mode
    if stat.S_ISDIR(mode):
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
    if not (stat.S_ISREG(mode) or stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)):
        kind = "block device" if stat.S_ISBLK(mode) else "socket"
        reason = f"it is a {kind} (only regular files, character devices and FIFOs are written)"
        raise OSError(errno.EINVAL, reason, str(path))
    if stat.S_ISREG(mode):
        # Opened for writing (not truncated) only to be refused as open() refuses: the file is replaced, not opened.
        os.close(os.open(resolved, os.O_WRONLY | _CLOEXEC))
    return _Target(resolved, existing)


def _write_contents(file: BinaryIO, contents: Contents) -> None:
    if callable(contents):
        contents(file)
    else:
        file.write(contents.encode("utf-8") if isinstance(contents, str) else contents)
    file.flush()


def _keep_owner_and_mode(descriptor: int, existing: os.stat_result) -> None:
    """Give the new file the owner, then the mode, of the one it replaces (``chown`` clears set-id bits)."""
    if (existing.st_uid, existing.st_gid) != (os.getuid(), os.getgid()):
        try:
            os.fchown(descriptor, existing.st_uid, existing.st_gid)
        except PermissionError:
            raise PermissionError(
                errno.EPERM, f"it belongs to user {existing.st_uid} and cannot be replaced keeping its owner"
            ) from None
    os.fchmod(descriptor, stat.S_IMODE(existing.st_mode))


def _write_new(path: Path, contents: Contents, replaced: os.stat_result | None) -> None:
    # Mode 0o666 before the umask, as open() would: the kernel applies the user's umask.
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _CLOEXEC, 0o666)
    with os.fdopen(descriptor, "wb") as file:
        if replaced is not None:
            _keep_owner_and_mode(file.fileno(), replaced)
        _write_contents(file, contents)
        os.fsync(file.fileno())


def _write_into(path: Path, contents: Contents) -> None:
    """Write into a character device or FIFO as it is (no fsync: devices and pipes refuse it)."""
    with os.fdopen(os.open(path, os.O_WRONLY | _CLOEXEC), "wb") as file:
        _write_contents(file, contents)


def write_atomically(path: Path, contents: Contents) -> None:
    """Write ``contents`` (text as UTF-8, bytes, or a function writing to the open file) to ``path`` atomically.

    Raises OSError as the write does, or for a target that is refused (module docstring); the old
    ``path`` is then untouched.
    """
    write_all_atomically([(path, contents)])


def write_all_atomically(files: Sequence[tuple[Path, Contents]]) -> None:
    """Write several files, each atomically, renamed into place only once every one is complete.

    A failure while writing leaves every old file untouched (a report's plot, numbers and page stay
    one run's). Raises OSError.
    """
    targets = [(_target(path), contents) for path, contents in files]
    temporaries: list[tuple[Path, Path]] = []
    try:
        for target, contents in targets:
            if target.is_stream:
                _write_into(target.path, contents)
                continue
            temporary = temporary_sibling(target.path)
            temporaries.append((temporary, target.path))
            _write_new(temporary, contents, target.existing)
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
