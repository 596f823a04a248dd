"""Gradients of rollouts (``sc.gradient``): against central differences, adjoint against
forward sensitivities, against the fits' sensitivities, the trajectory against
``simulate``, and a trajectory that leaves the domain gives no gradient."""

from __future__ import annotations

import subprocess
import sys

import casadi as ca
import matplotlib.pyplot
import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.identification.experiments._loading import Experiment
from softcurve.identification.fits._parameters import Free, FreeParameters
from softcurve.identification.maps import bellows_input_map, curvature_map
from softcurve.simulation.sensitivity import trajectory_sensitivities

from .test_kinds import gripper, six_strain_segment

NODES = 3  # quadrature nodes: a smaller expression, the same physics to check
Q0 = np.array([0.064, 5.0, -2.0])
QD0 = np.array([0.0, 40.0, 0.0])
T = np.linspace(0.0, 0.15, 7)
A1 = "segments[0].bending_stiffness.a1"
DAMPING = "segments[0].damping[1,1]"


@pytest.fixture(scope="module")
def model():
    return sc.Model(sc.presets.ifac2020(), quadrature_nodes=NODES)


@pytest.fixture(scope="module")
def bellows():
    return sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)


def pressures(t):
    """Held pressures [Pa] that change at every sample, seeded."""
    rng = np.random.default_rng(47)
    return 1e4 + 2e4 * rng.random((t.size, 3))


def cost(trajectory):
    """The tip's height at the end [m], the bends along the way and the running
    integral: every part of a trajectory a cost can read."""
    bends = ca.sumsqr(trajectory.q[1:3, :]) / trajectory.t.size
    return trajectory.tip[2, -1] + 1e-4 * bends + 1e-6 * trajectory.integral[0, -1]


def running(x, u, p):
    """The squared bending rates [1/(m s)]^2."""
    return ca.sumsqr(x[4:6])


@pytest.fixture(scope="module")
def reference(model, bellows):
    """CVODES's adjoint at its tight tolerances: the reference of the discrete one."""
    return sc.gradient(model, cost, Q0, QD0, t=T, inputs=pressures(T), actuator=bellows,
                       running=running, method="adjoint")  # fmt: skip


@pytest.fixture(scope="module")
def discrete(model, bellows):
    """The same by the default route, the discrete adjoint of the driver's Radau IIA."""
    return sc.gradient(
        model, cost, Q0, QD0, t=T, inputs=pressures(T), actuator=bellows, running=running
    )


def value(model, bellows, q0=Q0, inputs=None, parameters=None, method="adjoint"):
    """The cost alone at a perturbed start, inputs or parameters."""
    inputs = pressures(T) if inputs is None else inputs
    return sc.gradient(
        model, cost, q0, QD0, t=T, inputs=inputs, actuator=bellows, running=running, wrt="x0",
        parameters=parameters, method=method,
    ).value  # fmt: skip


def test_the_gradient_is_the_central_differences_one(model, bellows, reference):
    assert reference.success, reference.message
    assert reference.method == "adjoint" and reference.inputs.shape == (T.size, 3)
    for i, step in ((0, 1e-5), (1, 1e-3), (2, 1e-3)):
        shift = np.eye(3)[i] * step
        difference = (value(model, bellows, Q0 + shift) - value(model, bellows, Q0 - shift)) / (
            2 * step
        )
        np.testing.assert_allclose(reference.x0[i], difference, rtol=1e-5, atol=1e-9)
    u = pressures(T)
    for k, i in ((0, 0), (3, 1), (5, 2)):
        shift = np.zeros_like(u)
        shift[k, i] = 10.0  # Pa
        difference = (value(model, bellows, inputs=u + shift)
                      - value(model, bellows, inputs=u - shift)) / 20.0  # fmt: skip
        np.testing.assert_allclose(reference.inputs[k, i], difference, rtol=1e-4, atol=1e-12)
    assert np.all(reference.inputs[-1] == 0.0)  # the last sample acts on nothing
    names = list(reference.names)
    for name in (A1, DAMPING):
        j = names.index(name)
        p = model.parameters.copy()
        step = 1e-4 * abs(p[j])
        p[j] += step
        up = value(model, bellows, parameters=p)
        p[j] -= 2 * step
        difference = (up - value(model, bellows, parameters=p)) / (2 * step)
        np.testing.assert_allclose(reference.by_name[name], difference, rtol=1e-4)


def test_the_discrete_adjoint_is_cvodes_adjoint(discrete, reference):
    """Radau IIA's discrete adjoint at simulate's tolerance against CVODES's continuous
    adjoint at 1e-10: every entry above a millionth of the largest within 1e-4 (measured
    1.1e-5 along x0, 1.6e-5 along the inputs, 3.4e-6 along the parameters)."""
    assert discrete.success and discrete.method == "radau-adjoint", discrete.message
    assert "Radau IIA" in discrete.reason
    assert discrete.value == pytest.approx(reference.value, rel=1e-7)
    for along in ("x0", "inputs", "parameters"):
        ours, theirs = getattr(discrete, along), getattr(reference, along)
        largest = np.max(np.abs(theirs))
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=2e-5 * largest)
        np.testing.assert_allclose(ours, theirs, rtol=1e-4, atol=1e-6 * largest)
    assert np.all(discrete.inputs[-1] == 0.0)
    # a budget on the counts (measured 6.5 evaluations and 3.2 iterations a step): a
    # slower contraction of the transposed iteration shows here
    stats = discrete.stats
    assert stats["steps"] > 0 and stats["vjp_evaluations"] <= 9 * stats["steps"]
    assert stats["iterations"] <= 4 * stats["steps"] and dict(reference.stats) == {}


