"""Stop signals kept while a library that swallows them runs, then acted on.

trimesh's loaders catch ``BaseException`` while they parse (they try one reader after another), so
a Ctrl-C or SIGTERM that arrives as KeyboardInterrupt inside them is lost and the command goes on
as if nothing had happened. :func:`signals_kept` holds SIGINT and SIGTERM for the duration and
delivers the first one afterwards, to the handlers that were there before: the signal stops the
command as soon as the library returns (mesh loading is bounded by the face and vertex caps).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

#: The signals that stop a command or the node.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextmanager
def signals_kept() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM are noted, not raised; the first one is delivered after it.

    Only the main thread has signal handlers (elsewhere signals reach the main thread anyway).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def note(signum: int, _: FrameType | None) -> None:
        received.append(signum)

    previous = {number: signal.signal(number, note) for number in STOP_SIGNALS}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        if received:
            signal.raise_signal(received[0])
