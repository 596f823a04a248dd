"""The documentation site builds strictly: ``python docs/build.py OUT`` with every warning
an error (a broken cross-reference in a docstring, a link to a missing page, markup that
does not parse). Skipped with a message where the ``docs`` extra is not installed."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
DOCS_TOOLS = ("sphinx", "numpydoc", "myst_parser")


def _missing_tools() -> list[str]:
    import importlib.util

    return [name for name in DOCS_TOOLS if importlib.util.find_spec(name) is None]


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    missing = _missing_tools()
    if missing:
        pytest.skip(
            f"the docs tools are not installed ({', '.join(missing)}): pip install '.[test]'"
        )
    out = tmp_path_factory.mktemp("site")
    build = subprocess.run(
        [sys.executable, str(ROOT / "docs" / "build.py"), str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert build.returncode == 0, f"strict build failed:\n{build.stdout}\n{build.stderr}"
    return out, build.stdout


def test_the_test_extra_installs_the_docs_tools():
    """The README's test command, ``pip install ".[test]"``, installs what these tests need,
    so that none of them skips (before, the tools were in the docs extra only)."""
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    test = pyproject["project"]["optional-dependencies"]["test"]
    names = {re.match(r"[A-Za-z0-9_.-]+", r).group().lower().replace("-", "_") for r in test}
    assert set(DOCS_TOOLS) <= names, sorted(set(DOCS_TOOLS) - names)


def test_the_site_builds_strictly_with_every_part(site):
    out, printed = site
    assert "API pages" in printed
    for page in ("index", "api/index", "api/softcurve", "cli/index", "gallery/index"):
        assert (out / f"{page}.html").is_file(), page
    guide = sorted(p.stem for p in (ROOT / "docs").glob("*.md") if p.stem != "index")
    for page in guide:  # every guide page is part of the site
        assert (out / f"{page}.html").is_file(), page


def test_the_api_reference_renders_the_docstrings(site):
    out, _ = site
    model = (out / "api" / "softcurve.compiled.html").read_text(encoding="utf-8")
    assert 'id="softcurve.compiled.Model.forward_dynamics"' in model
    assert "%(" not in model  # the shared parameter texts are substituted
    assert "Generalized coordinates" in model  # ... with the text of softcurve.base.docs
    facade = (out / "api" / "softcurve.html").read_text(encoding="utf-8")
    assert 'href="softcurve.compiled.html#softcurve.compiled.Model"' in facade
    assert not (out / "api" / "softcurve.compiled._model.html").exists()  # private: no page
    results = (out / "api" / "softcurve.simulation.results.html").read_text(encoding="utf-8")
    assert 'id="softcurve.simulation.results.Trajectory"' in results  # its face ...
    simulation = (out / "api" / "softcurve.simulation.html").read_text(encoding="utf-8")
    assert 'id="softcurve.simulation.Trajectory"' not in simulation  # ... documents it once
    assert 'href="softcurve.simulation.results.html#softcurve.simulation.results.Trajectory"' in (
        simulation
    )


def test_a_page_per_command_from_its_help(site):
    from softcurve.cli import COMMANDS

    out, _ = site
    for command in COMMANDS:
        page = (out / "cli" / f"{command}.html").read_text(encoding="utf-8")
        assert f"usage: softcurve {command}" in page
    assert "--figure" in (out / "cli" / "sweep.html").read_text(encoding="utf-8")


def test_the_gallery_shows_every_example_with_its_figures(site):
    out, _ = site
    for example in sorted((ROOT / "examples").glob("*.*")):
        if example.suffix in (".py", ".toml"):
            assert (out / "gallery" / f"{example.stem}.html").is_file(), example.name
    paper = (out / "gallery" / "ifac2020.html").read_text(encoding="utf-8")
    assert "paper-tip.png" in paper and (out / "_images" / "paper-tip.png").is_file()


def test_a_link_to_a_missing_page_fails_the_strict_build(tmp_path):
    """docs/build.py with docs/conf.py on a one-page guide (nothing generated, for speed)
    that links to a page that does not exist: exit code 1, the link named."""
    if _missing_tools():
        pytest.skip("the docs tools are not installed: pip install '.[test]'")
    import shutil

    docs = tmp_path / "docs"
    shutil.copytree(ROOT / "docs" / "_ext", docs / "_ext", ignore=shutil.ignore_patterns("__py*"))
    for name in ("build.py", "conf.py"):
        shutil.copy(ROOT / "docs" / name, docs / name)
    with open(docs / "conf.py", "a", encoding="utf-8") as conf:
        conf.write("\nsoftcurve_generate = False\n")
    (docs / "index.md").write_text("# Guide\n\nSee [the missing page](no-such-page.md).\n")
    build = subprocess.run(
        [sys.executable, str(docs / "build.py"), str(tmp_path / "out")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert build.returncode == 1, build.stdout + build.stderr
    assert "no-such-page.md" in build.stderr and "strict build failed" in build.stderr
