"""The ``softcurve`` script and ``python -m softcurve``: the command line of
:mod:`softcurve.cli`, entered through this small module so that a Ctrl-C while Python
imports the command line is one line and exit code 130, not a traceback (the script
imports this module, which imports nothing but the tiny facade; ``softcurve.cli`` is
imported inside :func:`main`)."""

import os
import signal
import sys

INTERRUPTED = 128 + signal.SIGINT
"""Exit code of a command stopped by Ctrl-C, as a shell reports it."""


def _interrupted_at_exit(signum, frame) -> None:
    """Ctrl-C once the command has returned (while Python ends its threads and worker
    pools): one line and exit code 130 at once, instead of a traceback from its teardown;
    the command's output is flushed already."""
    os.write(2, b"softcurve: interrupted while exiting: the command had finished\n")
    os._exit(INTERRUPTED)


def _interrupted_in_a_callback(unraisable) -> None:
    """A Ctrl-C that lands in a callback Python cannot raise from (a weakref's or a
    finalizer's, run by the garbage collector at any point) would be printed as ignored, a
    traceback, and lost: the command stops there, one line and exit code 130 (its files
    are written whole or not at all). Anything else goes to Python's own hook."""
    if unraisable.exc_type is not KeyboardInterrupt:
        sys.__unraisablehook__(unraisable)
        return
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: nothing left to say there
            pass
    os.write(2, b"softcurve: interrupted\n")
    os._exit(INTERRUPTED)


def main() -> int:
    """Import and run the command line on ``sys.argv``; returns the exit code."""
    sys.unraisablehook = _interrupted_in_a_callback
    try:
        from softcurve.cli import main as command_line
    except KeyboardInterrupt:  # in the words of softcurve.cli.main's own interrupt
        print("softcurve: interrupted before starting: nothing was done", file=sys.stderr)
        return INTERRUPTED
    code = None
    try:
        code = command_line()
        sys.stdout.flush()
        sys.stderr.flush()
        signal.signal(signal.SIGINT, _interrupted_at_exit)
    except KeyboardInterrupt:
        if code is None:  # in the command's last steps, past its own handler
            print("softcurve: interrupted", file=sys.stderr)
            return INTERRUPTED
        # between the command's return and the exit handler's installation
        _interrupted_at_exit(signal.SIGINT, None)
    return code


if __name__ == "__main__":
    sys.exit(main())
