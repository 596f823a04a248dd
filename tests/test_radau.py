"""Radau IIA of order 5 in the C driver (``method="radau"``): its constants against their
defining conditions, its order on problems with a known solution (one of them stiff), the
energy it never creates, the trajectories of CVODES to the tolerance on every segment
kind, actuator and scenario file, batches, its fallback and its failures."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.cli import main
from softcurve.compiled import NativeFunction, compile_source
from softcurve.identification.experiments import Experiment
from softcurve.identification.maps import bending_angle_map
from softcurve.simulation import JACOBIANS, METHODS, SimulationSettings
from softcurve.simulation.sensitivity import choose_method
from softcurve.simulation.solvers import (
    DRIVER_FAMILIES,
    casadi_only,
    driver_integrate,
    driver_options,
    driver_problem,
    radau_constants,
    radau_tableau,
)
from softcurve.simulation.solvers import _driver as c_driver

from .conftest import random_state
from .test_identify import SEG
from .test_identify import oscillation as identify_oscillation
from .test_kinds import KINDS, robots
from .test_sensitivity_driver import bellows_trial as sensitivity_trial

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


# -- the method's constants -------------------------------------------------------------------
def test_the_tableau_meets_the_conditions_that_define_it():
    """Nodes, collocation (C(3)) and quadrature of order 5 (B(5)), the eigenvalues and the
    error weights Hairer and Wanner publish, and the dense output through the stages."""
    t = radau_tableau()
    root6 = np.sqrt(6.0)
    np.testing.assert_allclose(t.nodes, [(4 - root6) / 10, (4 + root6) / 10, 1.0], rtol=1e-14)
    for k in range(1, 4):  # C(3): the stages are collocation points of order 3
        np.testing.assert_allclose(t.matrix @ t.nodes ** (k - 1), t.nodes**k / k, atol=1e-15)
    for k in range(1, 6):  # B(5): the weights integrate polynomials of degree 4 exactly
        assert t.weights @ t.nodes ** (k - 1) == pytest.approx(1.0 / k, abs=1e-15)
    blocks = t.inverse_transform @ np.linalg.inv(t.matrix) @ t.transform
    expected = [[t.gamma, 0, 0], [0, t.alpha, -t.beta], [0, t.beta, t.alpha]]
    np.testing.assert_allclose(blocks, expected, atol=1e-13)
    assert t.gamma == pytest.approx(3 + 3 ** (2 / 3) - 3 ** (1 / 3), rel=1e-14)
    published = np.array([-13 - 7 * root6, -13 + 7 * root6, -1]) / 3
    np.testing.assert_allclose(t.error, published, rtol=1e-13)
    # the polynomial y + sum_k x^(k+1) sum_i P[k, i] Z_i passes through the stages Z_j
    powers = t.nodes[:, None] ** np.arange(1, 4)
    np.testing.assert_allclose(powers @ t.dense, np.eye(3), atol=1e-13)


def test_the_constants_lie_where_the_header_says():
    constants, at, t = radau_constants(), c_driver.DECLARATIONS.constants, radau_tableau()
    assert not constants.flags.writeable
    slots = {"C": t.nodes, "T": t.transform, "TI": t.inverse_transform, "GAMMA": t.gamma,
             "ALPHA": t.alpha, "BETA": t.beta, "E": t.error, "P": t.dense}  # fmt: skip
    expected = np.full(at["RADAU_CONSTANTS"], np.nan)
    for name, value in slots.items():
        flat = np.ravel(value)  # row-major, as the header says
        expected[at[f"RADAU_{name}"] : at[f"RADAU_{name}"] + flat.size] = flat
    np.testing.assert_array_equal(constants, expected)  # every slot filled, none twice


# -- order and stiffness on a problem with a known solution --------------------------------
def _prothero_robinson():
    """``y' = lam (y - s) + c`` with ``s' = c``, ``c' = -s`` (autonomous, as the driver
    integrates): from ``(0, 0, 1)``, ``y = s = sin t`` whatever ``lam`` (the parameter)."""
    x, tau, p = ca.SX.sym("x", 3), ca.SX.sym("tau", 1), ca.SX.sym("p", 1)
    f = ca.Function("radau_prothero_robinson", [x, tau, p],
                    [ca.vertcat(p[0] * (x[0] - x[1]) + x[2], x[2], -x[1])])  # fmt: skip
    generator = ca.CodeGenerator("f.c", {"with_header": False})
    generator.add(f)
    built = compile_source("test_radau", generator.dump(), symbols=(f.name(),))
    return c_driver.DriverProblem(NativeFunction(built, f.name()), 3, 1, 1)


def _final_error(problem, lam, rtol, y0=0.0, t_final=10.0):
    """The error of ``y(t_final)`` (exact: ``sin t + y0 exp(lam t)``) and the steps."""
    settings = driver_options(rtol, rtol, 10**6, radau=radau_constants())
    out, _, flags, counts, _ = driver_integrate(
        problem, [DRIVER_FAMILIES["radau"]], np.array([[y0, 0.0, 1.0]]), np.zeros((1, 1, 1)),
        np.array([[lam]]), np.ones((1, 3)), np.array([0.0, t_final]), ([1], [True]), settings,
    )  # fmt: skip
    assert flags[0] == 0
    exact = np.sin(t_final) + y0 * np.exp(lam * t_final)
    return abs(out[0, -1, 0] - exact), int(counts[0, 0])


def test_order_five_on_a_problem_with_a_known_solution():
    """Error against steps over tolerances 1e-3 .. 1e-10: slope -5 (order 5) with lam = -1
    and with lam = -1e6 (an explicit method would need 1e6 / 2.8 steps per second)."""
    problem = _prothero_robinson()
    rtols = 10.0 ** -np.arange(3, 11)
    for lam in (-1.0, -1e6):
        errors, steps = np.array([_final_error(problem, lam, rtol) for rtol in rtols]).T
        slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
        assert -5.6 < slope < -4.6, f"lam {lam}: error ~ steps^{slope:.2f}"
        assert np.all(np.diff(errors) < 0)
        assert steps[-1] < 1000


def test_a_stiff_transient_is_damped_at_once():
    """L-stability: started off the slow solution (``y0 = 1``, a transient ``exp(-1e6 t)``),
    the steps that resolve the transient leave nothing of it (the stability function
    vanishes at infinity; the trapezoidal rule would carry it on as (-1)^n), and the run
    ends with the error of a start on the slow solution, in a few hundred steps where an
    explicit method would need millions."""
    problem = _prothero_robinson()
    for rtol in (1e-4, 1e-8):
        on, _ = _final_error(problem, -1e6, rtol)
        off, off_steps = _final_error(problem, -1e6, rtol, y0=1.0)
        assert off <= 2.0 * on + 1e-14, (rtol, off, on)
        assert off_steps < 500, (rtol, off_steps)


def test_the_order_observed_on_the_paper_case(paper_model):
    """The paper's case, 0.5 s: error at the outputs against steps over tolerances 1e-3 ..
    1e-7, against CVODES at 1e-13. The outputs between steps come from the collocation
    polynomial (degree 3, local error h^4), so the order seen there lies between 4 and
    the steps' 5."""
    start = ([0.064, 25.0, 0.0], [0.0, 0.0, 1500.0])
    reference = sc.simulate(paper_model, *start, t_final=0.5, dt=0.01, rtol=1e-13)
    scale = np.abs(reference.q).max(axis=0)
    rows = []
    for rtol in 10.0 ** -np.arange(3, 8):
        run = sc.simulate(paper_model, *start, t_final=0.5, dt=0.01, rtol=rtol, method="radau")
        rows.append((np.max(np.abs(run.q - reference.q) / scale), run.stats["steps"]))
    errors, steps = np.array(rows).T
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert -5.5 < slope < -3.6, f"error ~ steps^{slope:.2f}"
    assert np.all(errors < 10.0 ** -np.arange(3, 8))  # within the tolerance asked


