"""The one progress bar: a line on stderr for long work counted in units (chunks, rows,
simulated seconds)."""

from __future__ import annotations

import sys
import time

WIDTH = 30
"""Characters of the bar."""


class ProgressLine:
    """``label [#####.....] 12/40 chunks, 10.1 s, ~23 s left`` on stderr, redrawn in place.

    Parameters
    ----------
    total : int
        Units of the whole work.
    done : int
        Units already done before this run (they do not count for the rate).
    show : bool
        Whether to draw at all.
    unit : str
        What is counted, e.g. ``"chunks"``.
    label : str
        Text before the bar, e.g. ``"writing trajectory.csv"``.
    delay : float
        Seconds of work before the bar appears (a short run shows none) [s].
    stream : file, optional
        Where to draw (default ``sys.stderr`` at each draw).
    """

    def __init__(self, total: float, done: float = 0, show: bool = True, unit: str = "",
                 label="", delay: float = 0.0, stream=None):  # fmt: skip
        self.total, self.first, self.show = total, done, show
        self.unit, self.label = unit, f"{label} " if label else ""
        self.delay, self.stream, self.shown = delay, stream, False
        self.start = time.perf_counter()
        self.update(done)

    def update(self, done: int) -> None:
        """Redraw with ``done`` units finished.

        Parameters
        ----------
        done : float
            Units finished so far.
        """
        elapsed = time.perf_counter() - self.start
        if not self.show or elapsed < self.delay:
            return
        rate = (done - self.first) / elapsed if elapsed > 0 else 0.0
        left = f", ~{(self.total - done) / rate:.0f} s left" if rate > 0 else ""
        filled = int(WIDTH * min(done / self.total, 1.0)) if self.total > 0 else WIDTH
        stream = self.stream or sys.stderr
        stream.write(
            f"\r{self.label}[{'#' * filled}{'.' * (WIDTH - filled)}] {done:.6g}/{self.total:.6g} "
            f"{self.unit}, {elapsed:.1f} s{left}   "
        )
        stream.flush()
        self.shown = True

    def close(self) -> None:
        """End the line (where it was drawn)."""
        if self.shown:
            stream = self.stream or sys.stderr
            stream.write("\n")
            stream.flush()
