"""The viewer's page: HTML, style and the script that builds the tube from the scene's
ring frames and plays it with Plotly (embedded, so the file works offline).

The page and its script are files of this package, read once at import:
``viewer_page.html`` (:data:`PAGE`) and ``viewer_page.js`` (:data:`SCRIPT`), each written
in its own language. ``PAGE`` has four placeholders, each replaced once: ``__TITLE__``
(escaped text), ``__PLOTLY__`` (plotly.min.js), ``__SCENE__`` (the scene as JSON, ``</``
escaped) and ``__SCRIPT__`` (``SCRIPT``). The page reads ``#frame=N`` or ``#t=SECONDS``
from its address to choose the first frame shown, and exposes ``window.softcurveViewer``
(``show(i)``, ``play()``, ``pause()``, ``frames``); ``document.body.dataset.frame`` is
the frame drawn last.
"""

from importlib.resources import files

_HERE = files(__package__)

PAGE = _HERE.joinpath("viewer_page.html").read_text(encoding="utf-8")
"""The HTML document with its style, the placeholders where the parts go."""

SCRIPT = _HERE.joinpath("viewer_page.js").read_text(encoding="utf-8")
"""The script that builds the tube from the ring frames and plays them with Plotly."""
