"""Convex decomposition of concave meshes (CoACD, or pybullet's V-HACD), cached on disk.

Bullet collides convex shapes. A concave object (a mug, a bowl, a tray) given as its convex
hull is solid where it is hollow: a cube resting in a bowl overlaps the bowl's hull. A convex
decomposition approximates the mesh by a few convex *parts* whose union follows its cavities;
Bullet then collides each part (a compound shape).

Methods:

* ``coacd`` (default): CoACD, Wei et al. 2022, "Approximate convex decomposition for 3D meshes
  with collision-aware concavity and tree search". ``threshold`` is its concavity threshold
  (0.01 to 1, dimensionless: relative to the mesh's size); lower gives more, finer parts. Each part
  is decimated to at most :data:`COACD_MAX_PART_VERTICES` vertices. Seeded, so a mesh always gives
  the same parts. Slow: about 30 s for pybullet_data's mug on one core (more on a busy machine).
* ``vhacd``: pybullet's built-in V-HACD (its default parameters, except a voxel resolution of
  :data:`VHACD_RESOLUTION` instead of 1,000,000: ten times faster, about as many parts). Faster,
  coarser; the fallback to compare against (``BENCHMARKS.md``).

A decomposition is computed on the mesh file as read (unscaled, in its own frame) and stored in
the cache as an OBJ file, one ``o part_<i>`` group per convex part, which pybullet loads as a
compound of convex hulls (scaled by the body's ``scale``). Its first lines give the part count and a
SHA-256 of the rest; a cache file is used only if both match and every part is finite and has a
volume, and is otherwise computed again and replaced (a file truncated by a full disk, edited, or
damaged in any way is never blamed on the mesh). The file name is a SHA-256 key of
the mesh file's bytes, the method, its parameters and the library's version, so a changed file
or parameter is decomposed again, and an unchanged one never is. Files are written to a temporary
name and renamed, so concurrent loads (two nodes, a test run) never see half a file, with the
permissions the user's umask gives (usually readable by everyone, so a shared cache folder serves
other users' nodes); nothing is ever evicted (delete the folder to reclaim the space).

The cache folder is ``$PHYSICS_MAPPER_CACHE_DIR/decompositions`` if that variable is set, else the
platform's user cache folder (``platformdirs``): ``~/.cache/physics_mapper/decompositions`` on
Linux (``$XDG_CACHE_HOME`` honoured), ``~/Library/Caches/physics_mapper/decompositions`` on macOS,
``%LOCALAPPDATA%\\physics_mapper\\Cache\\decompositions`` on Windows.

Parts read from a user's own file (``parts:`` in a scene: an OBJ whose ``o``/``g`` groups are the
convex parts, as V-HACD and pybullet_data's ``*_vhacd.obj`` files are) are copied into the cache
in the same canonical form, so pybullet always loads a file written here.
"""

from __future__ import annotations

import contextlib
import contextvars
import hashlib
import importlib
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.atomic_files import write_atomically

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
Progress = Callable[[str], None]

