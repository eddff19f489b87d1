"""rclpy context and spinning helpers shared by the node, the publisher and the bag player, and clean stops on signals.

Stopping on SIGINT and SIGTERM (:class:`SignalStop`): rclpy's own handlers shut the context down
from a signal, under whatever the process is doing; every rclpy call after that (a publish in
the middle of a tick, the executor's next wait) raises, and the error escapes with a traceback and
exit code 1. With :class:`SignalStop` rclpy installs no handler; a signal only asks the spin loop
to stop, and the process shuts rclpy down itself, in order. Where stopping at once is safe (a
search), :meth:`SignalStop.interruptible` lets the first signal interrupt the work with
KeyboardInterrupt instead. Later signals are ignored: the stop is already under way.

A command (:func:`ros_for_command`) stops with KeyboardInterrupt instead, except inside rclpy's
executor (:func:`spin_once`): an interrupt there can land in the middle of building a task, whose
half-made object then prints a traceback when collected; the signal's interrupt is raised when the
spin returns.

Before the handlers exist, the entry point holds both signals pending
(``physics_mapper.commands.node.hold_stop_signals``) rather than let Python raise KeyboardInterrupt
in the middle of an import: such an interrupt can be lost, or leave CPython exiting by SIGINT after
all (observed: exit -2 with the interrupt caught; CPython marks the process as interrupted when the
interrupt lands in code a C extension runs through ``PyRun_String``, even if Python catches it).
:meth:`SignalStop.install` releases them, so a signal sent during start-up is acted on, not lost.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

import rclpy
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import ok

#: The signals that stop the process cleanly.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: Seconds an idle spin waits before it looks for a stop request again (the latency of a stop when idle).
STOP_POLL = 0.1


def shutdown_ros() -> None:
    """Shut rclpy down unless a signal (SIGINT, SIGTERM) already did."""
    if ok():
        rclpy.shutdown()


class _CommandStop:
    """The signal handler of :func:`ros_for_command`: the first signal raises KeyboardInterrupt, at
    once, or when the current :func:`spin_once` returns; later ones are ignored."""

    def __init__(self) -> None:
        self.stopping = False
        self.spinning = 0
        self.pending = False

    def reset(self) -> None:
        """No signal seen yet (a command run in a process that ran one before)."""
        self.stopping = self.pending = False

    def handle(self, number: int, frame: FrameType | None) -> None:
        for stop_signal in STOP_SIGNALS:
            signal.signal(stop_signal, signal.SIG_IGN)
        if self.stopping:
            return
        self.stopping = True
        if self.spinning:
            self.pending = True
        else:
            raise KeyboardInterrupt

    @contextmanager
    def spin(self) -> Iterator[None]:
        """A section of rclpy's executor: the signal's KeyboardInterrupt waits for its end."""
        self.spinning += 1
        try:
            yield
        finally:
            self.spinning -= 1
            if self.pending and not self.spinning:
                self.pending = False
                raise KeyboardInterrupt


_command_stop = _CommandStop()


@contextmanager
def ros_for_command() -> Iterator[None]:
    """rclpy for a command that the first SIGINT or SIGTERM stops with KeyboardInterrupt (``publish``, a
    live replay); later ones are ignored.

    rclpy installs no signal handler: its handler shut the context down from the signal, and one
    arriving between the ``ok()`` check and the shutdown of :func:`shutdown_ros` made the shutdown
    raise (``rcl_shutdown already called``), as did a publish after it. Here the first signal
    raises KeyboardInterrupt (inside :func:`spin_once`, when it returns) and ignores both from then on
    (a second one during the interpreter's exit, when Python puts the default action back for the
    handlers it set, killed the process); ROS is shut down once, when the block ends, with the
    signals held meanwhile.
    """
    _command_stop.reset()
    previous = {number: signal.signal(number, _command_stop.handle) for number in STOP_SIGNALS}
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield
    finally:
        held = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            shutdown_ros()
        finally:
            if not _command_stop.stopping:
                for number, handler in previous.items():
                    signal.signal(number, handler)
            signal.pthread_sigmask(signal.SIG_SETMASK, held)


def spin_once(spinner: Node | Executor, timeout_sec: float) -> None:
    """Handle one of ``spinner``'s events (a node's with rclpy's global executor), waiting up to
    ``timeout_sec``; a command's stop signal interrupts only when it returns (see the module)."""
    with _command_stop.spin():
        if isinstance(spinner, Executor):
            spinner.spin_once(timeout_sec=timeout_sec)
        else:
            rclpy.spin_once(spinner, timeout_sec=timeout_sec)


def spin_for(node: Node, seconds: float) -> None:
    """Handle ``node``'s events for ``seconds`` (less if rclpy shuts down)."""
    end = time.monotonic() + seconds
    while ok() and time.monotonic() < end:
        spin_once(node, 0.05)


class SignalStop:
    """SIGINT and SIGTERM, from :meth:`install` on, ask the process to stop (:attr:`requested`).

    Outside :meth:`interruptible` sections a signal only sets :attr:`requested`, so that what the
    process is doing (publishing, spinning, shutting down) completes; inside one, the first
    signal also raises KeyboardInterrupt there. Pass ``signal_handler_options=SignalHandlerOptions.NO``
    to ``rclpy.init`` so that rclpy does not replace these handlers with its own.
    """

    def __init__(self) -> None:
        self.requested = False
        self._interruptible = 0

    def install(self) -> None:
        """Handle both signals from now on; one held pending by the entry point is delivered now."""
        for number in STOP_SIGNALS:
            signal.signal(number, self._handle)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)

    def _handle(self, number: int, frame: FrameType | None) -> None:
        if self.requested:
            return
        self.requested = True
        if self._interruptible:
            raise KeyboardInterrupt

    @contextmanager
    def interruptible(self) -> Iterator[None]:
        """A section that the first signal interrupts with KeyboardInterrupt (at once, also if it came before)."""
        if self.requested:
            raise KeyboardInterrupt
        self._interruptible += 1
        try:
            yield
        finally:
            self._interruptible -= 1