# -- against CVODES, on every kind, actuator and scenario ---------------------------------
def _close(a, b, scale, what):
    gap = np.abs(a - b).max(axis=0) / scale
    assert gap.max() < 1e-6, f"{what}: {gap.max():.2e}"


@pytest.mark.parametrize("kind", KINDS)
def test_radau_follows_cvodes_on_every_kind(rng, kind):
    model = sc.Model(robots()[kind])
    q0, qd0 = random_state(rng, model)
    runs = {}
    for method in ("cvodes", "radau"):
        runs[method] = sc.simulate(model, q0, qd0, t_final=0.2, dt=0.01, rtol=1e-9,
                                   method=method)  # fmt: skip
        assert runs[method].success, runs[method].message
    radau = runs["radau"]
    assert radau.stats["route"] == "driver-radau" and radau.stats["method"] == "radau"
    assert "radau" in radau.message
    scale = np.abs(runs["cvodes"].q).max(axis=0) + 1e-3
    _close(radau.q, runs["cvodes"].q, scale, kind)


@pytest.mark.parametrize("time_constant", [None, 0.02])
def test_radau_follows_cvodes_with_tendons(time_constant):
    robot = sc.presets.ifac2020().with_segments(2)
    tendons = sc.TendonActuator.three_per_segment(
        distance=0.01, t_max=5.0, time_constant=time_constant, elements=robot
    )
    model = sc.Model(robot)
    inputs = np.zeros((31, tendons.n_inputs))
    inputs[:, 0], inputs[15:, 4] = 3.0, 2.0  # a jump halfway: a new segment of the input
    runs = {}
    for method in ("cvodes", "radau"):
        runs[method] = sc.simulate(
            model, robot.rest_configuration(), np.zeros(model.n), actuator=tendons,
            inputs=inputs, t_final=0.3, dt=0.01, rtol=1e-9, method=method,
        )  # fmt: skip
        assert runs[method].success, runs[method].message
    scale = np.abs(runs["cvodes"].q).max(axis=0) + 1e-3
    _close(runs["radau"].q, runs["cvodes"].q, scale, f"tendons, lag {time_constant}")