@pytest.fixture(scope="module")
def continuous(model, bellows):
    """The same by the continuous adjoint on the driver's CVODES, at 1e-9."""
    return sc.gradient(model, cost, Q0, QD0, t=T, inputs=pressures(T), actuator=bellows,
                       running=running, method="adams-adjoint", rtol=1e-9)  # fmt: skip


def test_the_continuous_adjoint_is_cvodes_adjoint(model, bellows, continuous, reference):
    """The driver's continuous adjoint against CVODES's adjoint through CasADi at 1e-10,
    on pressures that change at every sample (a start at each) and a cost reading every
    output time. It converges with its tolerance (the largest difference over the largest
    entry along x0 from CVODES's at 1e-12, measured: 2.6e-5 at its default 1e-7, 6.2e-7
    at 1e-8, 2.8e-7 at 1e-9; Radau IIA's adjoint at its default 2.4e-6): against the
    reference at 1e-10, every entry within 1e-5 of the largest at 1e-9 and 1e-4 at the
    default (where ``auto`` takes Radau IIA's adjoint: starts every 25 ms)."""
    assert continuous.success and continuous.method == "adams-adjoint", continuous.message
    assert continuous.reason == "asked"
    assert continuous.value == pytest.approx(reference.value, rel=1e-7)
    np.testing.assert_allclose(continuous.x, reference.x, rtol=1e-6, atol=1e-9)
    default = sc.gradient(model, cost, Q0, QD0, t=T, inputs=pressures(T), actuator=bellows,
                          running=running, method="adams-adjoint")  # fmt: skip
    for along in ("x0", "inputs", "parameters"):
        theirs = getattr(reference, along)
        largest = np.max(np.abs(theirs))
        np.testing.assert_allclose(getattr(continuous, along), theirs, rtol=0,
                                   atol=1e-5 * largest)  # fmt: skip
        np.testing.assert_allclose(getattr(default, along), theirs, rtol=0, atol=1e-4 * largest)
    assert np.all(continuous.inputs[-1] == 0.0)
    # the counts: a start at every change of the pressures (each output time), one
    # reverse-mode evaluation per right-hand side of the adjoint equations (measured 1.1
    # to 1.4 a step), one pass (the adjoint does not decay below ADAMS_DECAYED here)
    stats = continuous.stats
    assert stats["backward_passes"] == 1 and stats["backward_starts"] == T.size - 1
    assert 0 < stats["backward_vjp_evaluations"] <= 2 * stats["backward_steps"]


def test_the_continuous_adjoint_gives_each_sample_its_own_derivative(model, bellows):
    """Constant pressures: the forward and backward passes go through the output times
    without a start, and each sample's derivative is its own interval's integral (CVODES's
    adjoint, which starts afresh at every sample, to 1e-4 of the largest); without the
    cost reading the states along the way the only start is the end's."""

    def tip_cost(trajectory):
        return trajectory.tip[2, -1] + 1e-6 * trajectory.integral[0, -1]

    held = np.full((T.size, 3), 2e4)
    options = {"t": T, "inputs": held, "actuator": bellows, "running": running}
    ours = sc.gradient(model, tip_cost, Q0, QD0, method="adams-adjoint", **options)
    theirs = sc.gradient(model, tip_cost, Q0, QD0, method="adjoint", **options)
    assert ours.success, ours.message
    assert ours.stats["backward_starts"] == 1 and ours.stats["steps"] > 0
    largest = np.max(np.abs(theirs.inputs))
    np.testing.assert_allclose(ours.inputs, theirs.inputs, rtol=0, atol=1e-4 * largest)
    assert np.all(np.abs(ours.inputs[:-1]).max(axis=1) > 1e-3 * largest)  # every row its own


def test_auto_takes_the_continuous_adjoint_where_it_starts_seldom(model):
    """The paper swing over 1 s: a cost of the tip at the end and an integral starts the
    continuous adjoint once (1 s apart, about 280 over the fastest rate, over
    ADAMS_WITHIN); one reading the state at 100 output times would start it every 10 ms,
    and takes Radau IIA's. The continuous adjoint lies within 1e-5 of the largest entry
    from CVODES's adjoint at 1e-10 (measured 1.3e-6 along x0, 1.6e-7 along the
    parameters; Radau IIA's 2.0e-6 and 3.5e-7)."""
    t, q0, qd0 = np.linspace(0.0, 1.0, 101), [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0]

    def at_end_cost(trajectory):
        return trajectory.tip[2, -1] + 1e-6 * trajectory.integral[0, -1]

    at_end = sc.gradient(model, at_end_cost, q0, qd0, t=t, running=running)
    assert at_end.method == "adams-adjoint", at_end.reason
    assert "starts afresh every 1 s" in at_end.reason and "ADAMS_WITHIN" in at_end.reason
    assert at_end.stats["backward_starts"] == 1
    everywhere = sc.gradient(model, lambda tr: ca.sumsqr(tr.tip[2, :]), q0, qd0, t=t, wrt="x0")
    assert everywhere.method == "radau-adjoint", everywhere.reason
    assert "every 0.01 s" in everywhere.reason
    reference = sc.gradient(model, at_end_cost, q0, qd0, t=t, running=running,
                            method="adjoint")  # fmt: skip
    for along in ("x0", "parameters"):
        theirs = getattr(reference, along)
        np.testing.assert_allclose(getattr(at_end, along), theirs, rtol=0,
                                   atol=1e-5 * np.max(np.abs(theirs)))  # fmt: skip