DecompositionMethod = Literal["coacd", "vhacd"]
DECOMPOSITION_METHODS: tuple[DecompositionMethod, ...] = ("coacd", "vhacd")
#: Environment variable naming the cache's parent folder (tests, CI, read-only homes).
CACHE_ENVIRONMENT_VARIABLE = "PHYSICS_MAPPER_CACHE_DIR"
#: Bumped when the cache's file format changes, so that old files are not read.
CACHE_FORMAT = 2
#: Most convex parts a decomposition or a ``parts`` file may have: Bullet collides every part of a body
#: with every part near it, and CoACD and V-HACD give tens (``BENCHMARKS.md`` "Input caps" measures a
#: parts file at the cap).
MAX_CONVEX_PARTS = 256
#: Most vertices all convex parts of one decomposition or ``parts`` file may have together.
MAX_PART_VERTICES = 100_000
#: Largest ``parts`` file or cache file read, bytes.
MAX_PARTS_FILE_BYTES = 64 * 1024 * 1024
#: A part whose vertices span less than this fraction of its size in some direction is flat: no volume.
FLAT_PART_RATIO = 1e-9
#: CoACD's concavity threshold range (its own documented range).
THRESHOLD_LIMITS = (0.01, 1.0)
#: Most vertices a CoACD part keeps (its decimation): Bullet's cost of a convex part grows with its vertices,
#: and undecimated parts of the mug reach 500 (V-HACD's default cap is 64 too).
COACD_MAX_PART_VERTICES = 64
#: Wall-clock seconds a decomposition may take (CoACD on pybullet_data's mug: about 30 s on one core).
DECOMPOSITION_TIME_LIMIT = 600.0
#: Address space a decomposition's child process may use, bytes (CoACD on the mug peaks far below).
DECOMPOSITION_MEMORY_LIMIT = 4 * 2**30
#: Environment variables overriding the two limits: seconds, and MiB.
TIME_LIMIT_VARIABLE = "PHYSICS_MAPPER_DECOMPOSITION_SECONDS"
MEMORY_LIMIT_VARIABLE = "PHYSICS_MAPPER_DECOMPOSITION_MIB"
#: Seconds between two looks of the parent at its decomposing child: the latency of a stop.
STOP_POLL = 0.05
#: Voxels V-HACD fills the mesh with (pybullet's default is 1,000,000: 6 s on the mug, 14 parts; this: 0.5 s, 12).
VHACD_RESOLUTION = 100_000


@dataclass(frozen=True)
class DecompositionSettings:
    """How a mesh is decomposed: ``method`` and, for CoACD, its concavity ``threshold``."""

    method: DecompositionMethod = "coacd"
    threshold: float = 0.05


@dataclass(frozen=True, eq=False)
class ConvexPart:
    """One convex part: ``vertices`` (K, 3) and triangle ``faces`` (F, 3) indexing them."""

    vertices: FloatArray
    faces: IntArray


@dataclass(frozen=True)
class Decomposition:
    """Convex parts of a mesh, unscaled in the mesh file's frame, and the cached OBJ holding them.

    ``computed_seconds`` is the wall-clock time the decomposition took when this call computed
    it, and None when it came from the cache (or from a user's parts file).
    """

    parts: tuple[ConvexPart, ...]
    file: Path
    method: str
    computed_seconds: float | None

    @property
    def from_cache(self) -> bool:
        return self.computed_seconds is None


class DecompositionError(ValueError):
    """A decomposition could not be computed, read or stored (the message says which and why)."""


def stderr_progress(line: str) -> None:
    """Default progress report: one line on stderr (a first decomposition can take a minute)."""
    print(f"physics_mapper: {line}", file=sys.stderr, flush=True)


def cache_directory() -> Path:
    """The folder of cached decompositions (see the module docstring); not created here."""
    override = os.environ.get(CACHE_ENVIRONMENT_VARIABLE)
    if override:
        return Path(override).expanduser() / "decompositions"
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("physics_mapper", appauthor=False)) / "decompositions"


def cache_key(mesh_bytes: bytes, settings: DecompositionSettings) -> str:
    """Hex key of a decomposition: SHA-256 of the mesh bytes, the settings and the library version."""
    library = "coacd" if settings.method == "coacd" else "pybullet"
    if settings.method == "coacd":
        parameters = {**asdict(settings), "max_part_vertices": COACD_MAX_PART_VERTICES, "seed": 0}
    else:
        parameters = {"method": "vhacd", "resolution": VHACD_RESOLUTION}
    header = json.dumps({"format": CACHE_FORMAT, "settings": parameters, library: _version(library)})
    digest = hashlib.sha256(header.encode())
    digest.update(mesh_bytes)
    return digest.hexdigest()[:32]


def _version(library: str) -> str:
    try:
        return version(library)
    except PackageNotFoundError:  # decomposing says so, with what to do
        return "not installed"


