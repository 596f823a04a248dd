"""``python -m softcurve``: the same command line as the ``softcurve`` script."""

import sys

from .cli import main

sys.exit(main())