SCENARIOS = sorted(p.name for p in EXAMPLES.glob("*.toml") if not p.name.startswith("sweep"))


@pytest.mark.parametrize("name", SCENARIOS)
def test_radau_follows_cvodes_on_every_scenario_file(name):
    scenario = sc.load_config(EXAMPLES / name)
    model = sc.Model(scenario.robot, environment=scenario.environment)
    q0, qd0, lam0 = scenario.initial_state()
    t_final = min(0.3, scenario.settings.t_final)
    runs = {}
    for method in ("cvodes", "radau"):
        dt = min(scenario.settings.dt, t_final / 10)
        settings = scenario.settings.replace(method=method, rtol=1e-8, t_final=t_final, dt=dt)
        runs[method] = sc.simulate(
            model, q0, qd0, lam0, tau=None if scenario.tau is None else scenario.tau,
            actuator=scenario.actuator() if scenario.inputs is not None else None,
            inputs=scenario.inputs, settings=settings,
        )  # fmt: skip
        assert runs[method].success, runs[method].message
    scale = np.abs(runs["cvodes"].q).max(axis=0) + 1e-3
    _close(runs["radau"].q, runs["cvodes"].q, scale, name)


# -- energy -----------------------------------------------------------------------------------
@pytest.mark.parametrize("damping", [False, True])
def test_the_scheme_never_creates_energy(damping):
    """Without damping the energy stays within the tolerance of the start (Radau IIA's
    damping of the fastest modes only takes energy away); with damping it never rises
    from one output to the next beyond the tolerance."""
    robot = sc.presets.ifac2020(damping=damping)
    segment = robot.segments[0]
    creep = sc.Creep(segment.creep.rate, segment.creep.gain, np.zeros(3))  # creep inert
    model = sc.Model(robot.replace(segments=(segment.replace(creep=creep),)))
    run = sc.simulate(model, [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0], t_final=1.0, dt=0.01,
                      rtol=1e-8, method="radau")  # fmt: skip
    assert run.success, run.message
    energy = np.array([model.energy(q, qd) for q, qd in zip(run.q, run.qd, strict=True)])
    slack = 1e-6 * abs(energy[0])
    if damping:
        assert np.all(np.diff(energy) <= slack) and energy[-1] < 0.5 * energy[0]
    else:
        assert np.all(energy <= energy[0] + slack)
        assert energy.min() > energy[0] - 1e-4 * abs(energy[0])


