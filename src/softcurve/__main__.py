"""``python -m softcurve``: the same command line as the ``softcurve`` script."""

import signal
import sys

try:  # Ctrl-C while Python imports the command line: one line, as main() says it
    from softcurve.cli import main
except KeyboardInterrupt:
    print("softcurve: interrupted before starting: nothing was done", file=sys.stderr)
    sys.exit(128 + signal.SIGINT)

sys.exit(main())