def _own_differences(g, model, value_at, steps_x0, names):
    """Assert ``g`` equals central differences of ``value_at(q0=..., parameters=...)``
    along the initial state and the named parameters (2e-5 relative)."""
    for i, step in steps_x0:
        shift = np.eye(3)[i] * step
        difference = (value_at(q0=Q0 + shift) - value_at(q0=Q0 - shift)) / (2 * step)
        assert g.x0[i] == pytest.approx(difference, rel=2e-5)
    for name in names:
        j = list(g.names).index(name)
        p, step = model.parameters.copy(), 1e-5 * abs(model.parameters[j])
        p[j] += step
        up = value_at(parameters=p)
        p[j] -= 2 * step
        difference = (up - value_at(parameters=p)) / (2 * step)
        assert g.by_name[name] == pytest.approx(difference, rel=2e-5)


def test_the_discrete_adjoint_is_the_gradient_of_its_own_numbers(model, bellows, discrete):
    """Central differences of the same route's values (its steps' sizes move with the
    start, inputs and parameters, and the derivative holds them): within 2e-5 at
    simulate's tolerance (measured 1e-8 to 5e-6); stopping at every output time (the
    pressures change at each), then passing through them (constant pressures, no
    gradient along them: the outputs from the collocation polynomial)."""

    def own(**change):
        return value(model, bellows, method="radau-adjoint", **change)

    _own_differences(discrete, model, own, ((0, 1e-6), (1, 1e-4), (2, 1e-4)), (A1, DAMPING))
    u = pressures(T)
    for k, i in ((0, 0), (3, 1), (5, 2)):
        shift = np.zeros_like(u)
        shift[k, i] = 1.0  # Pa
        difference = (own(inputs=u + shift) - own(inputs=u - shift)) / 2.0
        assert discrete.inputs[k, i] == pytest.approx(difference, rel=2e-5)
    held = np.full(3, 2e4)  # Pa
    options = {"inputs": held, "actuator": bellows, "running": running}
    through = sc.gradient(model, cost, Q0, QD0, t=T, wrt=("parameters", "x0"), **options)

    def through_value(q0=Q0, parameters=None):
        return sc.gradient(model, cost, q0, QD0, t=T, wrt="x0", parameters=parameters,
                           **options).value  # fmt: skip

    _own_differences(through, model, through_value, ((1, 1e-4),), (A1,))


def test_a_tape_beyond_memory_is_a_failed_set_up(model, monkeypatch):
    from softcurve.simulation.solvers import _adjoint

    monkeypatch.setattr(_adjoint, "FIRST_ROOM", (2**45, 0, 1))  # petabytes of steps
    g = sc.gradient(model, lambda tr: tr.tip[2, -1], Q0, t=T)
    assert g.status is Status.INTEGRATION_FAILED and "could not be set up" in g.message
    assert np.isnan(g.value) and g.stats == {}


def test_a_tape_that_fills_grows_and_gives_the_same_gradient(model, bellows, discrete, monkeypatch):
    """Room for one step and one Jacobian: the forward pass runs again on four times the
    room of what filled, steps and Jacobians in turn, to the same numbers."""
    from softcurve.simulation.solvers import _adjoint

    monkeypatch.setattr(_adjoint, "FIRST_ROOM", (1, 0, 1))
    again = sc.gradient(
        model, cost, Q0, QD0, t=T, inputs=pressures(T), actuator=bellows, running=running
    )
    assert again.success, again.message
    np.testing.assert_array_equal(again.x, discrete.x)
    np.testing.assert_array_equal(again.parameters, discrete.parameters)


def test_auto_counts_the_restarts_a_lag_and_a_start_it_cannot_linearize(model, bellows):
    """The choice's inputs: over 3 s a cost at the end starts the continuous adjoint every
    RESTART_INTERVAL (1 s, not 3); over 0.5 s (about 140 over the robot's fastest rate)
    the discrete adjoint, unless a lagging actuator's rate is faster (1 ms: 500 over);
    a start whose linearization is not finite takes the discrete adjoint and says so."""
    q0, qd0 = [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0]

    def tip(trajectory):
        return trajectory.tip[2, -1]

    long = sc.gradient(model, tip, q0, qd0, t=[0.0, 3.0], wrt="x0")
    assert long.method == "adams-adjoint" and "every 1 s" in long.reason, long.reason
    t, held = np.linspace(0.0, 0.5, 51), np.full(3, 2e4)
    alone = sc.gradient(model, tip, q0, t=t, inputs=held, actuator=bellows, wrt="x0")
    assert alone.method == "radau-adjoint", alone.reason
    assert "every 0.5 s" in alone.reason and "under ADAMS_WITHIN" in alone.reason
    fast = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5,
                                              time_constant=1e-3)  # fmt: skip
    lagging = sc.gradient(model, tip, q0, t=t, inputs=held, actuator=fast, wrt="x0")
    assert lagging.method == "adams-adjoint" and "500 over" in lagging.reason, lagging.reason
    p = model.parameters.copy()
    p[model.robot.parameter_names().index("gravity[2]")] = 1e305
    overflowing = sc.gradient(model, tip, q0, qd0, t=[0.0, 0.025], parameters=p)
    assert overflowing.method == "radau-adjoint"
    assert "linearization at the start is not finite" in overflowing.reason


