"""What an output path names is kept: links are written through, devices and FIFOs written into, an
overwritten file keeps its mode and owner, and what cannot be written is one error line, exit 2.

Through the command (``solve --trace``) and its real files: devices made with ``mknod`` (the suite runs
as root, as ROS containers do), a read-only tmpfs mounted for the test.
"""

from __future__ import annotations

import json
import os
import stat
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from ros_helpers import one_error_line, run_cli

from physics_mapper.model.atomic_files import write_all_atomically

REPO = Path(__file__).resolve().parents[2]
PYRAMID_PROBLEM = REPO / "config" / "problems" / "pyramid.yaml"
NULL_DEVICE = os.makedev(1, 3)
FULL_DEVICE = os.makedev(1, 7)


def trace_into(path: Path) -> subprocess.CompletedProcess[str]:
    return run_cli("solve", str(PYRAMID_PROBLEM), "--trace", str(path))


def device(path: Path, number: int) -> Path:
    """A character device at ``path`` (a copy of ``/dev/null`` or ``/dev/full``), made as root makes one."""
    os.mknod(path, 0o666 | stat.S_IFCHR, number)
    return path


def test_a_character_device_is_written_into_and_stays_a_device(tmp_path: Path) -> None:
    null = device(tmp_path / "null", NULL_DEVICE)
    completed = trace_into(null)
    assert completed.returncode == 0, completed.stderr
    assert stat.S_ISCHR(null.stat().st_mode) and null.stat().st_rdev == NULL_DEVICE
    assert [p.name for p in tmp_path.iterdir()] == ["null"]  # no temporary left beside it


def test_a_full_device_is_one_error_line_and_exit_2(tmp_path: Path) -> None:
    full = device(tmp_path / "full", FULL_DEVICE)
    one_error_line(trace_into(full), f"cannot write {full}: No space left on device")
    assert stat.S_ISCHR(full.stat().st_mode) and full.stat().st_rdev == FULL_DEVICE


def test_a_symbolic_link_is_written_through_and_stays_a_link(tmp_path: Path) -> None:
    (tmp_path / "traces").mkdir()
    real = tmp_path / "traces" / "trace.json"
    real.write_text("[]\n", encoding="utf-8")
    link = tmp_path / "latest.json"
    link.symlink_to(Path("traces") / "trace.json")
    assert trace_into(link).returncode == 0
    assert link.is_symlink() and os.readlink(link) == str(Path("traces") / "trace.json")
    assert json.loads(real.read_text(encoding="utf-8"))  # the trace, through the link
    dangling = tmp_path / "next.json"
    dangling.symlink_to(tmp_path / "traces" / "new.json")
    assert trace_into(dangling).returncode == 0
    assert dangling.is_symlink() and json.loads((tmp_path / "traces" / "new.json").read_text(encoding="utf-8"))


def test_a_symbolic_link_loop_is_one_error_line(tmp_path: Path) -> None:
    loop = tmp_path / "loop.json"
    loop.symlink_to(loop)
    one_error_line(trace_into(loop), f"cannot write {loop}: a symbolic link loop")
    assert loop.is_symlink()


def test_an_overwritten_file_keeps_its_mode_and_owner(tmp_path: Path) -> None:
    theirs = tmp_path / "theirs.json"
    theirs.write_text("[]\n", encoding="utf-8")
    os.chown(theirs, 4321, 4322)
    theirs.chmod(0o600)
    assert trace_into(theirs).returncode == 0
    after = theirs.stat()
    assert (after.st_uid, after.st_gid, stat.S_IMODE(after.st_mode)) == (4321, 4322, 0o600)
    assert json.loads(theirs.read_text(encoding="utf-8"))


@pytest.mark.parametrize("kind", ["directory", "socket"])
def test_a_directory_or_socket_is_never_replaced(tmp_path: Path, kind: str) -> None:
    target = tmp_path / "target"
    if kind == "directory":
        target.mkdir()
        fragment = "Is a directory"
    else:
        os.mknod(target, 0o666 | stat.S_IFSOCK)
        fragment = "it is a socket"
    one_error_line(trace_into(target), f"cannot write {target}: {fragment}")
    assert stat.S_IFMT(target.lstat().st_mode) == (stat.S_IFDIR if kind == "directory" else stat.S_IFSOCK)


@pytest.fixture
def read_only_disk(tmp_path: Path) -> Iterator[Path]:
    """A tmpfs holding one file, ``old.json``, remounted read-only for the test."""
    folder = tmp_path / "disk"
    folder.mkdir()
    assert subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)], check=False).returncode == 0
    try:
        (folder / "old.json").write_text("[]\n", encoding="utf-8")
        assert subprocess.run(["mount", "-o", "remount,ro", str(folder)], check=False).returncode == 0
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def test_an_unwritable_target_is_one_error_line_and_exit_2(read_only_disk: Path) -> None:
    for target in (read_only_disk / "old.json", read_only_disk / "new.json"):
        one_error_line(trace_into(target), f"cannot write {target}: Read-only file system")
    assert (read_only_disk / "old.json").read_text(encoding="utf-8") == "[]\n"


def test_a_refused_target_among_several_leaves_every_file_untouched(tmp_path: Path) -> None:
    """Targets are looked at before anything is written: the report's other files keep their old text."""
    first = tmp_path / "report.json"
    first.write_text("old\n", encoding="utf-8")
    (tmp_path / "report.md").mkdir()
    with pytest.raises(IsADirectoryError):
        write_all_atomically([(first, "new\n"), (tmp_path / "report.md", "new\n")])
    assert first.read_text(encoding="utf-8") == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.json", "report.md"]
