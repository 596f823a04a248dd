"""A one-line progress bar on stderr for long work counted in units (chunks, rows)."""

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
    """

    def __init__(self, total: int, done: int = 0, show: bool = True, unit: str = "", label=""):
        self.total, self.first, self.show = total, done, show
        self.unit, self.label = unit, f"{label} " if label else ""
        self.start = time.perf_counter()
        self.update(done)

    def update(self, done: int) -> None:
        """Redraw with ``done`` units finished.

        Parameters
        ----------
        done : int
            Units finished so far.
        """
        if not self.show:
            return
        elapsed = time.perf_counter() - self.start
        rate = (done - self.first) / elapsed if elapsed > 0 else 0.0
        left = f", ~{(self.total - done) / rate:.0f} s left" if rate > 0 else ""
        filled = int(WIDTH * done / max(self.total, 1))
        sys.stderr.write(
            f"\r{self.label}[{'#' * filled}{'.' * (WIDTH - filled)}] {done}/{self.total} "
            f"{self.unit}, {elapsed:.1f} s{left}   "
        )
        sys.stderr.flush()

    def close(self) -> None:
        """End the line."""
        if self.show:
            sys.stderr.write("\n")
            sys.stderr.flush()
