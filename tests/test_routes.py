"""Every result names the route that integrated it (``stats["route"]``), chosen in one place
(:func:`softcurve.simulation.solvers.choose_route`); the progress bar leaves the route and
the trajectory unchanged; a fast route that should build and does not warns once; the
table of routes in docs/architecture.md names every route the code can produce."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import softcurve as sc
from softcurve.compiled._build import checksum_file
from softcurve.simulation.solvers import ROUTES, Route, casadi_only, choose_route
from softcurve.simulation.solvers import _driver as native
from softcurve.simulation.solvers._driver import SWITCHED_OFF
from softcurve.simulation.stepper import Stepper
from tests.test_sensitivity_driver import bellows_trial

Q0, QD0 = [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0]
DOCS = Path(__file__).resolve().parent.parent / "docs" / "architecture.md"

needs_driver = pytest.mark.skipif(
    native.driver() is None, reason="softcurve's C driver of CVODES cannot be built here"
)


def _exact(a, b) -> bool:
    """Equal bit for bit, NaN where NaN."""
    return a.shape == b.shape and bool(np.all((a == b) | (np.isnan(a) & np.isnan(b))))


@needs_driver
def test_simulate_names_its_route(paper_model):
    fast = sc.simulate(paper_model, Q0, QD0, t_final=0.2, dt=0.01)
    with casadi_only():
        slow = sc.simulate(paper_model, Q0, QD0, t_final=0.2, dt=0.01)
    explicit = sc.simulate(paper_model, Q0, QD0, t_final=0.2, dt=0.01, method="rk45")
    assert fast.stats["route"] == "driver"
    assert slow.stats["route"] == "casadi-cvodes"
    assert slow.stats["route_reason"] == native.CASADI_ONLY
    assert explicit.stats["route"] == "rk45"
    # the algorithm is the same on both CVODES routes; only the route differs
    assert fast.stats["method"] == slow.stats["method"]


@needs_driver
def test_a_batch_names_its_route_and_each_members(paper_model):
    q0 = [[0.064, 5.0 * k, 0.0] for k in range(5)]
    grouped = sc.simulate_batch(paper_model, q0, QD0, t_final=0.1, dt=0.01, threads=1)
    alone = sc.simulate_batch(paper_model, q0, QD0, t_final=0.1, dt=0.01, threads=1, lanes=False)
    with casadi_only():
        mapped = sc.simulate_batch(paper_model, q0, QD0, t_final=0.1, dt=0.01, threads=1)
    assert grouped.stats["route"] == "driver-lanes"
    assert grouped.stats["routes"] == ["driver-lanes"] * 5
    assert alone.stats["route"] == "driver" and alone.stats["routes"] == ["driver"] * 5
    assert mapped.stats["route"] == "casadi-cvodes"
    assert grouped.member(3).stats["route"] == "driver-lanes"
    assert alone.member(3).stats["route"] == "driver"
    # a batch too small for a group of lanes takes the driver member by member
    small = sc.simulate_batch(paper_model, q0[:2], QD0, t_final=0.1, dt=0.01, threads=1)
    assert small.stats["route"] == "driver"


@needs_driver
def test_a_batch_in_processes_names_the_routes_of_its_chunks(paper_model):
    q0 = [[0.064, 5.0 * k, 0.0] for k in range(8)]
    split = sc.simulate_batch(paper_model, q0, QD0, t_final=0.1, dt=0.01, processes=2)
    assert split.stats["routes"] == ["driver-lanes"] * 8
    assert split.stats["route"] == "driver-lanes"


@needs_driver
def test_the_sensitivities_name_their_route():
    model = sc.Model(sc.presets.ifac2020(), quadrature_nodes=4)
    one, theta = bellows_trial(model, "linear")
    one(theta)
    two, theta = bellows_trial(model, "linear", threads=2)
    two(theta)
    with casadi_only():
        reference, theta = bellows_trial(model, "linear")
    reference(theta)
    assert one.stats["route"] == "sensitivity-driver"
    assert two.stats["route"] == "sensitivity-driver-split"
    assert reference.stats["route"] == "sensitivity-casadi"


def test_the_stepper_names_its_route(paper_model):
    compiled = Stepper(paper_model, period=0.02, threads=1)
    interpreted = Stepper(paper_model, period=0.02, threads=1, compiled=False)
    expected = "stepper-lanes" if paper_model.compiled_library is not None else "stepper-casadi"
    assert compiled.route.name == compiled.stats["route"] == expected
    assert interpreted.stats["route"] == "stepper-casadi"
    assert compiled.stats["method"] == interpreted.stats["method"]


@pytest.mark.parametrize("only_casadi", [False, True])
def test_the_progress_bar_changes_neither_route_nor_trajectory(paper_model, only_casadi, capsys):
    """3.5 s: three restarts, where the paper's robot settles and switches to BDF (the
    driver's switch inside its one call against the same rule between its calls)."""
    settings = {"t_final": 3.5, "dt": 0.002}
    if only_casadi:
        with casadi_only():
            quiet = sc.simulate(paper_model, Q0, QD0, **settings)
            shown = sc.simulate(paper_model, Q0, QD0, progress=True, **settings)
    else:
        quiet = sc.simulate(paper_model, Q0, QD0, **settings)
        shown = sc.simulate(paper_model, Q0, QD0, progress=True, **settings)
    capsys.readouterr()
    assert shown.stats["route"] == quiet.stats["route"]
    assert shown.stats["method"] == quiet.stats["method"] == "cvodes-adams+bdf"
    assert shown.stats["steps"] == quiet.stats["steps"]
    for name in ("t", "q", "qd", "lam", "tau"):
        assert _exact(getattr(shown, name), getattr(quiet, name)), name