# -- batches, routes, restarts, failures ------------------------------------------------------
def test_a_batch_runs_each_member_as_simulate_does(paper_model):
    q0 = [[0.064, 5.0, 0.0], [0.064, -8.0, 3.0]]
    batch = sc.simulate_batch(paper_model, q0, [0.0, 0.0, 0.0], t_final=0.5, dt=0.01,
                              method="radau", threads=2)  # fmt: skip
    assert batch.success and batch.stats["route"] == "driver-radau"
    assert batch.stats["methods"] == ["radau", "radau"]
    for b, q in enumerate(q0):
        alone = sc.simulate(paper_model, q, [0.0, 0.0, 0.0], t_final=0.5, dt=0.01,
                            method="radau")  # fmt: skip
        np.testing.assert_array_equal(batch.q[b], alone.q)


def test_the_steps_go_on_through_segments_of_the_same_input(paper_model):
    """Segments whose input is the last one's neither stop nor restart the steps: the
    driver's outputs and work are those of one segment, bit for bit. A new input stops
    them where it starts, and a constant input given per output is the constant input."""
    problem = driver_problem(paper_model)
    settings = driver_options(1e-6, 1e-6, 10**4, radau=radau_constants())
    times = np.linspace(0.0, 1.0, 101)
    x0 = np.array([[0.064, 25.0, 0.0, 0.0, 0.0, 1500.0, 0.0, 0.0, 0.0]])

    def run(ends, forces):
        u = np.array(forces, dtype=float)[None]
        return driver_integrate(problem, [DRIVER_FAMILIES["radau"]], x0, u,
                                paper_model.parameters[None], np.ones((1, 9)), times,
                                (ends, [True] * len(ends)), settings)  # fmt: skip

    whole = run([100], [[0.0, 1e-3, 0.0]])
    split = run([20, 50, 100], [[0.0, 1e-3, 0.0]] * 3)
    np.testing.assert_array_equal(split[0], whole[0])
    np.testing.assert_array_equal(split[3].sum(axis=0), whole[3].sum(axis=0))
    changed = run([50, 100], [[0.0, 1e-3, 0.0], [0.0, -1e-3, 0.0]])
    assert changed[2][0] == 0 and not np.array_equal(changed[0][0, 51:], whole[0][0, 51:])
    np.testing.assert_array_equal(changed[0][0, :50], whole[0][0, :50])  # before the change
    start = ([0.064, 25.0, 0.0], [0.0, 0.0, 1500.0])
    tau = np.tile([0.0, 1e-3, 0.0], (201, 1))
    constant = sc.simulate(paper_model, *start, tau=tau[0], t_final=2.0, dt=0.01, method="radau")
    per_output = sc.simulate(paper_model, *start, tau=tau, t_final=2.0, dt=0.01, method="radau")
    np.testing.assert_array_equal(constant.q, per_output.q)


def test_the_progress_bar_keeps_the_route_and_the_trajectory_to_the_tolerance(paper_model, capsys):
    """With a bar the driver runs a call per restart segment, each a fresh start of Radau
    IIA: the same route, the same trajectory to the tolerance."""
    start = ([0.064, 25.0, 0.0], [0.0, 0.0, 1500.0])
    quiet = sc.simulate(paper_model, *start, t_final=3.5, dt=0.01, method="radau", rtol=1e-8)
    shown = sc.simulate(paper_model, *start, t_final=3.5, dt=0.01, method="radau", rtol=1e-8,
                        progress=True)  # fmt: skip
    capsys.readouterr()
    assert shown.stats["route"] == quiet.stats["route"] == "driver-radau"
    _close(shown.q, quiet.q, np.abs(quiet.q).max(axis=0), "with and without the bar")


