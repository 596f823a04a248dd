"""The one progress bar: a line on stderr for long work counted in units (chunks, rows,
simulated seconds), or, for work of unknown length (a model's compile), the seconds so
far (:func:`elapsed_line`)."""

from __future__ import annotations

import contextlib
import sys
import threading
import time
import warnings

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


TICK = 1.0
"""Seconds between two redraws of :func:`elapsed_line` [s]: the work takes seconds to
minutes, so finer would only redraw the same number."""


@contextlib.contextmanager
def elapsed_line(label: str, show: bool = True):
    """While the block runs, ``label, N s`` redrawn in place on stderr every :data:`TICK`
    seconds (when ``show``), erased after it; the warnings the block gives are shown after
    the erasure, so that none lands inside the redrawn line.

    Parameters
    ----------
    label : str
        What runs, e.g. ``"softcurve simulate: compiling"``.
    show : bool
        Whether to draw at all.
    """
    if not show:
        yield
        return
    stop = threading.Event()
    start = time.perf_counter()
    drawn = [""]

    def tick():
        while not stop.wait(TICK):
            drawn[0] = f"{label}, {time.perf_counter() - start:.0f} s"
            sys.stderr.write("\r" + drawn[0])
            sys.stderr.flush()

    ticker = threading.Thread(target=tick, daemon=True)
    try:
        with warnings.catch_warnings(record=True) as caught:
            ticker.start()
            try:
                yield
            finally:
                stop.set()
                ticker.join()
    finally:
        if drawn[0]:
            sys.stderr.write("\r" + " " * len(drawn[0]) + "\r")
        for warning in caught:
            warnings.showwarning(
                warning.message, warning.category, warning.filename, warning.lineno
            )