def test_cvodes_starts_afresh_after_every_restart_interval(model):
    """Over 2.5 s backward, as ``simulate`` restarts (RESTART_INTERVAL): three starts a
    pass; the tip's height at the end has decayed along the initial state (below
    ADAMS_DECAYED of its seed), so the pass runs twice. The forward pass's starts are
    counted on its tape (the passes' test)."""
    g = sc.gradient(model, lambda tr: tr.tip[2, -1], [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0],
                    t=[0.0, 2.5], wrt="x0", method="adams-adjoint")  # fmt: skip
    assert g.success, g.message
    assert g.stats["backward_passes"] == 2 and g.stats["backward_starts"] == 6


@pytest.mark.parametrize(("t_end", "count"), [(2.0, 99), (2.5, 6)])
def test_output_times_at_a_restart_are_taken(model, t_end, count):
    """``linspace(0, 2, 99)`` holds 0.9999999999999999, one rounding unit before the
    backward pass's restart at 2 - 1 = 1 s: no start is put there (CVODES would refuse
    the interval, CV_TOO_CLOSE), it starts afresh at the output time; in ``linspace(0,
    2.5, 6)`` the restart at 1.5 s is an output time."""
    t = np.linspace(0.0, t_end, count)
    g = sc.gradient(model, lambda tr: tr.tip[2, -1], [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0],
                    t=t, method="adams-adjoint")  # fmt: skip
    assert g.success, g.message
    assert np.all(np.isfinite(g.parameters))


def test_a_decayed_adjoint_runs_again_on_its_own_scale(model):
    """The tip's height after 1 s alone: the adjoint at the start has decayed far below
    its seed (under ADAMS_DECAYED), so the backward pass runs again with the absolute
    tolerance scaled down; ``auto`` takes the continuous adjoint, which then lies within
    1e-4 of the largest entry from CVODES's adjoint at 1e-10 (measured 2.5e-5 along x0,
    2.5e-6 along the parameters; after one pass, 3.5e-2 and 4.6e-3)."""
    t, q0, qd0 = np.linspace(0.0, 1.0, 101), [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0]
    g = sc.gradient(model, lambda tr: tr.tip[2, -1], q0, qd0, t=t)
    assert g.method == "adams-adjoint" and g.stats["backward_passes"] == 2, g.reason
    reference = sc.gradient(model, lambda tr: tr.tip[2, -1], q0, qd0, t=t, method="adjoint")
    for along in ("x0", "parameters"):
        theirs = getattr(reference, along)
        np.testing.assert_allclose(getattr(g, along), theirs, rtol=0,
                                   atol=1e-4 * np.max(np.abs(theirs)))  # fmt: skip


def test_an_adams_tape_that_fills_grows_and_gives_the_same_gradient(model, bellows, continuous,
                                                                  monkeypatch):  # fmt: skip
    """Room for one point: the forward pass runs again on four times the room, to the
    same numbers."""
    from softcurve.simulation.solvers import _adjoint

    monkeypatch.setattr(_adjoint, "ADAMS_FIRST_ROOM", (1, 0))
    again = sc.gradient(model, cost, Q0, QD0, t=T, inputs=pressures(T), actuator=bellows,
                        running=running, method="adams-adjoint", rtol=1e-9)  # fmt: skip
    assert again.success, again.message
    np.testing.assert_array_equal(again.x, continuous.x)
    np.testing.assert_array_equal(again.parameters, continuous.parameters)


