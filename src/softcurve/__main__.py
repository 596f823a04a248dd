"""``python -m softcurve``: the same command line as the ``softcurve`` script."""

import sys

from softcurve.cli import main

sys.exit(main())