def decompose(
    mesh_file: Path,
    vertices: FloatArray,
    faces: IntArray,
    settings: DecompositionSettings,
    progress: Progress = stderr_progress,
) -> Decomposition:
    """The convex parts of the mesh read from ``mesh_file`` (``vertices``, ``faces``: as read, unscaled).

    Read from the cache when there; otherwise computed (reported through ``progress``, before
    and after), stored, and returned. Raises :class:`DecompositionError`.
    """
    directory = cache_directory()
    cached = directory / f"{cache_key(_read_bytes(mesh_file), settings)}.obj"
    damage = ""
    if cached.is_file():
        try:
            return Decomposition(read_cached_parts(cached), cached, settings.method, None)
        except DecompositionError as error:  # disk full, edited, truncated: computed again and replaced
            damage = f"; the cached file was damaged: {error}"
    where = f"threshold {settings.threshold:g}, " if settings.method == "coacd" else ""
    progress(
        f"decomposing {mesh_file} with {settings.method} ({where}once: the result is cached in {directory}){damage}"
    )
    start = time.monotonic()
    parts = _in_child_process(mesh_file, vertices, faces, settings)
    seconds = time.monotonic() - start
    if not parts:
        raise DecompositionError(f"{settings.method} returned no convex part")
    problem = parts_problem(parts)
    if problem is not None:
        raise DecompositionError(f"{settings.method} of {mesh_file} gave an unusable result: {problem}")
    write_parts(cached, parts, f"{settings.method} decomposition of {mesh_file} ({asdict(settings)})")
    progress(f"decomposed {mesh_file}: {len(parts)} convex parts in {seconds:.1f} s, cached as {cached}")
    return Decomposition(parts, cached, settings.method, seconds)


def parts_from_file(parts_file: Path) -> Decomposition:
    """A user's decomposition: the ``o``/``g`` groups of an OBJ file, copied into the cache in canonical form."""
    parts = read_parts(parts_file)
    problem = parts_problem(parts)
    if problem is not None:
        raise DecompositionError(f"{parts_file}: {problem}")
    cached = cache_directory() / f"parts-{hashlib.sha256(_read_bytes(parts_file)).hexdigest()[:32]}.obj"
    try:
        read_cached_parts(cached)
    except DecompositionError:  # missing or damaged: written (again)
        write_parts(cached, parts, f"convex parts of {parts_file}")
    return Decomposition(parts, cached, "parts file", None)


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as error:
        raise DecompositionError(f"cannot read {path}: {error.strerror or error}") from None


def run_method(
    vertices: FloatArray, faces: IntArray, settings: DecompositionSettings, folder: Path
) -> tuple[ConvexPart, ...]:
    """Run ``settings.method`` in this process (what the child process of :func:`decompose` does); V-HACD's
    files go in ``folder``, which the caller removes (a child killed past its limit removes nothing)."""
    return _coacd(vertices, faces, settings) if settings.method == "coacd" else _vhacd(vertices, faces, folder)


#: The child's CPU-time backstop: this many times the wall-clock limit, plus a margin (seconds).
CPU_LIMIT_FACTOR = 2
CPU_LIMIT_MARGIN = 2


def decomposition_limits() -> tuple[float, int]:
    """The wall-clock seconds and bytes of memory a decomposition may take (module constants, or the
    environment's :data:`TIME_LIMIT_VARIABLE` and :data:`MEMORY_LIMIT_VARIABLE`)."""
    seconds, memory = DECOMPOSITION_TIME_LIMIT, DECOMPOSITION_MEMORY_LIMIT
    try:
        seconds = float(os.environ.get(TIME_LIMIT_VARIABLE, seconds))
        memory = int(float(os.environ.get(MEMORY_LIMIT_VARIABLE, memory / 2**20)) * 2**20)
    except ValueError:
        raise DecompositionError(f"{TIME_LIMIT_VARIABLE} and {MEMORY_LIMIT_VARIABLE} must be numbers") from None
    return seconds, memory