def test_the_adjoints_passes_refuse_what_they_cannot_take(model, bellows):
    """The driver's passes check their arrays before any C runs (C would read or write
    beyond them) and refuse a problem whose actuator acts beside f (the backward pass
    differentiates f alone) and a backward pass after a failed forward one."""
    from softcurve.compiled import compile_functions, load_function
    from softcurve.simulation.solvers import (
        ActuatorInput,
        DriverProblem,
        _driver,
        adams_backward,
        adams_forward,
        adjoint_backward,
        adjoint_forward,
        driver_problem,
        vjp_function,
    )

    tr = sc.Transcription(model)
    x, u, p = (ca.SX.sym(name, size) for name, size in
               (("x", tr.n_x), ("u", tr.n_u), ("p", tr.parameters.size)))  # fmt: skip
    rhs = ca.Function("f", [x, u, p], [tr.rhs_sx(x, u, p)])
    f, vjp = compile_functions([rhs, vjp_function(rhs)], load=load_function)
    problem = DriverProblem(f, tr.n_x, tr.n_u, tr.parameters.size)
    x0, u, nominal = tr.start(Q0, QD0), np.zeros((T.size, tr.n_u)), np.ones(tr.n_x)
    arguments = (tr.parameters, nominal, T, 1e-6, 1e-6, 100)
    with pytest.raises(ValueError, match=r"u must have shape \(7, 3\)"):
        adjoint_forward(problem, x0, u[:, :2], *arguments)
    with pytest.raises(ValueError, match="x0 must have shape"):
        adjoint_forward(problem, x0[:-1], u, *arguments)
    with pytest.raises(ValueError, match="increasing output times"):
        adjoint_forward(problem, x0, u, tr.parameters, nominal, T[::-1], 1e-6, 1e-6, 100)
    actuated = driver_problem(model, ActuatorInput.of(bellows, model.n))
    with pytest.raises(ValueError, match="no actuator's force or lag"):
        adjoint_forward(actuated, x0, u, *arguments)
    taped = adjoint_forward(problem, x0, u, *arguments)
    assert taped.flag == 0 and not taped.states.flags.writeable
    with pytest.raises(ValueError, match="seeds must have shape"):
        adjoint_backward(taped, vjp, np.zeros((T.size, 2)))
    with pytest.raises(ValueError, match="vjp must be"):
        adjoint_backward(taped, f, np.zeros_like(taped.states))
    failed = adjoint_forward(problem, x0, u, *arguments[:-1], 1)  # one step an interval
    assert failed.flag != 0
    with pytest.raises(ValueError, match="the forward pass failed"):
        adjoint_backward(failed, vjp, np.zeros_like(failed.states))
    # the continuous adjoint's passes: the same checks, and its method's own
    with pytest.raises(ValueError, match=r"u must have shape \(7, 3\)"):
        adams_forward(problem, x0, u[:, :2], *arguments)
    with pytest.raises(ValueError, match="no actuator's force or lag"):
        adams_forward(actuated, x0, u, *arguments)
    with pytest.raises(ValueError, match=r"max_order must be in \[1, 5\], got 12"):
        adams_forward(problem, x0, u, *arguments, family=2, max_order=12)
    with pytest.raises(ValueError, match="family must be 1"):
        adams_forward(problem, x0, u, *arguments, family=3)
    taped = adams_forward(problem, x0, u, *arguments)
    assert taped.flag == 0 and not taped.tape.flags.writeable
    with pytest.raises(ValueError, match="a tape of the 'adams' forward pass"):
        adjoint_backward(taped, vjp, np.zeros_like(taped.states))
    # a start at the first step's end after every RESTART_INTERVAL: order-0 points
    times = np.linspace(0.0, 2.5, 6)
    long = adams_forward(problem, x0, np.zeros((6, tr.n_u)), tr.parameters, nominal, times,
                         1e-6, 1e-6, 10_000, stops=[1, 0, 0, 0, 0, 1])  # fmt: skip
    column = _driver.DECLARATIONS.constants["ADAMS_ORDER"]
    assert long.flag == 0 and np.count_nonzero(long.tape[: long.steps, column] == 0) == 3
    with pytest.raises(ValueError, match="seeds must have shape"):
        adams_backward(taped, vjp, np.zeros((T.size, 2)))
    failed = adams_forward(problem, x0, u, *arguments[:-1], 1)
    assert failed.flag != 0
    with pytest.raises(ValueError, match="the forward pass failed"):
        adams_backward(failed, vjp, np.zeros_like(failed.states))


def test_without_the_driver_auto_takes_cvodes_and_radau_is_refused():
    plain = sc.Model(sc.presets.ifac2020(), quadrature_nodes=NODES, compile=False)
    g = sc.gradient(plain, lambda tr: tr.tip[2, -1], Q0, QD0, t=T[:3], wrt="x0")
    assert g.success and g.method == "adjoint" and "not compiled" in g.reason, g.reason
    with pytest.raises(sc.ParameterError, match="radau-adjoint.*not compiled"):
        sc.gradient(plain, lambda tr: tr.tip[2, -1], Q0, t=T[:3], method="radau-adjoint")


def test_forward_sensitivities_give_the_adjoint_gradient():
    """Along the initial state and generalized forces that change at every sample, on a
    model that is not compiled (the right-hand side and its derivatives in CasADi's
    virtual machine: the compiled second derivatives are checked by
    ``tests/test_planning.py``'s compiled collocation)."""
    small = sc.Model(sc.presets.ifac2020(), quadrature_nodes=2, compile=False)
    t = T[:3]
    forces = 0.002 * np.sin(np.outer(t, [30.0, 50.0, 70.0]))  # [N, N m^2, N m^2]
    options = dict(t=t, inputs=forces, running=running, wrt=("x0", "inputs"))
    adjoint = sc.gradient(small, cost, Q0, QD0, **options)
    forward = sc.gradient(small, cost, Q0, QD0, method="forward", **options)
    assert forward.method == "forward" and forward.parameters is None
    np.testing.assert_allclose(forward.x0, adjoint.x0, rtol=1e-6, atol=1e-10)
    np.testing.assert_allclose(forward.inputs, adjoint.inputs, rtol=1e-5, atol=1e-10)
    assert forward.value == pytest.approx(adjoint.value, rel=1e-12)


