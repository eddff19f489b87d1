"""Loading a scene or problem file in a thread of its own: the node keeps handling events, a command its signals.

A scene's first load may decompose meshes (a minute for CoACD); :class:`SceneLoading` runs
:func:`~physics_mapper.model.scene_files.load_scene` in a thread while the node spins and reports
what is happening (:attr:`SceneLoading.activity`: the decomposition under way). :meth:`SceneLoading.cancel`
stops it within the decomposition's poll period (its child process is killed), or leaves a mesh parser,
which cannot be stopped, to finish in a daemon thread while the node exits.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Generic, TypeVar

from physics_mapper.model.decomposition import Progress, cancelled_by, stderr_progress
from physics_mapper.model.scene import Problem, Scene

Loaded = TypeVar("Loaded", Scene, Problem)

#: Seconds :meth:`SceneLoading.cancel` waits for the loading thread: longer than a decomposition's
#: poll period (``decomposition.STOP_POLL``), far shorter than parsing a mesh at the face cap (1.6 s).
CANCEL_WAIT = 0.1


class SceneLoading(Generic[Loaded]):
    """A scene (or problem) file being loaded by ``load`` in a background thread; :meth:`result` waits for it."""

    def __init__(self, path: Path, load: Callable[[Path, Progress], Loaded]) -> None:
        self.path = path
        self._load: Callable[[Path, Progress], Loaded] = load
        self._cancel = threading.Event()
        self._activity: str | None = None
        self._loaded: Loaded | None = None
        self._error: BaseException | None = None
        # Waited on instead of Thread.join: in CPython 3.11 a join that a signal's KeyboardInterrupt
        # interrupts marks the thread as ended while it runs, and a later join returns at once, so a
        # stopping command would exit and leave a decomposition's child running.
        self._ended = threading.Event()
        threading.Thread(target=self._run, name="scene loading", daemon=True).start()

    def _run(self) -> None:
        try:
            with cancelled_by(self._cancel):
                self._loaded = self._load(self.path, self._progress)
        except BaseException as error:  # handed to the thread that asks for the result
            self._error = error
        finally:
            self._ended.set()

    def _progress(self, line: str) -> None:
        stderr_progress(line)
        self._activity = line if line.startswith("decomposing") else None

    @property
    def done(self) -> bool:
        return self._ended.is_set()

    @property
    def activity(self) -> str | None:
        """What the load is doing now, if it is slow work (``decomposing <mesh> with <method> ...``)."""
        return self._activity

    def wait(self, seconds: float) -> bool:
        """Wait up to ``seconds`` for the load to end; whether it has."""
        return self._ended.wait(seconds)

    def cancel(self) -> bool:
        """Stop the load and wait up to :data:`CANCEL_WAIT` seconds for its thread; whether it has ended.

        A decomposition's child process is killed within its poll period, and waited for whatever it
        takes (an exiting process must not leave it running). A mesh parser (trimesh) cannot be stopped:
        it goes on in the thread, a daemon that does not keep the process from exiting.
        """
        self._cancel.set()
        return self._ended.wait(None if self._activity is not None else CANCEL_WAIT)

    def result(self) -> Loaded:
        """What was loaded, once loaded; raises what loading raised (a SceneError)."""
        self._ended.wait()
        if self._error is not None:
            raise self._error
        assert self._loaded is not None
        return self._loaded


def load_stoppably(path: str | Path, load: Callable[[Path, Progress], Loaded]) -> Loaded:
    """``load`` (:func:`~physics_mapper.model.scene_files.load_scene` or ``load_problem``) of ``path`` in a
    thread, this one waiting: a signal's KeyboardInterrupt stops the wait at once (a mesh parser, which
    cannot be stopped and holds signals in the main thread, is left to its daemon thread; a
    decomposition's child is killed)."""
    loading = SceneLoading(Path(path), load)
    try:
        return loading.result()
    except KeyboardInterrupt:
        loading.cancel()
        raise
