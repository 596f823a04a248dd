"""The one progress bar: a line on stderr for long work counted in units (chunks, rows,
simulated seconds), or, for work of unknown length (a test program's build), the seconds
so far (:func:`elapsed_line`).

On a terminal the line is redrawn in place. Elsewhere (a pipe, a log file, a batch job's
output) a redrawn line would pile up as one unreadable line: a line is written instead
per tenth of the work or :data:`LINE_EVERY` seconds after the last (and, with ``beat``,
every :data:`LINE_EVERY` seconds while no unit finishes).
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
import warnings

WIDTH = 30
"""Characters of the bar."""

LINE_EVERY = 10.0
"""Seconds between two lines of progress outside a terminal [s]: the work shown takes
tens of seconds to hours, and a log needs a sign of life, not a line per second."""

TENTHS = 10
"""Lines of progress outside a terminal per whole work, besides those of
:data:`LINE_EVERY`."""


def on_terminal(stream=None) -> bool:
    """Whether ``stream`` (default ``sys.stderr``) is a terminal, where a line can be
    redrawn in place.

    Parameters
    ----------
    stream : file, optional
        The stream.
    """
    isatty = getattr(stream or sys.stderr, "isatty", None)
    try:
        return bool(isatty and isatty())
    except ValueError:  # closed
        return False


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
    beat : bool
        Outside a terminal, also a line every :data:`LINE_EVERY` seconds while no unit
        finishes (a thread, until :meth:`close`: call it in a ``finally``), for units
        that take long (a sweep's chunks).
    """

    def __init__(self, total: float, done: float = 0, show: bool = True, unit: str = "",
                 label="", delay: float = 0.0, stream=None, beat: bool = False):  # fmt: skip
        self.total, self.first, self.show = total, done, show
        self.unit, self.label = unit, f"{label} " if label else ""
        self.delay, self.stream, self.shown = delay, stream, False
        self.start = time.perf_counter()
        self.lines = not on_terminal(stream)
        self.done, self.written, self.tenth = done, None, None
        self.lock = threading.Lock()
        self.stop = threading.Event()
        if show and beat and self.lines:  # a line every LINE_EVERY s while no unit ends
            threading.Thread(target=self._tick, daemon=True).start()
        self.update(done)

    def _tick(self) -> None:
        while not self.stop.wait(LINE_EVERY / 4):
            with self.lock:
                if self.written is not None and not self.stop.is_set():
                    if time.perf_counter() - self.written >= LINE_EVERY:
                        self._draw(self.done)

    def update(self, done: int) -> None:
        """Redraw with ``done`` units finished (outside a terminal: a line when a tenth of
        the work is passed, or :data:`LINE_EVERY` seconds after the last line).

        Parameters
        ----------
        done : float
            Units finished so far.
        """
        with self.lock:
            self.done = done
            now = time.perf_counter()
            if not self.show or now - self.start < self.delay:
                return
            if self.lines:
                tenth = int(TENTHS * min(done / self.total, 1.0)) if self.total > 0 else TENTHS
                due = self.written is None or now - self.written >= LINE_EVERY
                if tenth == self.tenth and not due:
                    return
                self.tenth = tenth
            self._draw(done)

    def _draw(self, done: float) -> None:
        """Write the line for ``done`` units (the caller holds the lock)."""
        now = time.perf_counter()
        elapsed = now - self.start
        rate = (done - self.first) / elapsed if elapsed > 0 else 0.0
        left = f", ~{(self.total - done) / rate:.0f} s left" if rate > 0 else ""
        filled = int(WIDTH * min(done / self.total, 1.0)) if self.total > 0 else WIDTH
        stream = self.stream or sys.stderr
        text = (
            f"{self.label}[{'#' * filled}{'.' * (WIDTH - filled)}] {done:.6g}/{self.total:.6g} "
            f"{self.unit}, {elapsed:.1f} s{left}"
        )
        stream.write(f"{text}\n" if self.lines else f"\r{text}   ")
        stream.flush()
        self.shown, self.written = True, now

    def close(self) -> None:
        """End the line (where it was drawn)."""
        with self.lock:
            self.stop.set()
            if self.shown and not self.lines:
                stream = self.stream or sys.stderr
                stream.write("\n")
                stream.flush()


TICK = 1.0
"""Seconds between two redraws of :func:`elapsed_line` [s]: the work takes seconds to
minutes, so finer would only redraw the same number."""


@contextlib.contextmanager
def every(interval: float, call):
    """While the block runs, ``call(seconds so far)`` every ``interval`` seconds, on a
    thread of its own that ends with the block.

    Parameters
    ----------
    interval : float
        Seconds between two calls [s].
    call : callable
        ``call(elapsed)``, ``elapsed`` in seconds since the block began.
    """
    stop = threading.Event()
    start = time.perf_counter()

    def tick():
        while not stop.wait(interval):
            call(time.perf_counter() - start)

    ticker = threading.Thread(target=tick, daemon=True)
    ticker.start()
    try:
        yield
    finally:
        stop.set()
        ticker.join()


@contextlib.contextmanager
def elapsed_line(label: str, show: bool = True):
    """While the block runs, ``label, N s`` redrawn in place on stderr every :data:`TICK`
    seconds (when ``show``), erased after it; the warnings the block gives are shown after
    the erasure, so that none lands inside the redrawn line. Outside a terminal, a line
    ``label ...`` first and ``label, N s`` every :data:`LINE_EVERY` seconds instead.

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
    drawn = [""]
    lines = not on_terminal()

    def draw(elapsed):
        text = f"{label}, {elapsed:.0f} s"
        if lines:
            sys.stderr.write(text + "\n")
        else:
            drawn[0] = text
            sys.stderr.write("\r" + text)
        sys.stderr.flush()

    if lines:
        sys.stderr.write(f"{label} ...\n")
        sys.stderr.flush()
    try:
        with warnings.catch_warnings(record=True) as caught:
            with every(LINE_EVERY if lines else TICK, draw):
                yield
    finally:
        if drawn[0]:
            sys.stderr.write("\r" + " " * len(drawn[0]) + "\r")
        for warning in caught:
            warnings.showwarning(
                warning.message, warning.category, warning.filename, warning.lineno
            )
