"""Where a batch run's tasks execute: in this process, on a local process pool, or on a Ray cluster.

Every executor calls ``function(*arguments, progress=...)`` once per task and reports each task to
:class:`Events` as it ends, in whatever order the tasks end (callers key results by task index, so
the outcome does not depend on the executor). The contract, the same for all three:

- ``progress`` is a callable the function calls after each unit of work, relayed to
  :meth:`Events.progress`; None where the executor cannot relay it (Ray: progress per task).
- A task whose function raises is reported failed with the error, not retried (it would raise again).
- A task whose worker process dies (a crash, the out-of-memory killer) is run once more on a new
  worker (:data:`ATTEMPTS`), then reported failed. In this process there is no worker to lose.
- KeyboardInterrupt stops the run: workers are stopped (tasks in flight are lost) and it propagates.

:class:`ProcessPool` is ``multiprocessing`` (spawn) with one pipe per worker, so that a dead worker's
task is known exactly; :class:`RayCluster` is Ray's task API, whose ``max_retries`` does the retry.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import multiprocessing
import os
import signal
import socket
import traceback
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from multiprocessing.context import SpawnContext, SpawnProcess
from types import TracebackType
from typing import Any, Protocol, Self

from physics_mapper.model.errors import InputError

#: Runs of a task whose worker died: the first and one retry.
ATTEMPTS = 2
#: Seconds a stopped worker gets to exit before it is killed.
STOP_TIMEOUT = 2.0


@dataclass(frozen=True)
class TaskFailure:
    """Why a task gave no result: ``error`` (one line) after ``attempts`` runs."""

    error: str
    attempts: int


class Events(Protocol):
    """What an executor reports while it runs (always from the calling thread)."""

    def progress(self, index: int) -> None:
        """Task ``index`` finished one unit of work."""

    def finished(self, index: int, output: Any) -> None:
        """Task ``index`` returned ``output``."""

    def failed(self, index: int, failure: TaskFailure) -> None:
        """Task ``index`` gave no result."""


class Executor(Protocol):
    """Runs tasks; a context manager (a cluster is connected on entry and left on exit).

    ``remote_workers``: the workers may run on other machines, so tasks must carry their data, not paths.
    """

    remote_workers: bool

    def __enter__(self) -> Self: ...

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None: ...

    def description(self) -> dict[str, Any]:
        """Which executor this is, for the report: ``executor`` and its size."""

    def run(self, function: Callable[..., Any], calls: Sequence[tuple[Any, ...]], events: Events) -> None:
        """Call ``function(*calls[i], progress=...)`` for every i, reporting each to ``events``."""


def error_line(error: BaseException) -> str:
    """An exception as one line: its type and message, and where it was raised."""
    frames = traceback.extract_tb(error.__traceback__)
    where = f" (at {os.path.basename(frames[-1].filename)}:{frames[-1].lineno})" if frames else ""
    message = " ".join(str(error).split())
    return f"{type(error).__name__}: {message}{where}" if message else f"{type(error).__name__}{where}"


class _Entered:
    """Context-manager methods for executors that hold nothing between runs."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        return None


class InProcess(_Entered):
    """Every task in this process, one after the other (``--workers 0``: for debugging and profiling)."""

    remote_workers = False

    def description(self) -> dict[str, Any]:
        return {"executor": "in-process", "workers": 0}

    def run(self, function: Callable[..., Any], calls: Sequence[tuple[Any, ...]], events: Events) -> None:
        for index, arguments in enumerate(calls):
            try:
                output = function(*arguments, progress=functools.partial(events.progress, index))
            except Exception as error:
                events.failed(index, TaskFailure(error_line(error), 1))
            else:
                events.finished(index, output)


# --- local process pool -------------------------------------------------------------------------------


def _serve(connection: Connection) -> None:
    """A pool worker: run the tasks it is sent until it is sent None (or its driver goes away)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the driver's to handle: it stops the workers
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)  # pybullet's banner and other C-level chatter must not interleave with the report
    while True:
        try:
            message = connection.recv()
        except EOFError:
            return
        if message is None:
            return
        index, function, arguments = message

        def progress(index: int = index) -> None:
            connection.send(("progress", index, None))

        try:
            output = function(*arguments, progress=progress)
        except Exception as error:
            connection.send(("error", index, error_line(error)))
        else:
            connection.send(("done", index, output))


def _death(process: SpawnProcess) -> str:
    process.join(STOP_TIMEOUT)
    code = process.exitcode
    if code is not None and code < 0:
        return f"killed by {signal.Signals(-code).name}"
    return f"exit code {code}"


class _Worker:
    """One pool process and the driver's end of its pipe; ``task`` is the index it runs (None: idle)."""

    def __init__(self, context: SpawnContext) -> None:
        self.connection, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child,), daemon=True)
        self.process.start()
        child.close()
        self.task: int | None = None

    def send(self, index: int, function: Callable[..., Any], arguments: tuple[Any, ...]) -> None:
        self.connection.send((index, function, arguments))
        self.task = index

    def stop(self) -> None:
        """Ask an idle worker to exit; end a busy one (interrupted run) at once."""
        if self.task is None and self.process.is_alive():
            with contextlib.suppress(OSError):  # it died meanwhile
                self.connection.send(None)
            self.process.join(STOP_TIMEOUT)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(STOP_TIMEOUT)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.connection.close()