def _in_child_process(
    mesh_file: Path, vertices: FloatArray, faces: IntArray, settings: DecompositionSettings
) -> tuple[ConvexPart, ...]:
    """:func:`run_method` in a child process with a wall-clock, CPU and memory limit, killed if interrupted.

    The wait polls every :data:`STOP_POLL` seconds, so a signal's KeyboardInterrupt (the command's, or
    the node's interruptible start-up) stops it within that time, at any moment of the decomposition.
    """
    seconds, memory = decomposition_limits()
    with tempfile.TemporaryDirectory(prefix="physics_mapper_decomposition_") as name:
        folder = Path(name)
        request = {
            "method": settings.method,
            "threshold": settings.threshold,
            "memory_bytes": memory,
            # The wall clock decides; the CPU limit is the child's own backstop, should the parent be gone:
            # above it, so that a decomposition on two cores meets the wall-clock limit first.
            "cpu_seconds": CPU_LIMIT_FACTOR * math.ceil(seconds) + CPU_LIMIT_MARGIN,
        }
        (folder / "request.json").write_text(json.dumps(request), encoding="utf-8")
        np.savez(folder / "mesh.npz", vertices=np.asarray(vertices, dtype=np.float64), faces=np.asarray(faces))
        command = [sys.executable, "-m", "physics_mapper.model.decomposition_worker", str(folder)]
        cancel = _CANCEL.get()
        # Its own session: a Ctrl-C in the terminal reaches the parent only, which kills the child. Its
        # stderr goes to a file: a pipe nobody reads while it runs would block it once full.
        with (folder / "stderr.txt").open("wb") as log:
            child = subprocess.Popen(
                command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=log, start_new_session=True
            )
        try:
            deadline = time.monotonic() + seconds
            while child.poll() is None:
                if cancel is not None and cancel.is_set():
                    raise DecompositionError(f"{settings.method} of {mesh_file}: interrupted")
                if time.monotonic() > deadline:
                    raise DecompositionError(
                        f"{settings.method} of {mesh_file} took longer than its {seconds:g} s limit "
                        f"(set {TIME_LIMIT_VARIABLE} to allow more, or simplify the mesh)"
                    )
                with contextlib.suppress(subprocess.TimeoutExpired):
                    child.wait(STOP_POLL)
        finally:
            if child.poll() is None:
                child.kill()
                # Reaped by a thread of its own: the kernel frees the child's memory (gigabytes for a
                # runaway V-HACD) before wait() returns, 0.1 s that a stopping command need not wait.
                threading.Thread(target=child.wait, name="decomposition reaper", daemon=True).start()
        stderr = (folder / "stderr.txt").read_text(encoding="utf-8", errors="replace")
        error_file = folder / "error.txt"
        if child.returncode != 0:
            raise DecompositionError(_child_failure(mesh_file, settings, child.returncode, error_file, stderr, memory))
        with np.load(folder / "parts.npz") as data:
            count = len(data.files) // 2
            return tuple(
                ConvexPart(np.asarray(data[f"v{i}"], dtype=np.float64), np.asarray(data[f"f{i}"], dtype=np.int64))
                for i in range(count)
            )


_CANCEL: contextvars.ContextVar[threading.Event | None] = contextvars.ContextVar("decomposition_cancel", default=None)


@contextlib.contextmanager
def cancelled_by(event: threading.Event) -> Iterator[None]:
    """Within the block (in this thread), a decomposition stops with DecompositionError once ``event`` is set.

    For a thread loading a scene while another waits (the node spinning during its start-up): setting
    the event kills the decomposition's child process within :data:`STOP_POLL` seconds.
    """
    token = _CANCEL.set(event)
    try:
        yield
    finally:
        _CANCEL.reset(token)


def _child_failure(
    mesh_file: Path, settings: DecompositionSettings, status: int, error_file: Path, stderr: str, memory: int
) -> str:
    """One line saying why the decomposition's child process failed."""
    what = f"{settings.method} of {mesh_file}"
    reported = error_file.read_text(encoding="utf-8").strip() if error_file.is_file() else ""
    limit = f"its {memory / 2**20:g} MiB memory limit (set {MEMORY_LIMIT_VARIABLE} to allow more, or simplify the mesh)"
    if reported == "out of memory" or "bad_alloc" in stderr or "MemoryError" in stderr:
        return f"{what} ran out of {limit}"
    if reported:
        return f"{what} failed: {reported}"
    if status in (-signal.SIGXCPU, 128 + signal.SIGXCPU):
        return f"{what} used up its CPU time limit (set {TIME_LIMIT_VARIABLE} to allow more, or simplify the mesh)"
    if status in (-signal.SIGABRT, 128 + signal.SIGABRT, -signal.SIGSEGV, -signal.SIGKILL):
        return f"{what} crashed (signal {-status if status < 0 else status - 128}), probably past {limit}"
    last = stderr.strip().splitlines()[-1] if stderr.strip() else f"exit status {status}"
    return f"{what} failed: {' '.join(last.split())}"


