"""What softcurve says while it works: records of the logger ``softcurve`` and its children
(``softcurve.compiled`` says what it compiles, where it caches it and how long it took).

The library logs and the application configures, as ``logging`` intends: an application
that has configured logging (a handler on the root logger, on ``softcurve`` or on one of
its children) gets the records through its configuration and at its levels. A plain
script that configured nothing still sees them, as lines on stderr (``softcurve: ...``),
from INFO, or from the level set on the logger ``softcurve`` when one is set: the
standard library's own last resort shows only warnings, and a compile of minutes
without a word looks like a hang. So::

    logging.getLogger("softcurve").setLevel(logging.WARNING)  # silent
    logging.getLogger("softcurve").setLevel(logging.DEBUG)    # also the seconds so far

The seconds so far of long work (:func:`timed`) are DEBUG records, one per
:data:`~softcurve.base.progress.LINE_EVERY` seconds: the progress option.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time

from softcurve.base.progress import LINE_EVERY, every

PACKAGE = "softcurve"
"""The name of the package's logger; every module logs under a child of it."""


def logger(name: str) -> logging.Logger:
    """The logger ``softcurve.<name>``.

    Parameters
    ----------
    name : str
        The part of the package that logs, e.g. ``"compiled"``.
    """
    return logging.getLogger(f"{PACKAGE}.{name}")


class ConsoleHandler(logging.Handler):
    """Each record as one line ``<prefix>message`` on stderr (looked up at each record, so
    that a redirected ``sys.stderr`` is followed).

    Parameters
    ----------
    prefix : str
        Text before each message, e.g. ``"softcurve simulate: "``.
    """

    def __init__(self, prefix: str = f"{PACKAGE}: "):
        super().__init__()
        self.prefix = prefix

    def emit(self, record: logging.LogRecord) -> None:
        try:
            sys.stderr.write(f"{self.prefix}{record.getMessage()}\n")
            sys.stderr.flush()
        except Exception:
            self.handleError(record)


FALLBACK = ConsoleHandler()
"""What writes the records when logging is not configured."""


def _configured(log: logging.Logger) -> bool:
    """Whether a record of ``log`` would reach a handler (logging was configured)."""
    current: logging.Logger | None = log
    while current is not None:
        if current.handlers:
            return True
        if not current.propagate:
            return False
        current = current.parent
    return False


def _threshold(log: logging.Logger) -> int:
    """The level from which :data:`FALLBACK` writes the records of ``log``: the first level
    set on it or its parents below the root, else INFO."""
    current: logging.Logger | None = log
    while current is not None and current.name != "root":
        if current.level != logging.NOTSET:
            return current.level
        current = current.parent
    return logging.INFO


def say(log: logging.Logger, level: int, message: str, *args) -> None:
    """``log.log(level, message, *args)`` when logging is configured; else, from INFO (or
    the level set on the package's logger), a line on stderr through :data:`FALLBACK`.

    Parameters
    ----------
    log : logging.Logger
        A logger of the package (:func:`logger`).
    level : int
        ``logging.INFO`` for what is done, ``logging.DEBUG`` for progress.
    message : str
        The message, ``%``-formatted with ``args``.
    *args
        Its arguments.
    """
    if _configured(log):
        log.log(level, message, *args)
    elif level >= _threshold(log) and not log.manager.disable >= level:
        record = log.makeRecord(log.name, level, "(softcurve)", 0, message, args, None)
        FALLBACK.handle(record)


@contextlib.contextmanager
def timed(log: logging.Logger, begin: str, end: str, so_far: str):
    """Say ``begin`` (INFO), then ``so_far % seconds`` while the block runs (DEBUG, every
    :data:`~softcurve.base.progress.LINE_EVERY` seconds), then ``end % seconds`` (INFO)
    when it ends without an error.

    Parameters
    ----------
    log : logging.Logger
        A logger of the package.
    begin : str
        What starts, e.g. ``"compiling the model of 2 segments ..."``.
    end : str
        What ended, with one ``%.1f`` for the seconds it took.
    so_far : str
        The progress, with one ``%.0f`` for the seconds so far.
    """
    say(log, logging.INFO, "%s", begin)
    start = time.perf_counter()
    with every(LINE_EVERY, lambda elapsed: say(log, logging.DEBUG, so_far, elapsed)):
        yield
    say(log, logging.INFO, end, time.perf_counter() - start)