class ProcessPool(_Entered):
    """``workers`` local processes (started per run, spawn), each running one task at a time in its own
    pybullet world; a worker that dies is replaced and its task run once more."""

    remote_workers = False

    def __init__(self, workers: int) -> None:
        if workers < 1:
            raise ValueError(f"a process pool needs at least 1 worker, got {workers}")
        self.workers = workers

    def description(self) -> dict[str, Any]:
        return {"executor": "process pool", "workers": self.workers}

    def run(self, function: Callable[..., Any], calls: Sequence[tuple[Any, ...]], events: Events) -> None:
        context = multiprocessing.get_context("spawn")
        waiting = deque(range(len(calls)))
        attempts = [0] * len(calls)
        workers: list[_Worker] = []
        try:
            workers = [_Worker(context) for _ in range(min(self.workers, len(calls)))]
            while waiting or any(worker.task is not None for worker in workers):
                for position, worker in enumerate(workers):
                    if worker.task is None and waiting:
                        index = waiting.popleft()
                        attempts[index] += 1
                        workers[position] = self._hand_over(context, worker, index, function, calls[index])
                busy = [worker for worker in workers if worker.task is not None]
                ready = wait([w.connection for w in busy] + [w.process.sentinel for w in busy])
                for worker in busy:
                    woken = worker.connection in ready or worker.process.sentinel in ready
                    if woken and not self._collect(worker, events, attempts, waiting):
                        worker.stop()
                        workers.remove(worker)
                        if waiting:  # a new worker for the task put back (or the next)
                            workers.append(_Worker(context))
        finally:
            for worker in workers:
                worker.stop()

    @staticmethod
    def _hand_over(
        context: SpawnContext, worker: _Worker, index: int, function: Callable[..., Any], arguments: tuple[Any, ...]
    ) -> _Worker:
        """Send a task to an idle worker; one that died while idle is replaced first (no attempt lost)."""
        try:
            worker.send(index, function, arguments)
        except OSError:
            worker.stop()
            worker = _Worker(context)
            worker.send(index, function, arguments)
        return worker

    @staticmethod
    def _collect(worker: _Worker, events: Events, attempts: list[int], waiting: deque[int]) -> bool:
        """Take one message from a busy worker; False if it died: its task goes back in front, or fails for good."""
        index = worker.task
        assert index is not None
        try:
            if worker.connection.poll():
                kind, _, payload = worker.connection.recv()
                if kind == "progress":
                    events.progress(index)
                    return True
                worker.task = None
                if kind == "done":
                    events.finished(index, payload)
                else:
                    events.failed(index, TaskFailure(payload, attempts[index]))
                return True
        except (EOFError, OSError):
            pass  # the pipe broke: the worker is gone
        if worker.process.is_alive():
            return True  # woken by a message that another wait() will deliver
        how = _death(worker.process)
        worker.task = None
        if attempts[index] < ATTEMPTS:
            waiting.appendleft(index)
        else:
            events.failed(
                index, TaskFailure(f"worker process died ({how}) in each of {attempts[index]} runs", ATTEMPTS)
            )
        return False


# --- Ray ----------------------------------------------------------------------------------------------


class RayUnavailable(RuntimeError):
    """Ray is installed but the cluster cannot be reached or started."""


#: Seconds to wait for a cluster's head to accept a connection (Ray itself would retry for minutes).
CONNECT_TIMEOUT = 5.0


def _check_reachable(address: str) -> None:
    """InputError for an address of no known form; RayUnavailable if a ``HOST:PORT`` head does not answer."""
    if address in ("auto", "local"):
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise InputError(f"--ray {address}: expected auto, local, HOST:PORT or ray://HOST:PORT")
    try:
        socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT).close()
    except OSError as error:
        raise RayUnavailable(f"cannot connect to Ray at {address}: {error.strerror or error}") from None


#: Seconds between looks at the cluster for finished tasks.
RAY_POLL_INTERVAL = 0.5
#: Tasks submitted at a time per CPU of the cluster: enough to keep every CPU busy.
RAY_TASKS_PER_CPU = 2
_SCALARS = (int, float, str, bool, type(None))


