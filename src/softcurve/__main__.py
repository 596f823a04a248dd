"""The ``softcurve`` script and ``python -m softcurve``: the command line of
:mod:`softcurve.cli`, entered through this small module so that a Ctrl-C while Python
imports the command line is one line and exit code 130, not a traceback (the script
imports this module, which imports nothing but the tiny facade; ``softcurve.cli`` is
imported inside :func:`main`)."""

import signal
import sys


def main() -> int:
    """Import and run the command line on ``sys.argv``; returns the exit code."""
    try:
        from softcurve.cli import main as command_line
    except KeyboardInterrupt:  # in the words of softcurve.cli.main's own interrupt
        print("softcurve: interrupted before starting: nothing was done", file=sys.stderr)
        return 128 + signal.SIGINT
    return command_line()


if __name__ == "__main__":
    sys.exit(main())