def test_without_the_driver_radau_is_scipys(paper_model):
    start = ([0.064, 25.0, 0.0], [0.0, 0.0, 1500.0])
    with casadi_only():
        scipy = sc.simulate(paper_model, *start, t_final=0.2, dt=0.01, method="radau")
    ours = sc.simulate(paper_model, *start, t_final=0.2, dt=0.01, method="radau")
    assert scipy.success and scipy.stats["route"] == "scipy-radau"
    assert scipy.stats["method"] == "radau-scipy"
    _close(scipy.q, ours.q, np.abs(ours.q).max(axis=0), "SciPy's Radau")


def test_a_batch_without_the_driver_takes_bdf_and_says_so(paper_model):
    with casadi_only():
        batch = sc.simulate_batch(paper_model, [[0.064, 5.0, 0.0]], [0.0, 0.0, 0.0],
                                  t_final=0.2, dt=0.01, method="radau")  # fmt: skip
    assert batch.success and batch.stats["route"] == "casadi-cvodes"
    assert batch.stats["methods"] == ["cvodes-bdf"]
    assert "casadi_only" in batch.stats["route_reason"]


def test_failures_say_which_method_and_why(paper_model):
    start = ([0.064, 25.0, 0.0], [0.0, 0.0, 1500.0])
    run = sc.simulate(paper_model, *start, t_final=0.2, dt=0.01, method="radau", max_steps=2)
    assert run.status is Status.INTEGRATION_FAILED
    assert "Radau IIA CV_TOO_MUCH_WORK" in run.message and "max_steps" in run.message
    assert "method='bdf'" not in run.message  # already a stiff method
    crushed = sc.simulate(paper_model, [0.0644, 0.0, 0.0], [0.0, 0.0, 0.0],
                          tau=[-150.0, 0.0, 0.0], t_final=0.2, dt=0.01, method="radau")  # fmt: skip
    assert crushed.status is Status.LEFT_DOMAIN, crushed.message
    assert "l of segment 1" in crushed.message
    assert np.all(crushed.q[:, 0] > 0)  # no output outside the domain is kept


@pytest.mark.parametrize(
    ("every", "chosen"), [(None, "cvodes-adams"), (0.01, "radau"), (0.1, "cvodes-adams")]
)
def test_auto_takes_radau_where_the_input_changes_often(paper_model, every, chosen):
    """The slow moment of ``benchmarks/bench_radau.py --case slow``, held for ``every``
    seconds (None: a constant moment): Radau IIA where it changes within AUTO_INTERVAL
    over the fastest rate (283 1/s: 35 ms), else CVODES's choice; the result says why."""
    q0 = sc.equilibrium(paper_model, paper_model.robot.rest_configuration()).q
    if every is None:
        tau = np.array([0.0, 1e-3, 0.0])
    else:  # the moment sampled every `every` s, on the grid of 10 ms
        held = np.floor(np.arange(101) * 0.01 / every + 1e-9) * every
        tau = np.outer(0.5 * (1.0 - np.cos(2.0 * np.pi * held / 10.0)), [0.0, 2e-3, 0.0])
    run = sc.simulate(paper_model, q0, np.zeros(3), tau=tau, t_final=1.0, dt=0.01,
                      method="auto")  # fmt: skip
    assert run.success and run.stats["method"] == chosen, run.stats
    reason = run.stats["method_reason"]
    assert reason.startswith("auto: ") and ("within" in reason) == (chosen == "radau")
    if every is None:
        assert "fewer than half" in reason
    batch = sc.simulate_batch(paper_model, [q0], np.zeros(3), tau=np.atleast_2d(tau)[0],
                              t_final=0.1, method="auto")  # fmt: skip
    assert batch.stats["methods"] == ["cvodes-adams"]
    assert "fewer than half" in batch.stats["method_reason"]


# -- sensitivities of the discrete scheme --------------------------------------------------
@pytest.fixture(scope="module")
def fit_model():
    return sc.Model(sc.presets.ifac2020(), quadrature_nodes=4)