def test_the_trajectory_and_the_cost_are_those_simulate_integrates(model, bellows, reference):
    run = sc.simulate(
        model, Q0, QD0, actuator=bellows, inputs=pressures(T), t_final=T[-1], dt=T[1],
        rtol=1e-10,
    )  # fmt: skip
    assert run.success
    scale = np.array([Q0[0], 10.0, 10.0])  # [m, 1/m, 1/m]
    assert np.max(np.abs(run.q - reference.x[:, :3]) / scale) < 1e-7
    tip = model.tip_pose(run.q[-1]).position
    bends = np.sum(run.q[:, 1:] ** 2) / T.size
    # the running integral by the trapezoid on a fine grid of its own
    fine = sc.simulate(
        model, Q0, QD0, actuator=bellows,
        inputs=np.vstack([np.repeat(pressures(T)[:-1], 200, axis=0), pressures(T)[-1:]]),
        t_final=T[-1], dt=T[1] / 200, rtol=1e-10,
    )  # fmt: skip
    integral = np.trapezoid(np.sum(fine.qd[:, 1:] ** 2, axis=1), fine.t)
    expected = tip[2] + 1e-4 * bends + 1e-6 * integral
    assert reference.value == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize(("method", "rtol"), [("auto", None), ("adams-adjoint", 1e-9)])
def test_the_gradient_along_parameters_is_the_fits_one(model, method, rtol):
    """``0.5 |y - m|^2`` of the curvatures under held pressures: the fits' Jacobian
    ``J' r`` along two of their free parameters, by the default route (the discrete
    adjoint: the cost reads every output time) and by the continuous adjoint at rtol 1e-9
    (at its default 1e-7 its value lies 1.7e-7 from the fits', beyond the 1e-7 asked)."""
    t = np.linspace(0.0, 0.2, 11)
    u = pressures(t)
    experiment = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, {f"p{i}": u[:, i] for i in range(3)})
    inputs = bellows_input_map(area=2e-5, distance=0.01)
    free = [Free(A1), Free(DAMPING)]
    parameters = FreeParameters(model, free, inputs.parameters, {}, None)
    x0 = np.zeros(model.n_state)
    x0[:3] = Q0
    evaluate = trajectory_sensitivities(
        model, parameters, curvature_map(), inputs, x0, experiment, None, hold="constant"
    )
    y, jacobian = evaluate(parameters.theta0)
    measured = y + 0.1 * np.random.default_rng(3).standard_normal(y.shape)
    fits = jacobian.T @ (y - measured).T.ravel()  # rows of the Jacobian: time-major

    def squares(trajectory):
        return 0.5 * ca.sumsqr(trajectory.q[1:3, :] - ca.DM(measured))

    actuator = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    ours = sc.gradient(model, squares, Q0, t=t, inputs=u, actuator=actuator, wrt="parameters",
                       method=method, rtol=rtol)  # fmt: skip
    assert ours.method == ("radau-adjoint" if method == "auto" else method), ours.reason
    np.testing.assert_allclose(ours.value, 0.5 * np.sum((y - measured) ** 2), rtol=1e-7)
    np.testing.assert_allclose([ours.by_name[A1], ours.by_name[DAMPING]], fits, rtol=1e-5)