class RayCluster:
    """Tasks as Ray tasks (one CPU each) on the cluster at ``address``: ``auto`` (the one this machine
    belongs to, or RAY_ADDRESS), ``HOST:PORT`` of its head, ``ray://HOST:PORT`` (Ray Client) or
    ``local`` (a new one-machine instance for this run, ``cpus`` CPUs, stopped at the end).

    Each task runs in a Ray worker process with its own pybullet world. At most
    :data:`RAY_TASKS_PER_CPU` tasks per CPU of the cluster are submitted at a time, so that the data
    of the tasks not yet running stays unread; arguments shared between tasks (the scene, a bag's
    input topics) are put in the object store once and released when their tasks are done. Ray
    reruns a task whose worker died once (``max_retries``). When this process is already connected
    to Ray (a program that uses the API and called ``ray.init`` itself), that connection is used and
    left open.
    """

    remote_workers = True

    def __init__(self, address: str, cpus: int | None = None) -> None:
        self.address = address
        self.cpus = cpus
        self._connected_here = False

    def __enter__(self) -> Self:
        try:
            import ray
        except ImportError:
            raise InputError(
                "--ray needs Ray, an optional dependency: pip install 'physics_mapper[ray]' "
                "(or the pinned version in requirements-ray.txt)"
            ) from None
        _check_reachable(self.address)
        if ray.is_initialized():
            return self
        options: dict[str, Any] = {"log_to_driver": False, "logging_level": logging.ERROR}
        if self.address == "local":
            options |= {"num_cpus": self.cpus, "include_dashboard": False}
        try:
            ray.init(address=self.address, **options)
        except (ConnectionError, RuntimeError, ValueError) as error:
            raise RayUnavailable(f"cannot connect to Ray at {self.address}: {' '.join(str(error).split())}") from None
        self._connected_here = True
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        if self._connected_here:
            import ray

            ray.shutdown()
            self._connected_here = False

    def description(self) -> dict[str, Any]:
        import ray

        alive = [node for node in ray.nodes() if node.get("Alive")]  # type: ignore[no-untyped-call]
        cpus = int(ray.cluster_resources().get("CPU", 0))  # type: ignore[no-untyped-call]
        return {"executor": "ray", "address": self.address, "nodes": len(alive), "cpus": cpus}

    def run(self, function: Callable[..., Any], calls: Sequence[tuple[Any, ...]], events: Events) -> None:
        import ray

        remote = ray.remote(num_cpus=1, max_retries=ATTEMPTS - 1)(function)
        store = _SharedObjects()
        limit = max(1, RAY_TASKS_PER_CPU * int(ray.cluster_resources().get("CPU", 1)))  # type: ignore[no-untyped-call]
        pending: dict[Any, tuple[int, list[int]]] = {}  # reference -> task index, the stored arguments it uses
        submitted = 0
        try:
            while submitted < len(calls) or pending:
                while submitted < len(calls) and len(pending) < limit:
                    arguments, keys = store.share(calls[submitted])
                    pending[remote.remote(*arguments, progress=None)] = (submitted, keys)
                    submitted += 1
                ready, _ = ray.wait(list(pending), num_returns=1, timeout=RAY_POLL_INTERVAL)
                for reference in ready:
                    index, keys = pending.pop(reference)
                    store.release(keys)
                    _report(index, reference, events)
        except KeyboardInterrupt:
            for reference in pending:
                ray.cancel(reference, force=True)
            raise


class _SharedObjects:
    """Task arguments in Ray's object store: each object put once, and dropped (so that Ray frees it)
    when no submitted task uses it any more. The object is kept with its reference, so that its id()
    cannot be taken by another object meanwhile."""

    def __init__(self) -> None:
        self._stored: dict[int, tuple[Any, Any, int]] = {}  # id -> (object, reference, tasks using it)

    def share(self, arguments: tuple[Any, ...]) -> tuple[list[Any], list[int]]:
        """The arguments with every non-scalar one as its object reference, and the ids used."""
        import ray

        shared, keys = [], []
        for argument in arguments:
            if isinstance(argument, _SCALARS):
                shared.append(argument)
                continue
            key = id(argument)
            kept, reference, users = self._stored.get(key, (argument, None, 0))
            self._stored[key] = (kept, reference if reference is not None else ray.put(argument), users + 1)
            shared.append(self._stored[key][1])
            keys.append(key)
        return shared, keys

    def release(self, keys: Sequence[int]) -> None:
        for key in keys:
            kept, reference, users = self._stored[key]
            if users == 1:
                del self._stored[key]
            else:
                self._stored[key] = (kept, reference, users - 1)


def _report(index: int, reference: Any, events: Events) -> None:
    """A finished Ray task's result, or why there is none, to ``events``."""
    import ray
    from ray.exceptions import RayError, RayTaskError

    try:
        output = ray.get(reference)
    except RayTaskError as error:
        cause = error.cause if isinstance(error.cause, BaseException) else error
        events.failed(index, TaskFailure(error_line(cause), 1))
    except RayError as error:
        events.failed(index, TaskFailure(f"worker died in each of {ATTEMPTS} runs ({type(error).__name__})", ATTEMPTS))
    else:
        events.finished(index, output)
