"""What starting softcurve imports: ``import softcurve`` and ``softcurve --help`` must not
load heavy modules that only a few functions use (``scipy.stats`` alone took half a
second to import, eight on a busy machine; the analysis layer with ``scipy.optimize``
2.25 s). Checked on the modules loaded, in a fresh interpreter, never on time."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import softcurve

HEAVY = ("scipy.stats",)
"""Imported where used (the starts of ``equilibria``, a fit's confidence intervals)."""

LIBRARY = (
    "scipy",
    "casadi",
    "matplotlib",
    "pandas",
    "pyarrow",
    "dask",
    "softcurve.symbolic",
    "softcurve.compiled",
    "softcurve.figures",
    "softcurve.analysis",
    "softcurve.simulation",
    "softcurve.control",
    "softcurve.identification",
    "softcurve.scenarios",
    "softcurve.envs",
)
"""What starting the command line imports none of: the layers that hold CasADi, SciPy and
Matplotlib, imported by the command that is run (``softcurve simulate`` ...)."""

HELP = "from softcurve.cli import main\ntry:\n    main({argv})\nexcept SystemExit:\n    pass"
"""``softcurve ARGV`` as the console script runs it (``--help`` ends in SystemExit)."""

LOADED = """
import json, sys
{code}
print(json.dumps(sorted(sys.modules)))
"""


def _modules_after(code: str) -> set[str]:
    run = subprocess.run(
        [sys.executable, "-c", LOADED.format(code=code)], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr
    return set(json.loads(run.stdout.splitlines()[-1]))


@pytest.mark.parametrize(
    "code",
    [
        "import softcurve",
        "from softcurve.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass",
        "from softcurve.cli import main\ntry:\n    main(['simulate', '--t-final', '-1'])\n"
        "except SystemExit:\n    pass",
    ],
    ids=["import", "help", "bad-input"],
)
def test_starting_softcurve_loads_no_heavy_module(code):
    loaded = _modules_after(code)
    heavy = sorted(m for m in loaded if any(m == h or m.startswith(h + ".") for h in HEAVY))
    assert not heavy, f"{code!r} imports {heavy[:5]}: import them where they are used"


def _within(loaded: set[str], prefixes) -> list[str]:
    return sorted(m for m in loaded if any(m == p or m.startswith(p + ".") for p in prefixes))


@pytest.mark.parametrize(
    ("code", "absent"),
    [
        ("import softcurve", (*LIBRARY, "numpy", "softcurve.description", "softcurve.cli")),
        ("from softcurve import __version__", (*LIBRARY, "numpy")),
        (HELP.format(argv=["--help"]), LIBRARY),
        (HELP.format(argv=["--version"]), LIBRARY),
        (HELP.format(argv=["simulate", "--help"]), LIBRARY),
        (HELP.format(argv=["sweep", "--help"]), LIBRARY),
    ],
    ids=["import", "version-attribute", "help", "version", "simulate-help", "sweep-help"],
)
def test_starting_softcurve_loads_no_layer_with_casadi_scipy_or_matplotlib(code, absent):
    loaded = _modules_after(code)
    assert not _within(loaded, absent), f"{code!r} imports {_within(loaded, absent)[:8]}"


def test_python_m_softcurve_help_imports_no_library_layer():
    """The real entry (``python -m softcurve`` runs ``softcurve/__main__.py``), read
    from ``-X importtime``'s list of every module imported."""
    run = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "softcurve", "--help"],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    imported = {
        line.rpartition("|")[2].strip()
        for line in run.stderr.splitlines()
        if line.startswith("import time:")
    }
    assert "softcurve.cli" in imported and "argparse" in imported  # the list is complete
    assert not _within(imported, LIBRARY), _within(imported, LIBRARY)[:8]


def test_the_facade_gives_each_name_where_it_is_defined():
    """The facade imports a name's module on the name's first use (PEP 562): every name
    of ``__all__`` is there, listed by ``dir()``, the object its module defines; the
    layers are reached as attributes; an unknown name is an AttributeError."""
    assert set(softcurve.__all__) <= set(dir(softcurve))
    from softcurve import Model, presets, simulate  # the form users write

    assert Model is softcurve.compiled.Model and simulate is softcurve.simulation.simulate
    assert presets is softcurve.description.presets
    for name in softcurve.__all__:
        assert getattr(softcurve, name) is not None, name
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        softcurve.no_such_name  # noqa: B018


def test_the_facade_takes_its_names_from_public_modules():
    """The facade's table is strings, which the architecture test does not read as
    imports: its modules are public modules or faces, never private ones (rule 3)."""
    modules = set(softcurve._FACES)
    assert "softcurve.compiled" in modules
    private = [m for m in modules if any(part.startswith("_") for part in m.split("."))]
    assert not private, private


def test_the_check_sees_a_heavy_import():
    assert "scipy.stats" in _modules_after("import scipy.stats")
    assert _within(_modules_after("import softcurve\nsoftcurve.Model"), LIBRARY)