@pytest.mark.parametrize(("method", "rtol"), [("adjoint", None), ("radau-adjoint", 1e-10)])
def test_constant_inputs_take_one_integration_through_the_outputs(model, bellows, method, rtol):
    """Without a gradient along the inputs, held constant, one integration runs through
    every output time (CVODES), or the steps pass through them, the outputs from their
    collocation polynomials (Radau IIA): the same value and gradient as one integration
    per interval, to the tolerance."""
    u = np.full(3, 2e4)
    options = {"inputs": u, "actuator": bellows, "running": running, "method": method,
               "rtol": rtol}  # fmt: skip
    through = sc.gradient(model, cost, Q0, QD0, t=T, wrt=("parameters", "x0"), **options)
    held = sc.gradient(model, cost, Q0, QD0, t=T, **options)
    assert through.inputs is None and held.inputs.shape == (T.size, 3)
    assert through.value == pytest.approx(held.value, rel=1e-8)
    np.testing.assert_allclose(through.x0, held.x0, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(through.parameters, held.parameters, rtol=1e-5, atol=1e-9)


def test_the_integral_of_one_is_the_elapsed_time(model):
    g = sc.gradient(model, lambda tr: tr.integral[0, -1], Q0, t=T,
                    running=lambda x, u, p: ca.SX(1.0), wrt="x0")  # fmt: skip
    assert g.value == pytest.approx(T[-1] - T[0], rel=1e-12)
    np.testing.assert_allclose(g.x0, 0.0, atol=1e-12)


@pytest.mark.parametrize("method", ["auto", "adams-adjoint"])
def test_a_lagging_actuator_gradient_reaches_its_commands(model, method):
    """Along a command, central differences of the same route's values; the commands'
    lagging states are integrated (and taped) with the robot's."""
    lagging = sc.PneumaticActuator.three_bellows(
        distance=0.01, area=2e-5, p_max=1e5, time_constant=0.05
    )
    u = pressures(T)

    def height(inputs):
        return sc.gradient(model, lambda tr: tr.tip[2, -1], Q0, t=T, inputs=inputs,
                           actuator=lagging, wrt="inputs", method=method)  # fmt: skip

    g = height(u)
    assert g.x.shape == (T.size, model.n_state + 3)
    shift = np.zeros_like(u)
    shift[1, 0] = 10.0
    difference = (height(u + shift).value - height(u - shift).value) / 20.0
    np.testing.assert_allclose(g.inputs[1, 0], difference, rtol=1e-4)


def test_a_chain_of_other_kinds_has_the_central_differences_gradient():
    """A six-strain segment with creep carrying a rigid gripper (twist, shear, creep
    states and a fixed placement): the gradient along the initial state and two
    parameters, one of them the rigid body's mass."""
    robot = sc.Robot(segments=(six_strain_segment(creep=True), gripper()))
    chain = sc.Model(robot, compile=False, quadrature_nodes=2)
    q0 = robot.rest_configuration() + np.array([5.0, -3.0, 4.0, 0.05, -0.02, 0.1])
    t = np.linspace(0.0, 0.05, 6)

    def reach(trajectory):
        return trajectory.tip[0, -1] + trajectory.tip[2, -1]

    def at(q=q0, parameters=None):
        return sc.gradient(chain, reach, q, t=t, wrt="x0", parameters=parameters)

    g = sc.gradient(chain, reach, q0, t=t, wrt=("x0", "parameters"))
    assert g.success and g.x0.shape == (chain.n_state,)
    for i, step in ((0, 1e-3), (2, 1e-3), (4, 1e-5)):  # bend, twist, shear
        shift = np.eye(chain.n)[i] * step
        difference = (at(q0 + shift).value - at(q0 - shift).value) / (2 * step)
        np.testing.assert_allclose(g.x0[i], difference, rtol=1e-5, atol=1e-10)
    for name in ("segments[1].mass", "segments[0].stretch_stiffness.k0"):
        j = list(g.names).index(name)
        p = chain.parameters.copy()
        step = 1e-5 * abs(p[j])
        p[j] += step
        up = at(parameters=p).value
        p[j] -= 2 * step
        difference = (up - at(parameters=p).value) / (2 * step)
        np.testing.assert_allclose(g.by_name[name], difference, rtol=1e-4, atol=1e-10)


def test_the_drivers_adjoints_take_a_chain_of_other_kinds():
    """The same six-strain segment with creep and a rigid gripper, compiled: both of the
    driver's adjoints equal CVODES's adjoint at 1e-10, along the initial state and the
    parameters, within 1e-4 of the largest entry (measured: Radau IIA's 3.5e-6 and
    5.0e-7, the continuous adjoint's 3.3e-5 and 1.2e-5)."""
    robot = sc.Robot(segments=(six_strain_segment(creep=True), gripper()))
    chain = sc.Model(robot, quadrature_nodes=2)
    q0 = robot.rest_configuration() + np.array([5.0, -3.0, 4.0, 0.05, -0.02, 0.1])
    t = np.linspace(0.0, 0.05, 6)

    def reach(trajectory):
        return trajectory.tip[0, -1] + trajectory.tip[2, -1]

    wrt = ("x0", "parameters")
    reference = sc.gradient(chain, reach, q0, t=t, wrt=wrt, method="adjoint")
    for method in sc.control.GRADIENT_METHODS[:2]:
        g = sc.gradient(chain, reach, q0, t=t, wrt=wrt, method=method)
        assert g.success and g.method == method, g.message
        for along in wrt:
            theirs = getattr(reference, along)
            np.testing.assert_allclose(getattr(g, along), theirs, rtol=0,
                                       atol=1e-4 * np.max(np.abs(theirs)))  # fmt: skip


def test_a_trajectory_that_leaves_the_domain_gives_no_gradient(model):
    # 500 N along the length crushes the segment (simulate: LEFT_DOMAIN at 0.05 s)
    g = sc.gradient(model, lambda tr: tr.tip[2, -1], [0.064, 0.0, 0.0], inputs=[-500.0, 0, 0],
                    t=np.linspace(0.0, 0.2, 5))  # fmt: skip
    assert g.status is Status.LEFT_DOMAIN and not g.success, g.message
    assert "lengths l must be" in g.message
    assert np.isnan(g.parameters).all() and np.isnan(g.value)


@pytest.mark.parametrize(
    ("method", "q0", "qd0", "failing"),
    [
        ("adjoint", Q0, QD0, "CVode returned"),
        ("adjoint", [0.064, 0.0, 0.0], None, "CVodeB"),
        ("auto", Q0, QD0, "Radau IIA CV_ERR_FAILURE"),
        ("adams-adjoint", Q0, QD0, "CVODES CV_TOO_MUCH_WORK"),
    ],
)
def test_a_failing_integration_is_integration_failed_with_no_gradient(
    model, method, q0, qd0, failing
):
    """Gravity at 1e305 m/s^2 overflows the integration: CVODES's (moving) or, from rest,
    its adjoint; Radau IIA's forward pass. The result says so, without a gradient, and
    raises nothing."""
    p = model.parameters.copy()
    p[model.robot.parameter_names().index("gravity[2]")] = 1e305
    g = sc.gradient(model, lambda tr: tr.tip[2, -1], q0, qd0, t=[0.0, 0.025], parameters=p,
                    method=method)  # fmt: skip
    assert g.status is Status.INTEGRATION_FAILED, g.message
    assert {"adjoint": "CVODES failed", "auto": "Radau IIA"}.get(method, "CVODES") in g.message
    assert failing in g.message, g.message
    assert np.isnan(g.parameters).all() and np.isnan(g.value)
    assert g.x.shape == (2, model.n_state)


@pytest.mark.parametrize(
    ("running_", "cost_", "failing"),
    [
        # not finite in reverse mode alone: sqrt at 0 times a zero derivative
        (lambda x, u, p: ca.sqrt(ca.fmax(-x[0], 0.0)), lambda tr: tr.integral[0, -1],
         "Radau IIA's adjoint stopped: a step's multipliers did not converge"),
        (None, lambda tr: ca.sqrt(ca.fmin(tr.x[0, -1], 0.0)),
         "the cost's derivative along the state at t = 0.15 s is not finite"),
        # not finite along the parameters alone: the multipliers converge
        (lambda x, u, p: ca.sqrt(ca.fmax(-p[0], 0.0)), lambda tr: tr.integral[0, -1],
         "is not finite along the inputs or the parameters"),
        # the cost's own derivative along a parameter
        (None, lambda tr: tr.tip[2, -1] + ca.sqrt(ca.fmax(-tr.p[0], 0.0)),
         "the gradient is not finite along parameters"),
    ],
)  # fmt: skip
def test_a_derivative_that_is_not_finite_gives_no_gradient(model, running_, cost_, failing):
    g = sc.gradient(model, cost_, Q0, QD0, t=T, running=running_)
    assert g.status is Status.INTEGRATION_FAILED and g.method == "radau-adjoint"
    assert failing in g.message, g.message
    assert np.isnan(g.parameters).all() and np.isnan(g.value)
    assert np.all(np.isfinite(g.x))


@pytest.mark.parametrize(
    "running_",
    [lambda x, u, p: ca.sqrt(ca.fmax(-x[0], 0.0)), lambda x, u, p: ca.sqrt(ca.fmax(-p[0], 0.0))],
)
def test_a_reverse_mode_not_finite_stops_the_continuous_adjoint(model, running_):
    """Along the state or along the parameters alone: the backward pass stops at once."""
    g = sc.gradient(model, lambda tr: tr.integral[0, -1], Q0, QD0, t=T, running=running_,
                    method="adams-adjoint")  # fmt: skip
    assert g.status is Status.INTEGRATION_FAILED, g.message
    assert "the right-hand side's reverse mode failed, or is not finite" in g.message
    assert np.isnan(g.parameters).all() and np.all(np.isfinite(g.x))


def test_a_parameter_vector_is_checked_as_a_robot(model):
    p = model.parameters.copy()
    p[model.robot.parameter_names().index("segments[0].mass")] = -1.0
    with pytest.raises(sc.ParameterError, match=r"parameters: .*mass"):
        sc.gradient(model, lambda tr: tr.tip[2, -1], Q0, t=T, parameters=p)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"t": [0.0, 0.1, 0.1]}, "increasing output times"),
        ({"inputs": np.full(3, 2e5)}, r"inputs\[0\] = 200000.0 Pa is outside its bounds"),
        ({"inputs": np.zeros((2, 3))}, r"one row per output"),
        ({"wrt": "gravity"}, "wrt must name"),
        ({"method": "exact"}, "method must be"),
        ({"cost": lambda tr: tr.q[:, -1]}, "one scalar"),
        ({"cost": lambda tr: tr.integral[0, -1]}, "needs gradient"),
        ({"rtol": 2.0}, r"rtol must be in \[2.22045e-14, 1\)"),
        ({"rtol": True}, "rtol must be a real number"),
    ],
)
def test_bad_requests_are_refused_naming_the_field(model, bellows, change, match):
    request = {"t": T, "inputs": None, "wrt": "x0", "method": "auto", "cost": cost}
    request.update(change)
    cost_ = request.pop("cost")
    with pytest.raises(sc.ParameterError, match=match):
        sc.gradient(model, cost_, Q0, actuator=bellows, **request)