@pytest.mark.parametrize("hold", ["linear", "constant"])
def test_the_sensitivities_through_radau_are_cvodes_tight_ones(fit_model, hold):
    """The identification's trial of ``tests/test_sensitivity_driver.py`` (bellows, four
    free parameters): outputs and Jacobian by Radau IIA at the default rtol 1e-8 against
    CVODES at rtol 1e-12 with its columns in the error test (measured: outputs 7e-10 and
    3e-11, columns 5e-9 and 2e-11 of each column's largest entry)."""
    tight = {"reltol": 1e-12, "abstol": 1e-14, "max_num_steps": 10**6, "fsens_err_con": True}
    reference, theta = sensitivity_trial(fit_model, hold, options=tight)
    y_ref, jacobian_ref = reference(theta)
    evaluate, theta = sensitivity_trial(fit_model, hold, options={"method": "radau"})
    y, jacobian = evaluate(theta)
    assert evaluate.stats["method"] == "radau" and reference.stats["method"] == "adams"
    assert evaluate.stats["sensitivity_evaluations"] > 3 * evaluate.stats["steps"]
    assert np.abs(y - y_ref).max() <= 1e-7 * np.abs(y_ref).max()
    for j in range(jacobian.shape[1]):
        scale = np.abs(jacobian_ref[:, j]).max()
        assert np.abs(jacobian[:, j] - jacobian_ref[:, j]).max() <= 1e-6 * scale, j
    np.testing.assert_array_equal(evaluate.outputs(theta), y)  # the state's own steps


def test_the_sensitivities_through_radau_are_the_differences_of_its_outputs(fit_model):
    """Central differences of Radau IIA's outputs (rtol 1e-11, its steps re-chosen at each
    point) against its columns, each parameter stepped by 1e-6 of its value (1e-6 rad for
    the angle at zero), within 1e-5 of each column's largest entry (measured: up to 1.2e-6,
    the damping's; the stiffness's differences are off by 3e-9 there, 3e-7 at 1e-5 and
    3e-5 at 1e-4, of order two)."""
    evaluate, theta = sensitivity_trial(fit_model, "linear", options={"method": "radau"})
    _, jacobian = evaluate(theta)
    for j in range(theta.size):
        step = 1e-6 * (abs(theta[j]) or 1.0)
        plus, minus = theta.copy(), theta.copy()
        plus[j] += step
        minus[j] -= step
        moved = [evaluate.outputs(x, (1e-11, 1e-13)) for x in (plus, minus)]
        difference = (moved[0] - moved[1]).ravel("F") / (2 * step)  # vec: column-major
        scale = np.abs(difference).max()
        assert np.abs(jacobian[:, j] - difference).max() <= 1e-5 * scale, j


oscillation = identify_oscillation  # tests/test_identify.py's fixture, here too


def test_a_trajectory_fit_through_radau_recovers_the_robot(oscillation):
    """``tests/test_identify.py``'s noise-free oscillation fit, through Radau IIA."""
    model, x0, data = oscillation
    free = [
        sc.Free(SEG + "bending_stiffness.k0", 1e-4, 1.0, initial=0.012),
        sc.Free(SEG + "damping[1,1]", 1e-9, 1e-4, initial=1e-6),
    ]
    report = sc.fit_trajectory(model, data, output=bending_angle_map(), x0=x0, free=free,
                               integrator_options={"method": "radau"})  # fmt: skip
    assert report.success, report.message
    assert report.extra["method"] == {data.name: "radau"}
    assert report.extra["method_reason"] == {data.name: "integrator_options['method'] = 'radau'"}
    np.testing.assert_allclose(report.values, [0.008, 4e-7], rtol=1e-5)


@pytest.mark.parametrize(
    ("options", "hold", "rate", "expected", "why"),
    [
        ({}, "constant", 1000.0, "radau", "every 0.001 s on average, within 0.35 / fastest"),
        ({}, "constant", 100.0, "adams", "every 0.01 s on average, beyond 0.35 / fastest"),
        ({}, "linear", 1000.0, "adams", "joined linearly"),
        ({"max_order": 3}, "constant", 1000.0, "adams", "only CasADi's CVODES takes"),
        ({"fsens_err_con": True}, "constant", 1000.0, "adams", "fsens_err_con"),
    ],
)
def test_auto_chooses_the_method_of_a_fit_by_its_inputs(options, hold, rate, expected, why):
    t = np.arange(0.0, 0.1 + 1e-9, 1 / rate)
    samples = 1e4 + 1e3 * np.sin(7.0 * t)[None, :]
    asked = []

    def fastest():
        asked.append(True)
        return 282.0

    method, reason = choose_method(options, hold, t, samples, fastest)
    assert (method, reason.startswith("auto: ")) == (expected, True)
    assert why in reason
    assert asked == ([True] if why.startswith("every") else [])  # the rate only where needed