def _coacd(vertices: FloatArray, faces: IntArray, settings: DecompositionSettings) -> tuple[ConvexPart, ...]:
    try:
        coacd = importlib.import_module("coacd")
    except ImportError:
        raise DecompositionError("coacd is not installed (pip install coacd), use method: vhacd") from None
    coacd.set_log_level("error")
    mesh = coacd.Mesh(np.ascontiguousarray(vertices, dtype=np.float64), np.ascontiguousarray(faces, dtype=np.int32))
    parts = coacd.run_coacd(
        mesh, threshold=settings.threshold, decimate=True, max_ch_vertex=COACD_MAX_PART_VERTICES, seed=0
    )
    return tuple(ConvexPart(np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)) for v, f in parts)


def _vhacd(vertices: FloatArray, faces: IntArray, folder: Path) -> tuple[ConvexPart, ...]:
    from physics_mapper.model.bullet import pybullet, silenced_descriptor  # pybullet loads on first use

    source, output, log = (folder / f"vhacd_{name}" for name in ("mesh.obj", "parts.obj", "log.txt"))
    write_parts(source, (ConvexPart(vertices, faces),), "input of V-HACD")
    with silenced_descriptor(1):  # V-HACD prints its parameters and progress on stdout
        pybullet.vhacd(str(source), str(output), str(log), resolution=VHACD_RESOLUTION)
    return read_parts(output)


_HEADER = "# physics_mapper: "
_CHECKSUM = "# sha256 "


def write_parts(path: Path, parts: Sequence[ConvexPart], title: str) -> None:
    """Write ``parts`` as an OBJ file, one ``o part_<i>`` group each, atomically (temporary file + rename).

    The first two lines are comments (OBJ readers skip them): ``title`` with the part count, and the
    SHA-256 of every line after them, which :func:`read_cached_parts` checks.
    """
    lines = []
    offset = 1  # OBJ indices are 1-based and global across groups
    for index, part in enumerate(parts):
        lines.append(f"o part_{index}")
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in part.vertices.tolist()]
        lines += [f"f {a + offset} {b + offset} {c + offset}" for a, b, c in part.faces.tolist()]
        offset += len(part.vertices)
    body = "\n".join(lines) + "\n"
    header = f"{_HEADER}{' '.join(title.split())}: {len(parts)} convex parts\n"
    checksum = f"{_CHECKSUM}{hashlib.sha256(body.encode('ascii')).hexdigest()}\n"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomically(path, header + checksum + body)
    except OSError as error:
        raise DecompositionError(
            f"cannot write {path}: {error.strerror or error} (set {CACHE_ENVIRONMENT_VARIABLE} to a writable folder)"
        ) from None


def read_cached_parts(path: Path) -> tuple[ConvexPart, ...]:
    """The parts of a file :func:`write_parts` wrote, verified: its checksum and part count match and
    every part is finite and has a volume; DecompositionError saying what is damaged otherwise.
    """
    try:
        with path.open("rb") as file:
            content = file.read(MAX_PARTS_FILE_BYTES + 1)
    except OSError as error:
        raise DecompositionError(f"cannot read {path}: {error.strerror or error}") from None
    header, _, rest = content.partition(b"\n")
    checksum, _, body = rest.partition(b"\n")
    count_word = header.rsplit(b":", 1)[-1].split()[:1]
    if not header.startswith(_HEADER.encode()) or not checksum.startswith(_CHECKSUM.encode()) or not count_word:
        raise DecompositionError(f"{path}: no part count or checksum in its first lines")
    if hashlib.sha256(body).hexdigest() != checksum[len(_CHECKSUM) :].decode("ascii", "replace").strip():
        raise DecompositionError(f"{path}: checksum mismatch (truncated or changed)")
    parts = read_parts(path)
    if count_word[0].decode("ascii", "replace") != str(len(parts)):
        raise DecompositionError(f"{path}: {len(parts)} convex parts, its header says {count_word[0].decode()}")
    problem = parts_problem(parts)
    if problem is not None:
        raise DecompositionError(f"{path}: {problem}")
    return parts