def test_the_figure_draws_the_inputs_and_the_largest_parameters(reference):
    figure = reference.plot(largest=5)
    top, bottom = figure.axes
    assert len(top.lines) == 3 and "[per kPa]" in top.get_ylabel()
    assert len(bottom.patches) == 5 and "[" in bottom.get_xlabel()
    matplotlib.pyplot.close(figure)


CONTROLS_REVERSE = """
import sys
import casadi as ca, numpy as np
times = [float(a) for a in sys.argv[1:]]  # the output times
x, u = ca.MX.sym("x", 2), ca.MX.sym("u")
problem = {"x": x, "u": u, "ode": ca.vertcat(x[1], -x[0] + u)}
step = ca.integrator("I", "cvodes", problem, 0.0, times)
x0, U = ca.MX.sym("x0", 2), ca.MX.sym("U", 1, len(times))
value = step(x0=x0, u=U)["xf"][0, -1] ** 2
f = ca.Function("f", [x0, U], [value])
start, held = np.array([1.0, 0.0]), np.linspace(0.3, 0.1, len(times))[None, :]
print(f.reverse(1)(start, held, f(start, held), 1.0))
"""


@pytest.mark.skipif(not ca.__version__.startswith("3.8."), reason="the crash is CasADi 3.8's")
def test_casadi_still_crashes_in_reverse_through_an_integrators_controls():
    """The pin behind ``gradient``'s integration per interval: where this passes no more,
    one integrator with the inputs as controls may serve held inputs too."""

    def run(*times):
        return subprocess.run([sys.executable, "-c", CONTROLS_REVERSE, *map(str, times)],
                              capture_output=True, text=True)  # fmt: skip

    one = run(1.0)
    assert one.returncode == 0, one.stderr  # one output time: the snippet is sound
    two = run(0.5, 1.0)
    assert two.returncode < 0, two.stderr  # two: killed by a signal, not an exception