def test_auto_is_the_default_of_a_fits_sensitivities_and_says_why(fit_model):
    """Held pressures sampled at 1 kHz take Radau IIA; the default 12 Hz trial Adams;
    each says why, and both agree with an explicit choice of the same method."""
    t = np.arange(0.0, 0.3 + 1e-9, 1e-3)
    pressures = {f"p{i}": 1.5e4 + 2e3 * np.sin((5.0 + i) * t) for i in range(3)}
    fast = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, pressures)
    for experiment, expected in ((fast, "radau"), (None, "adams")):
        evaluate, theta = sensitivity_trial(fit_model, "constant", experiment=experiment)
        assert evaluate.method == expected
        assert evaluate.method_reason.startswith("auto: the input changes every")
        y, jacobian = evaluate(theta)
        assert evaluate.stats["method"] == expected
        chosen, _ = sensitivity_trial(
            fit_model, "constant", options={"method": expected}, experiment=experiment
        )
        assert chosen.method_reason == f"integrator_options['method'] = '{expected}'"
        y_chosen, jacobian_chosen = chosen(theta)
        np.testing.assert_array_equal(y, y_chosen)
        np.testing.assert_array_equal(jacobian, jacobian_chosen)


def test_a_method_of_the_sensitivities_outside_the_list_is_refused(fit_model):
    with pytest.raises(sc.ParameterError, match="method.*adams, bdf, radau.*'rk45'"):
        sensitivity_trial(fit_model, "linear", options={"method": "rk45"})
    with pytest.raises(sc.ParameterError, match="'radau' runs in softcurve's driver.*max_order"):
        sensitivity_trial(fit_model, "linear", options={"method": "radau", "max_order": 3})
    with pytest.raises(sc.ParameterError, match="'radau' takes no fsens_err_con"):
        sensitivity_trial(fit_model, "linear", options={"method": "radau", "fsens_err_con": True})


@pytest.mark.parametrize("hold", ["linear", "constant"])
def test_the_columns_survive_where_the_kept_jacobian_fails_them(fit_model, hold):
    """Strong random pressures at rtol 1e-3: the state's iteration converges on its kept
    Jacobian where the columns' diverges (measured: a contraction of 1.12), which then
    takes a fresh one at the step's start; every run succeeds, and matches CVODES's within
    what the loose tolerance allows."""
    t = np.arange(0.0, 10.0 + 1e-9, 1 / 12)
    for seed in range(3):
        rng = np.random.default_rng(seed)
        pressures = {f"p{i}": 4e4 * rng.random(t.size) for i in range(3)}
        experiment = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, pressures)
        options = {"method": "radau", "reltol": 1e-3, "abstol": 1e-5}
        evaluate, theta = sensitivity_trial(fit_model, hold, options=options, experiment=experiment)
        y, jacobian = evaluate(theta)
        assert np.all(np.isfinite(jacobian)) and evaluate.stats["steps"] > 0
        reference, _ = sensitivity_trial(fit_model, hold, experiment=experiment)
        y_ref, _ = reference(theta)
        assert np.abs(y - y_ref).max() <= 0.05 * np.abs(y_ref).max(), seed


def test_the_settings_and_the_command_line_take_radau(tmp_path, capsys):
    assert SimulationSettings(method="radau").method == "radau"
    with pytest.raises(SystemExit) as refused:  # argparse's usage error, before any work
        main(["simulate", "--method", "radau5"])
    assert refused.value.code == 2
    code = main(["simulate", "--method", "radau", "--t-final", "0.1", "--quiet",
                 "--out", str(tmp_path)])  # fmt: skip
    assert code == 0
    # the command line writes the choices out (it imports no layer to read them from)
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "{" + ",".join(METHODS) + "}" in text and "{" + ",".join(JACOBIANS) + "}" in text
