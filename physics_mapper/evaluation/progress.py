"""Progress of a batch run on stderr: a bar (tqdm) with the rate and an ETA on a terminal, one line per task otherwise.

On a terminal (``auto`` when the stream is a TTY) tqdm redraws one line at most :data:`REDRAW_INTERVAL`
apart; in a log (not a TTY) each finished task prints one line, with the same counts and ETA, and
nothing else. The ETA is the snapshots left divided by the rate so far (snapshots per second since
the start, start-up included, so it is pessimistic at first). The counts are ours, not tqdm's: the
total comes from the bags' metadata, which may be wrong (:meth:`Progress.status`).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from typing import Literal, TextIO

from tqdm import tqdm

from physics_mapper.model.limits import printable

ProgressMode = Literal["auto", "bar", "lines", "off"]

#: Seconds between two redraws of the bar.
REDRAW_INTERVAL = 0.1
BAR_WIDTH = 24


def duration_text(seconds: float) -> str:
    """``1:02:03``, ``02:03`` or ``00:07`` (tqdm's form): hours, minutes and seconds, rounded up."""
    return str(tqdm.format_interval(math.ceil(seconds)))


class Progress:
    """Counts snapshots and tasks done against their totals and shows them on ``stream``.

    ``prefix`` starts every line (the command's name); ``clock`` is seconds (monotonic).
    """

    def __init__(
        self,
        prefix: str,
        total_snapshots: int,
        total_tasks: int,
        stream: TextIO | None = None,
        mode: ProgressMode = "auto",
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.prefix = prefix
        self.total_snapshots = total_snapshots
        self.total_tasks = total_tasks
        self.stream = stream = stream or sys.stderr  # now, not at import: a test may have replaced it
        self.mode: ProgressMode = ("bar" if stream.isatty() else "lines") if mode == "auto" else mode
        self.clock = clock
        self.started = clock()
        self.snapshots = 0
        self.tasks = 0
        self._bar = tqdm(
            total=max(total_snapshots, 1),
            desc=prefix,
            file=stream,
            disable=self.mode != "bar",
            mininterval=REDRAW_INTERVAL,
            bar_format="{desc} {percentage:3.0f}% [{bar:" + str(BAR_WIDTH) + "}]{postfix}",  # postfix: ", ..."
            ascii=" #",
        )

    def snapshot_done(self, count: int = 1) -> None:
        """``count`` more snapshots searched."""
        self.snapshots += count
        self._redraw()

    def task_done(self, what: str) -> None:
        """One more task ended (``what`` says which, and how, for the log line)."""
        self.tasks += 1
        if self.mode == "lines":
            line = f"{self.prefix}: {self.tasks}/{self.total_tasks} {printable(what)}; {self.status()}"
            print(line, file=self.stream)
            self.stream.flush()
        else:
            self._redraw()

    def status(self) -> str:
        """Snapshots done of all, the rate and the ETA.

        The total comes from the bags' metadata, which may be wrong: once more snapshots are done
        than it said, the count shows ``N/N+`` (more than the metadata said, how many more unknown)
        and the ETA ``--``; never more done than total, nor a negative ETA.
        """
        elapsed = self.clock() - self.started
        rate = self.snapshots / elapsed if elapsed > 0.0 else 0.0
        if self.snapshots > self.total_snapshots:
            said = f"the metadata said {self.total_snapshots}"
            return f"{self.snapshots}/{self.snapshots}+ snapshots ({said}), {rate:.1f}/s, ETA --"
        left = self.total_snapshots - self.snapshots
        eta = duration_text(left / rate) if rate > 0.0 else "--"
        return f"{self.snapshots}/{self.total_snapshots} snapshots, {rate:.1f}/s, ETA {eta}"

    def bar(self) -> str:
        """The bar line: share of snapshots done (at most all), tasks done, :meth:`status`."""
        return str(self._bar)

    def _redraw(self) -> None:
        """Bring tqdm's bar to our counts (tqdm redraws at most every :data:`REDRAW_INTERVAL`)."""
        bar = self._bar
        done = min(self.snapshots, self.total_snapshots) if self.total_snapshots else 0
        if self.snapshots > self.total_snapshots:
            bar.total = done = max(self.snapshots, 1)  # the metadata said less: the bar is full
        bar.set_postfix_str(f"{self.tasks}/{self.total_tasks} tasks, {self.status()}", refresh=False)
        bar.update(done - bar.n)

    def close(self) -> None:
        """Draw the bar a last time and end its line, so that what follows starts on a new one."""
        self._bar.refresh()
        self._bar.close()