def parts_problem(parts: Sequence[ConvexPart]) -> str | None:
    """Say why ``parts`` cannot be a body's collision geometry (too many, non-finite, flat), or return None."""
    if len(parts) > MAX_CONVEX_PARTS:
        return f"{len(parts)} convex parts (at most {MAX_CONVEX_PARTS})"
    total = sum(len(part.vertices) for part in parts)
    if total > MAX_PART_VERTICES:
        return f"{total} vertices in its convex parts (at most {MAX_PART_VERTICES})"
    for index, part in enumerate(parts):
        if not np.isfinite(part.vertices).all():
            return f"non-finite vertex coordinates (NaN or Inf) in convex part {index}"
        if len(part.vertices) < 4:
            return f"convex part {index} is flat: fewer than 4 vertices"
        spans = np.linalg.svd(part.vertices - part.vertices.mean(axis=0), compute_uv=False)
        if spans[-1] <= FLAT_PART_RATIO * max(float(spans[0]), 1e-300):
            return f"convex part {index} is flat: its vertices lie in a plane, so it has no volume"
    return None


def read_parts(path: Path) -> tuple[ConvexPart, ...]:
    """The convex parts of an OBJ file: each ``o`` or ``g`` group with faces is one part.

    Polygons are split into triangle fans; ``v`` lines are global, ``f`` indices 1-based or
    negative (relative), with optional ``/texture/normal`` suffixes. Raises
    :class:`DecompositionError` naming the line of a malformed entry.
    """
    try:
        with path.open("rb") as file:
            content = file.read(MAX_PARTS_FILE_BYTES + 1)
        if len(content) > MAX_PARTS_FILE_BYTES:
            raise DecompositionError(f"{path}: larger than {MAX_PARTS_FILE_BYTES // 2**20} MiB")
        text = content.decode("utf-8")
    except (OSError, UnicodeDecodeError) as error:
        reason = error.strerror if isinstance(error, OSError) else "not a text (OBJ) file"
        raise DecompositionError(f"cannot read {path}: {reason or error}") from None
    vertices: list[tuple[float, float, float]] = []
    groups: list[list[tuple[int, int, int]]] = [[]]
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if not words:
            continue
        try:
            if words[0] == "v":
                x, y, z = (float(w) for w in words[1:4])
                vertices.append((x, y, z))
            elif words[0] == "f":
                corners = [_vertex_index(w, len(vertices)) for w in words[1:]]
                groups[-1] += [(corners[0], corners[i], corners[i + 1]) for i in range(1, len(corners) - 1)]
            elif words[0] in ("o", "g") and groups[-1]:
                groups.append([])
        except (ValueError, IndexError):
            raise DecompositionError(f"{path}: line {number}: malformed {words[0]!r} entry") from None
        if len(groups) > MAX_CONVEX_PARTS:
            raise DecompositionError(f"{path}: more than {MAX_CONVEX_PARTS} convex parts")
    if len(vertices) > MAX_PART_VERTICES:
        raise DecompositionError(f"{path}: {len(vertices)} vertices (at most {MAX_PART_VERTICES})")
    every_vertex = np.asarray(vertices, dtype=np.float64)  # once: not once per part
    parts = tuple(_part(every_vertex, faces) for faces in groups if faces)
    if not parts:
        raise DecompositionError(f"{path}: no faces, so no convex part")
    return parts


def _vertex_index(word: str, count: int) -> int:
    """0-based index of an OBJ face corner ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn`` (negative: from the end)."""
    index = int(word.split("/")[0])
    resolved = index - 1 if index > 0 else count + index
    if not 0 <= resolved < count:
        raise IndexError(index)
    return resolved


def _part(vertices: FloatArray, faces: Sequence[tuple[int, int, int]]) -> ConvexPart:
    """The part made of ``faces``, with only the vertices they use, renumbered."""
    used, inverse = np.unique(np.asarray(faces, dtype=np.int64), return_inverse=True)
    return ConvexPart(vertices[used], inverse.reshape(-1, 3).astype(np.int64))
