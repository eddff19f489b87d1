"""A bounded read-ahead window over a bag's message stream, filled by a background thread (ROS-free).

A live replay publishes each message at its recorded time; reading the bag (a chunk to decompress,
a file to open) must not delay it, nor may the replay hold the bag in memory: a ``ros2 bag record
-a`` bag with camera images is larger than RAM. :class:`ReadAhead` reads at most
:data:`READ_AHEAD_MESSAGES` messages and :data:`READ_AHEAD_BYTES` bytes ahead of the player (as
rosbag2's player reads a bounded queue ahead), and never less than one message, however large.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Iterator

from physics_mapper.bags.storage import BagMessage

#: Messages read ahead at most (rosbag2's player default is 1000 too).
READ_AHEAD_MESSAGES = 1000
#: Bytes of messages read ahead at most (one larger message is still read, alone).
READ_AHEAD_BYTES = 64 * 1024 * 1024


class ReadAhead:
    """Iterate ``messages`` while a thread reads them ahead into a bounded window; :meth:`close` stops it.

    ``peak_messages`` and ``peak_bytes`` record the fullest the window has been. An error raised
    while reading (a damaged bag) is raised again by the iteration, after the messages before it.
    """

    def __init__(
        self,
        messages: Iterator[BagMessage],
        max_messages: int = READ_AHEAD_MESSAGES,
        max_bytes: int = READ_AHEAD_BYTES,
    ) -> None:
        self.max_messages, self.max_bytes = max_messages, max_bytes
        self.peak_messages = self.peak_bytes = 0
        self._window: deque[BagMessage] = deque()
        self._bytes = 0
        self._finished = self._stopping = False
        self._error: BaseException | None = None
        self._condition = threading.Condition()
        self._thread = threading.Thread(target=self._read, args=(messages,), name="bag read-ahead", daemon=True)
        self._thread.start()

    def _full(self, size: int) -> bool:
        window = self._window
        return bool(window) and (len(window) >= self.max_messages or self._bytes + size > self.max_bytes)

    def _read(self, messages: Iterator[BagMessage]) -> None:
        try:
            for message in messages:
                size = len(message.raw)
                with self._condition:
                    self._condition.wait_for(lambda: self._stopping or not self._full(size))  # noqa: B023
                    if self._stopping:
                        break
                    self._window.append(message)
                    self._bytes += size
                    self.peak_messages = max(self.peak_messages, len(self._window))
                    self.peak_bytes = max(self.peak_bytes, self._bytes)
                    self._condition.notify_all()
        except Exception as error:
            self._error = error
        finally:
            close = getattr(messages, "close", None)
            if close is not None:
                close()  # a generator's reader closes its bag here, in the thread that used it
            with self._condition:
                self._finished = True
                self._condition.notify_all()

    def __iter__(self) -> ReadAhead:
        return self

    def __next__(self) -> BagMessage:
        with self._condition:
            self._condition.wait_for(lambda: bool(self._window) or self._finished)
            if self._window:
                message = self._window.popleft()
                self._bytes -= len(message.raw)
                self._condition.notify_all()
                return message
        if self._error is not None:
            raise self._error
        raise StopIteration

    def close(self) -> None:
        """Stop reading and wait for the thread (idempotent)."""
        with self._condition:
            self._stopping = True
            self._condition.notify_all()
        self._thread.join()

    def __enter__(self) -> ReadAhead:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