def test_the_progress_bar_keeps_the_restarts_at_changes_of_the_input(paper_model, capsys):
    """A force that steps inside a restart segment: the driver restarts there, with the bar
    as without."""
    tau = np.zeros((251, 3))
    tau[101:, 0] = -0.5
    quiet = sc.simulate(paper_model, Q0, QD0, tau=tau, t_final=2.5, dt=0.01)
    shown = sc.simulate(paper_model, Q0, QD0, tau=tau, t_final=2.5, dt=0.01, progress=True)
    capsys.readouterr()
    assert shown.stats["route"] == quiet.stats["route"]
    assert shown.stats["steps"] == quiet.stats["steps"]
    assert _exact(shown.x, quiet.x)


def _run_without_compiler(paper_model, tmp_path, **env) -> dict:
    """Two runs in a new process whose cache holds the session's model library but not
    the driver's, and whose C compiler does not exist: the driver's build fails there."""
    library = paper_model.compiled_library
    if library is None:
        pytest.skip("no C compiler: nothing is cached")
    cache = tmp_path / "cache"
    cache.mkdir()
    for source in (library, checksum_file(library)):
        shutil.copyfile(source, cache / source.name)
    script = f"""
import json, warnings
import softcurve as sc
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    model = sc.Model(sc.presets.ifac2020())
    runs = [sc.simulate(model, {Q0}, {QD0}, t_final=0.05, dt=0.01) for _ in range(2)]
print(json.dumps({{
    "compiled": model.compiled_library is not None,
    "routes": [run.stats["route"] for run in runs],
    "reason": runs[0].stats["route_reason"],
    "warnings": [str(w.message) for w in caught if issubclass(w.category, sc.RouteWarning)],
    "success": all(run.success for run in runs),
}}))
"""
    environment = {**os.environ, "SOFTCURVE_CACHE_DIR": str(cache), "CC": str(tmp_path / "no-cc"),
                   **env}  # fmt: skip
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=environment,
        timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_driver_that_cannot_build_warns_once(paper_model, tmp_path):
    found = _run_without_compiler(paper_model, tmp_path)
    assert found["compiled"] and found["success"]
    assert found["routes"] == ["casadi-cvodes", "casadi-cvodes"]
    assert "did not compile" in found["reason"]
    assert len(found["warnings"]) == 1, found["warnings"]
    assert found["reason"] in found["warnings"][0] and "casadi-cvodes" in found["warnings"][0]


def test_a_driver_switched_off_is_silent(paper_model, tmp_path):
    found = _run_without_compiler(paper_model, tmp_path, SOFTCURVE_NATIVE_CVODES="0")
    assert found["routes"] == ["casadi-cvodes", "casadi-cvodes"]
    assert found["reason"] == SWITCHED_OFF and found["warnings"] == []


def _documented_routes() -> list[str]:
    """The route names of the table under "## Routes" in docs/architecture.md."""
    text = DOCS.read_text()
    section = text.split("\n## Routes\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^\| `([a-z0-9-]+)` \|", section, flags=re.MULTILINE)


def test_the_route_table_documents_every_route():
    documented = _documented_routes()
    assert sorted(documented) == sorted(ROUTES), "docs/architecture.md ## Routes and ROUTES"
    assert len(documented) == len(set(documented))


PRODUCED = (
    r'Route\(\s*"([a-z0-9-]+)"',  # a route built from a literal name
    r'"route":\s*"([a-z0-9-]+)"',  # a result's stats naming one
    r'"route":\s*"[a-z0-9-]+"\s+if\s+\w+\s+else\s+"([a-z0-9-]+)"',  # ... or another
    r'for name in \(("stepper-[a-z0-9-]+"(?:, "[a-z0-9-]+")*)\)',  # tried in order
    r'== 1 else "([a-z0-9-]+)"',  # batch_route's name of members that disagree
)


def test_every_route_the_code_names_is_in_the_table():
    """Every route name the source gives a route or a result is a key of ROUTES, and
    Route refuses any other name (so a name made at run time is one too)."""
    source = Path(sc.__file__).parent / "simulation"
    written = set()
    for path in source.rglob("*.py"):
        text = path.read_text()
        for pattern in PRODUCED:
            for found in re.findall(pattern, text):
                written |= set(re.findall(r"[a-z0-9-]+", found))
    assert {
        "driver",
        "casadi-cvodes",
        "sensitivity-driver-split",
        "stepper-lanes",
        "mixed",
    } <= written
    assert written <= set(ROUTES), written - set(ROUTES)
    with pytest.raises(ValueError, match="unknown route"):
        Route("fastest", "no such route")


def test_rk45_is_chosen_before_any_build(paper_model):
    route = choose_route("simulate", "rk45", model=paper_model)
    assert route.name == "rk45" and route.built is None
