"""Build softcurve's documentation site, strictly: any warning fails the build.

    python docs/build.py [OUT] [--open]

Writes the HTML site into OUT (default: ``docs/_build/html``) and prints the page to
open; ``--open`` opens it in the web browser. Needs the ``docs`` extra
(``pip install ".[docs]"``: Sphinx, numpydoc, myst-parser). Strict means Sphinx's
``-W`` (warnings are errors) with ``-n`` (every cross-reference is checked): a broken
reference in a docstring, a link to a page that does not exist, a page in no table of
contents or docstring markup that does not parse fails the build with exit code 1,
after all problems are listed (``--keep-going``). The API reference, the pages of the
command line and the gallery are generated at each build by ``docs/_ext/softcurve_docs.py``.
"""

from __future__ import annotations

import argparse
import sys
import time
import webbrowser
from pathlib import Path

DOCS = Path(__file__).resolve().parent


def build(out: Path) -> int:
    """Build the site into ``out``; returns Sphinx's exit code (0: no warning)."""
    from sphinx.cmd.build import build_main

    arguments = ["-b", "html", "-W", "--keep-going", "-n", "-q"]
    arguments += ["-d", str(out / ".doctrees"), str(DOCS), str(out)]
    return build_main(arguments)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "out", nargs="?", default=str(DOCS / "_build" / "html"), help="output folder"
    )
    parser.add_argument("--open", action="store_true", help="open the site in the web browser")
    args = parser.parse_args(argv)
    try:
        import myst_parser  # noqa: F401
        import numpydoc  # noqa: F401
        import sphinx  # noqa: F401
    except ImportError as exc:
        print(f"docs/build.py: {exc.name} is missing: pip install '.[docs]'", file=sys.stderr)
        return 2
    out = Path(args.out).resolve()
    start = time.perf_counter()
    code = build(out)
    seconds = time.perf_counter() - start
    if code != 0:
        print(
            f"docs/build.py: the strict build failed (warnings above), {seconds:.0f} s",
            file=sys.stderr,
        )
        return 1
    pages = dict(line.split() for line in (out / ".pages.txt").read_text().splitlines())
    index = out / "index.html"
    print(
        f"docs/build.py: built in {seconds:.0f} s ({pages['api']} API pages, "
        f"{pages['cli']} commands, {pages['gallery']} examples): {index.as_uri()}"
    )
    if args.open:
        webbrowser.open(index.as_uri())
    return 0


if __name__ == "__main__":
    sys.exit(main())
