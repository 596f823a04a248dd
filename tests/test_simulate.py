"""simulate(): convergence, agreement of integrators, the energy balance, inputs, failures."""

from __future__ import annotations

import io

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson

import softcurve as sc
from softcurve.analysis.statics import equilibrium
from softcurve.base.progress import ProgressLine
from softcurve.base.status import Status
from softcurve.simulation._settings import SimulationSettings
from softcurve.simulation.solvers import _driver as native
from softcurve.simulation.solvers import _policy as _engines
from softcurve.simulation.solvers._grid import input_changes
from softcurve.simulation.solvers._policy import STIFFNESS_RATIO, linearization_rates, nominal_scale

from .conftest import assert_close

Q0, QD0 = np.array([0.064, 25.0, 0.0]), np.array([0.0, 0.0, 1500.0])


def normalized_error(trajectory, reference) -> float:
    """Max over time and states of |x - x_ref| / (max_t |x_ref| + natural scale)."""
    model = reference.model
    scale = np.abs(reference.x).max(axis=0) + nominal_scale(model, np.zeros(model.n_state))
    return float(np.max(np.abs(trajectory.x - reference.x) / scale))


@pytest.fixture(scope="module")
def reference(paper_model):
    """The paper's case over 1 s at a tight tolerance (the transient is in the first second)."""
    return sc.simulate(paper_model, Q0, QD0, t_final=1.0, method="adams", rtol=1e-11)


@pytest.mark.parametrize("method", ["adams", "bdf"])
def test_cvodes_error_falls_with_tolerance(paper_model, reference, method):
    errors = []
    for rtol in (1e-4, 1e-6, 1e-8):
        trajectory = sc.simulate(paper_model, Q0, QD0, t_final=1.0, method=method, rtol=rtol)
        assert trajectory.success, trajectory.message
        errors.append(normalized_error(trajectory, reference))
    assert errors[0] > 10 * errors[1] > 100 * errors[2], errors
    assert errors[1] < 1e-4 and errors[2] < 1e-6, errors  # a small multiple of rtol


def test_rk45_converges_and_agrees_with_cvodes(paper_model, reference):
    loose = sc.simulate(paper_model, Q0, QD0, t_final=1.0, method="rk45", rtol=1e-5)
    tight = sc.simulate(paper_model, Q0, QD0, t_final=1.0, method="rk45", rtol=1e-8)
    assert loose.success and tight.success
    assert normalized_error(tight, reference) < 1e-5
    assert normalized_error(loose, reference) > 10 * normalized_error(tight, reference)
    assert tight.stats["method"] == "rk45" and tight.stats["rhs_evaluations"] > 0


def test_default_picks_adams_for_the_paper_case_and_bdf_when_stiff(paper_model):
    x0 = np.concatenate([Q0, QD0, np.zeros(3)])
    ratio, _ = linearization_rates(paper_model, x0)
    assert 0.5 < ratio < STIFFNESS_RATIO  # creep decay ~ elongation frequency
    trajectory = sc.simulate(paper_model, Q0, QD0, t_final=0.05)
    assert trajectory.stats["method"] == "cvodes-adams"
    # the same structure with a creep 1000x faster relaxing: a stiff problem
    segment = paper_model.robot.segments[0]
    creep = sc.Creep(segment.creep.rate * 1e3, segment.creep.gain * 1e3, segment.creep.compliance)
    stiff = sc.Model(paper_model.robot.replace(segments=(segment.replace(creep=creep),)))
    trajectory = sc.simulate(stiff, Q0, QD0, t_final=0.05)
    assert trajectory.stats["stiffness_ratio"] > STIFFNESS_RATIO
    assert trajectory.stats["method"] == "cvodes-bdf" and trajectory.success


def test_a_settled_robot_continues_with_bdf_at_the_same_accuracy(paper_model):
    """After the first restart interval, "cvodes" switches a settled robot to BDF
    (SETTLED_RATIO); the result stays within tolerance of a tight reference, and with
    the switch disabled the same run stays with Adams."""
    q0, qd0 = np.array([0.064, 5.0, 0.0]), np.zeros(3)
    reference = sc.simulate(paper_model, q0, qd0, t_final=4.0, dt=0.01, method="adams", rtol=1e-10)
    switched = sc.simulate(paper_model, q0, qd0, t_final=4.0, dt=0.01)
    assert switched.stats["method"] == "cvodes-adams+bdf"
    assert "cvodes-adams+bdf" in switched.message
    assert normalized_error(switched, reference) < 5e-5
    state = switched.x[100]  # t = 1 s: still moving, so the second second is Adams
    fastest = _engines.linearization_rates(paper_model, switched.x[0])[1]
    scale = nominal_scale(paper_model, switched.x[0])
    assert not _engines.settled(paper_model.state_derivative(state), scale, fastest)
    assert _engines.settled(paper_model.state_derivative(switched.x[200]), scale, fastest)


def test_without_the_switch_adams_throughout(paper_model, monkeypatch):
    monkeypatch.setattr(_engines, "SETTLED_RATIO", np.inf)  # never settled
    q0, qd0 = np.array([0.064, 5.0, 0.0]), np.zeros(3)
    trajectory = sc.simulate(paper_model, q0, qd0, t_final=4.0, dt=0.01)
    assert trajectory.stats["method"] == "cvodes-adams"


def test_paper_case_budget_of_evaluations(paper_model):
    """10 s of the paper's case at rtol 1e-6: a budget on work, not on wall time."""
    trajectory = sc.simulate(paper_model, Q0, QD0, t_final=10.0)
    assert trajectory.success
    assert trajectory.t.shape == (10001,) and trajectory.t[-1] == 10.0
    # measured 987 steps, 1194 rhs, 143 Jacobians; without the restarts of the multistep
    # method (RESTART_INTERVAL) 1886 steps, 2112 rhs, 139 Jacobians
    assert trajectory.stats["steps"] < 1400
    assert trajectory.stats["rhs_evaluations"] < 1700
    assert trajectory.stats["jacobian_evaluations"] < 200
    if native.driver() is not None:
        # the C driver keeps the Jacobian while CVODES allows: measured 894 steps, 1005 rhs
        # and 24 Jacobians of 9 rhs each (CasADi's integrator: 1027 rhs, 120 Jacobians)
        work = trajectory.stats["rhs_evaluations"] + 9 * trajectory.stats["jacobian_evaluations"]
        assert trajectory.stats["jacobian_evaluations"] < 50 and work < 1500
    # converged to the straight, gravity-compressed equilibrium
    rest = equilibrium(paper_model, [0.064, 0.0, 0.0])
    assert rest.success and rest.q[0] < paper_model.robot.segments[0].rest_length
    assert abs(trajectory.q[-1, 0] - rest.q[0]) < 1e-6
    assert np.all(np.abs(trajectory.q[-1, 1:]) < 1e-6)
    tip = np.array([paper_model.tip_pose(q).position.copy() for q in trajectory.q[::997]])
    np.testing.assert_allclose(trajectory.tip[::997], tip, rtol=0, atol=1e-15)


def test_energy_balance_damped_forced_with_creep(paper_model):
    """E(t) - E(0) = int_0^t qd' (tau + K^T lam - R qd) dt along the trajectory."""
    tau = np.array([0.3, 2e-3, -1e-3])
    lam0 = np.array([1e-4, 5e-3, -2e-3])
    trajectory = sc.simulate(
        paper_model, Q0, QD0 / 3, lam0, tau=tau, t_final=0.5, dt=1e-4, rtol=1e-10
    )
    assert trajectory.success
    terms = paper_model.evaluate_along(
        "dynamics_terms", trajectory.q, trajectory.qd, trajectory.lam
    )
    damping, creep = terms[4], terms[5]
    power = np.einsum("ti,ti->t", trajectory.qd, trajectory.tau + creep - damping)
    work = cumulative_simpson(power, x=trajectory.t, initial=0.0)
    energy = trajectory.energy()
    scale = np.trapezoid(np.abs(power), trajectory.t)
    error = np.max(np.abs(energy - energy[0] - work))
    assert error < 1e-6 * scale, (error, scale)
    assert abs(energy[-1] - energy[0]) > 0.1 * scale  # the balance is not trivially zero


def test_straight_start_at_zero_curvature_is_exact(paper_model):
    trajectory = sc.simulate(paper_model, [0.0644, 0.0, 0.0], np.zeros(3), t_final=0.2)
    assert trajectory.success and np.all(np.isfinite(trajectory.x))
    # no bending appears from nothing (round-off of the finite-difference Newton matrix only)
    assert np.all(np.abs(trajectory.q[:, 1:]) < 1e-20)
    assert trajectory.q[-1, 0] < 0.0644  # gravity compresses the upright robot


class HoldLast:
    """A controller that records its calls and pushes the tip toward +x."""

    def __init__(self, sample_time):
        self.sample_time = sample_time
        self.calls = []
        self.was_reset = False

    def reset(self):
        self.was_reset = True
        self.calls.clear()

    def __call__(self, t, q, qd, lam):
        self.calls.append(t)
        return np.array([0.0, 1e-3 - 1e-5 * qd[1], 0.0])


def test_controller_is_sampled_and_held(paper_model):
    controller = HoldLast(sample_time=5e-3)
    trajectory = sc.simulate(paper_model, Q0, QD0, t_final=0.1, controller=controller, rtol=1e-9)
    assert trajectory.success and controller.was_reset
    np.testing.assert_allclose(controller.calls, np.arange(20) * 5e-3, atol=1e-12)
    held = trajectory.tau[:, 1].reshape(-1)[:100].reshape(20, 5)
    assert np.all(held == held[:, :1])  # constant between samples
    # the same inputs given as an array on the grid give the same trajectory
    replay = sc.simulate(paper_model, Q0, QD0, t_final=0.1, tau=trajectory.tau, rtol=1e-9)
    assert normalized_error(replay, trajectory) < 1e-7


def test_tau_callable_receives_the_state(paper_model):
    seen = []

    def tau(t, state):
        seen.append((t, state.q.copy(), state.x.size))
        return np.zeros(3)

    # tight tolerance: the held input restarts the integrator at every output, the free
    # run does not, so at rtol 1e-6 the two differ by several rtol
    trajectory = sc.simulate(paper_model, Q0, QD0, t_final=0.01, tau=tau, rtol=1e-9)
    free = sc.simulate(paper_model, Q0, QD0, t_final=0.01, rtol=1e-9)
    assert len(seen) == 10 and seen[0][2] == 9
    np.testing.assert_array_equal(seen[0][1], Q0)
    np.testing.assert_allclose(seen[3][1], trajectory.q[3], rtol=1e-14)
    assert normalized_error(trajectory, free) < 1e-7


def test_failure_keeps_the_partial_trajectory(paper_model):
    trajectory = sc.simulate(paper_model, Q0, QD0, t_final=1.0, max_steps=3)
    assert not trajectory.success and trajectory.status is Status.INTEGRATION_FAILED
    assert 0 < trajectory.t.size < 1001 and trajectory.t[-1] < 1.0
    assert "max_steps" in trajectory.message and "What to try" in trajectory.message
    full = sc.simulate(paper_model, Q0, QD0, t_final=1.0)
    k = trajectory.t.size
    np.testing.assert_allclose(trajectory.q, full.q[:k], rtol=1e-4, atol=1e-6)


def test_last_output_is_t_final_when_not_a_multiple_of_dt(paper_model):
    trajectory = sc.simulate(paper_model, Q0, QD0, t_final=0.0105, dt=1e-3)
    assert trajectory.t.size == 12 and trajectory.t[-1] == 0.0105
    assert np.allclose(np.diff(trajectory.t[:-1]), 1e-3)


def test_virtual_machine_model_runs(two_segment_model):
    q0 = np.array([0.0644, 5.0, 0.0, 0.0644, 0.0, 5.0])
    trajectory = sc.simulate(two_segment_model, q0, np.zeros(6), t_final=0.02, dt=2e-3)
    assert trajectory.success and trajectory.tip.shape == (11, 3)
    assert np.all(np.isfinite(trajectory.x))


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"t_final": 0.0}, "t_final"),
        ({"t_final": float("nan")}, "t_final"),
        ({"dt": -1e-3}, "dt"),
        ({"dt": 2.0}, "dt must be <= t_final"),
        ({"q0": [0.064, 25.0]}, "q0"),
        ({"qd0": [0.0, np.inf, 0.0]}, "qd0"),
        ({"lam0": np.zeros(2)}, "lam0"),
        ({"tau": np.zeros((5, 3))}, "tau"),
        ({"method": "euler"}, "method"),
        ({"rtol": 0.0}, "rtol"),
        ({"atol": -1.0}, "atol"),
        ({"atol": np.ones(4)}, "atol"),
        ({"max_steps": 0}, "max_steps"),
        ({"controller": object()}, "controller"),
        ({"controller": HoldLast(0.0)}, "sample_time"),
        ({"controller": HoldLast(1e-3), "tau": np.zeros(3)}, "one of tau, inputs or a controller"),
        ({"settings": {"t_final": 1.0}}, "SimulationSettings"),
    ],
)
def test_bad_arguments_are_named(paper_model, kwargs, named):
    arguments = {"t_final": 1.0, "q0": Q0, "qd0": QD0, **kwargs}
    with pytest.raises(sc.ParameterError, match=named):
        sc.simulate(paper_model, **arguments)


def test_progress_bar_appears_only_after_its_delay():
    stream = io.StringIO()
    bar = ProgressLine(10.0, unit="s simulated", delay=0.0, stream=stream)
    bar.update(2.5)
    bar.close()
    text = stream.getvalue()
    assert "2.5/10 s simulated" in text and "#" * 7 + "." in text and text.endswith("\n")
    quiet = io.StringIO()
    bar = ProgressLine(10.0, unit="s simulated", delay=3600.0, stream=quiet)
    bar.update(5.0)
    bar.close()
    assert quiet.getvalue() == ""


@pytest.mark.parametrize(
    ("t_final", "dt", "interval", "expected"),
    [
        (3.0, 1.0, 1.0, [(0, 1), (1, 2), (2, 3)]),
        (2.5, 0.5, 1.0, [(0, 2), (2, 4), (4, 5)]),
        (1.0, 0.4, 1.0, [(0, 3)]),  # exactly one interval
        (1.0, 0.4, 0.9, [(0, 2), (2, 3)]),  # last output interval 0.2 s
        (4.0, 2.0, 1.0, [(0, 1), (1, 2)]),  # output interval longer than the restart one
        (0.5, 0.1, 1.0, [(0, 5)]),
    ],
)
def test_restart_segments_cover_the_grid(t_final, dt, interval, expected):
    grid = SimulationSettings(t_final=t_final, dt=dt).output_times()
    assert _engines.restart_segments(grid, interval) == expected


def test_input_changes_are_the_rows_that_differ_from_the_one_before():
    rng = np.random.default_rng(15)
    inputs = rng.integers(0, 2, size=(400, 3)).astype(np.float64)
    inputs[100:200] = inputs[100]  # a long constant stretch
    expected = np.flatnonzero(np.any(inputs[1:-1] != inputs[:-2], axis=1)) + 1
    np.testing.assert_array_equal(input_changes(inputs), expected)
    assert input_changes(np.zeros((2, 3))).size == input_changes(np.zeros((9, 3))).size == 0


def test_restarts_keep_the_trajectory_within_tolerance(paper_model):
    q0, qd0 = [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0]
    reference = sc.simulate(paper_model, q0, qd0, t_final=3.0, dt=0.01, rtol=1e-11)
    restarted = sc.simulate(paper_model, q0, qd0, t_final=3.0, dt=0.01, rtol=1e-7)
    scale = np.max(np.abs(reference.x), axis=0) + _engines.nominal_scale(
        paper_model, reference.x[0]
    )
    assert np.max(np.abs(restarted.x - reference.x) / scale) < 100 * 1e-7


def _bellows(**extra):
    return sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4, **extra)


@pytest.mark.parametrize("method", ["cvodes", "rk45"])
def test_constant_pressures_settle_at_the_equilibrium_with_those_pressures(paper_model, method):
    actuator = _bellows()
    pressures = np.array([2e4, 0.0, 5e3])
    q0 = np.array([0.064, 0.0, 0.0])
    run = sc.simulate(
        paper_model,
        q0,
        np.zeros(3),
        t_final=6.0,
        inputs=pressures,
        actuator=actuator,
        dt=0.01,
        method=method,
    )  # fmt: skip
    assert run.success, run.message
    q_end = run.q[-1]
    static = paper_model.gravity_force(q_end) + paper_model.elastic_force(q_end)
    assert_close(static, actuator.generalized_force(q_end, pressures), atol=1e-6, rtol=1e-5)
    np.testing.assert_array_equal(run.inputs, np.tile(pressures, (run.t.size, 1)))
    assert_close(run.tau[-1], actuator.input_matrix(q_end) @ pressures, atol=0, rtol=1e-12)


def test_pressures_along_the_trajectory_equal_tau_given_as_h_of_q_times_p(paper_model):
    """H(q) p is evaluated inside the integrator: a callable tau(t, state) = H(q) p held
    per output interval converges to it as the output interval shrinks."""
    actuator = _bellows()
    pressures = np.array([3e4, 1e4, 0.0])
    q0, qd0 = np.array([0.064, 5.0, -3.0]), np.zeros(3)
    exact = sc.simulate(
        paper_model,
        q0,
        qd0,
        t_final=0.5,
        inputs=pressures,
        actuator=actuator,
        dt=0.05,
        rtol=1e-10,
    )  # fmt: skip
    errors = []
    for dt in (1e-3, 1e-4):
        held = sc.simulate(
            paper_model,
            q0,
            qd0,
            t_final=0.5,
            dt=dt,
            rtol=1e-10,
            tau=lambda t, s: actuator.generalized_force(s.q, pressures),
        )
        errors.append(np.max(np.abs(held.q[:: round(0.05 / dt)] - exact.q)))
    assert errors[1] < errors[0] / 5  # first-order convergence of the hold to the exact input


def test_pressure_inputs_are_validated(paper_model):
    q0, qd0 = [0.064, 0.0, 0.0], [0.0, 0.0, 0.0]
    with pytest.raises(sc.ParameterError, match=r"inputs\[0\] = 70000.0 Pa is outside"):
        sc.simulate(paper_model, q0, qd0, t_final=1.0, inputs=[7e4, 0, 0], actuator=_bellows())
    with pytest.raises(sc.ParameterError, match="actuator"):
        sc.simulate(paper_model, q0, qd0, t_final=1.0, inputs=[1e4, 0, 0])
    with pytest.raises(sc.ParameterError, match="one of tau, inputs"):
        sc.simulate(paper_model, q0, qd0, t_final=1.0, tau=[0, 0, 0], inputs=[0, 0, 0],
                    actuator=_bellows())  # fmt: skip
    with pytest.raises(sc.ParameterError, match="give inputs="):
        sc.simulate(paper_model, q0, qd0, t_final=1.0, actuator=_bellows())
    with pytest.raises(sc.ParameterError, match="shape"):
        sc.simulate(paper_model, q0, qd0, t_final=1.0, inputs=[0, 0], actuator=_bellows())
    with pytest.raises(sc.ParameterError, match=r"the callable's pressures\[0\] = -1.0 Pa"):
        sc.simulate(paper_model, q0, qd0, t_final=0.01, inputs=lambda t, s: [-1.0, 0, 0],
                    actuator=_bellows())  # fmt: skip
    with pytest.raises(sc.ParameterError, match=r"the controller's pressures\[0\] = -1.0 Pa"):
        sc.simulate(paper_model, q0, qd0, t_final=0.01, actuator=_bellows(),
                    controller=Constant([-1.0, 0.0, 0.0], 5e-3))  # fmt: skip


@pytest.mark.parametrize("method", ["cvodes", "rk45"])
def test_lagging_chamber_pressures_follow_the_exact_first_order_response(paper_model, method):
    """With a time constant the pressures are states: p(t) = c (1 - exp(-t / T)) from zero
    for a constant command c, whatever the robot does."""
    actuator = _bellows(time_constant=0.05)
    command = np.array([3e4, 0.0, 1e4])
    run = sc.simulate(
        paper_model,
        [0.064, 0.0, 0.0],
        np.zeros(3),
        t_final=0.5,
        dt=0.01,
        inputs=command,
        actuator=actuator,
        method=method,
        rtol=1e-9,
    )  # fmt: skip
    assert run.success, run.message
    exact = command * (1 - np.exp(-run.t / 0.05))[:, None]
    assert_close(run.inputs, exact, atol=1e-9 * 3e4, rtol=1e-6)
    assert_close(run.tau[-1], actuator.input_matrix(run.q[-1]) @ run.inputs[-1], rtol=1e-12)
    assert run.x.shape == (run.t.size, paper_model.n_state)


def test_pressure_controller_callable_with_lag_matches_a_constant_command(paper_model):
    actuator = _bellows(time_constant=0.05)
    command = np.array([2e4, 5e3, 0.0])
    kwargs = dict(actuator=actuator, dt=0.01, rtol=1e-9)
    constant = sc.simulate(
        paper_model,
        [0.064, 0.0, 0.0],
        np.zeros(3),
        t_final=0.3,
        inputs=command,
        **kwargs,
    )  # fmt: skip
    held = sc.simulate(
        paper_model,
        [0.064, 0.0, 0.0],
        np.zeros(3),
        t_final=0.3,
        inputs=lambda t, s: command,
        **kwargs,
    )
    assert_close(held.x, constant.x, atol=1e-7, rtol=1e-6, scale=np.max(np.abs(constant.x), 0))


class Constant:
    """A controller returning the same actuator inputs at every sample."""

    def __init__(self, inputs, sample_time):
        self.inputs, self.sample_time = np.asarray(inputs, dtype=float), sample_time

    def __call__(self, t, q, qd, lam):
        return self.inputs


def test_a_controller_returns_actuator_inputs_under_an_actuator(paper_model):
    """With actuator=, a controller's output is the actuator's inputs: a constant one gives
    the run of the same constant inputs, lag included, and the trajectory keeps them."""
    actuator = _bellows(time_constant=0.05)
    command = np.array([2e4, 5e3, 0.0])
    kwargs = dict(actuator=actuator, t_final=0.3, dt=0.01, rtol=1e-9)
    constant = sc.simulate(paper_model, [0.064, 0.0, 0.0], np.zeros(3), inputs=command, **kwargs)
    controlled = sc.simulate(paper_model, [0.064, 0.0, 0.0], np.zeros(3),
                             controller=Constant(command, 0.02), **kwargs)  # fmt: skip
    assert controlled.success and controlled.inputs.shape == (31, 3)
    assert_close(controlled.x, constant.x, atol=1e-7, rtol=1e-6,
                 scale=np.max(np.abs(constant.x), 0))  # fmt: skip
    assert_close(controlled.inputs, constant.inputs, atol=1e-9 * 2e4, rtol=1e-6)


def test_settings_are_validated_once_and_options_override_them(paper_model):
    settings = SimulationSettings(t_final=0.05, dt=0.01)
    run = sc.simulate(paper_model, Q0, QD0, settings=settings, dt=0.005)
    assert run.t.size == 11 and run.stats["dt"] == 0.005
    with pytest.raises(sc.ParameterError, match=r"dt must be <= t_final = 0.05 \[s\], got 1.0"):
        settings.replace(dt=1.0)
    with pytest.raises(sc.ParameterError, match="unknown simulation setting 'tfinal'"):
        settings.replace(tfinal=1.0)
    with pytest.raises(TypeError, match="unexpected keyword argument 'pressures'"):
        sc.simulate(paper_model, Q0, QD0, pressures=[0, 0, 0])
    bad = [
        ("rtol", 1.0, "rtol must be in"),
        ("atol", [1.0, -1.0], "atol"),
        ("max_steps", True, "max_steps"),
        ("t_final", "1", "t_final"),
    ]
    for field, value, named in bad:
        with pytest.raises(sc.ParameterError, match=named):
            SimulationSettings(**{field: value})


# -- the model's domain and passivity (issue 11, cases 3 and 4) ------------------------------
def test_a_length_crossing_zero_stops_with_left_domain(paper_model):
    """A huge initial rate drives l through zero: before, the run reported success with
    l < 0; now it stops at the first output outside the domain, keeping the rest."""
    run = sc.simulate(paper_model, [0.064, 0.0, 0.0], [-50.0, 0.0, 0.0], t_final=0.5, dt=1e-4)
    assert run.status is Status.LEFT_DOMAIN and not run.success
    assert 10 <= run.t.size < 5001 and np.all(run.q[:, 0] > 0)
    stopped = run.t[-1] + 1e-4
    for words in (
        f"the state left the model's domain at t = {stopped:.6g} s",
        "l of segment 1 (q[0]) = -",
        "0 < l <= 10 rest lengths",
        "too soft for its loads",
        "initial rate qd0 too large",
        f"the trajectory stops at t = {run.t[-1]:.6g} s",
    ):
        assert words in run.message, (words, run.message)
    kept = sc.simulate(paper_model, [0.064, 0.0, 0.0], [-50.0, 0.0, 0.0], t_final=run.t[-1],
                       dt=1e-4)  # fmt: skip
    assert kept.success and normalized_error(run, kept) < 1e-5  # the same run, to its rtol


@pytest.mark.parametrize(("gravity", "words"), [(-9.81, "= -"), (9.81, "l of segment 1")])
def test_a_robot_too_soft_for_its_weight_leaves_the_domain(gravity, words):
    """A 1e-3 N/m segment collapses upright (l < 0) or stretches past ten rest lengths
    hanging; both stop, also with RK45 (checked at every output)."""
    robot = sc.presets.ifac2020(creep=False)
    soft = robot.segments[0].replace(elongation_stiffness=sc.LinearStiffness(1e-3))
    model = sc.Model(robot.replace(segments=(soft,), gravity=[0.0, 0.0, gravity]), compile=False)
    for method in ("cvodes", "rk45"):
        run = sc.simulate(model, [0.0644, 0, 0], [0, 0, 0], t_final=2.0, dt=0.01, method=method)
        assert run.status is Status.LEFT_DOMAIN, (method, run.message)
        assert words in run.message and "too soft" in run.message
        assert np.all((run.q[:, 0] > 0) & (run.q[:, 0] <= 0.644))


def test_controller_never_sees_a_state_outside_the_domain(paper_model):
    seen = []

    def tau(t, state):
        seen.append(state.q[0])
        return np.zeros(3)

    run = sc.simulate(paper_model, [0.064, 0, 0], [-50.0, 0, 0], tau=tau, t_final=0.1, dt=1e-3)
    assert run.status is Status.LEFT_DOMAIN and "l of segment 1" in run.message
    assert min(seen) > 0


def test_q0_outside_the_domain_is_refused_as_by_the_scenario_loader(paper_model):
    from softcurve.scenarios.config import Scenario

    with pytest.raises(sc.ParameterError, match=r"q0: lengths l must be in the model's domain"):
        sc.simulate(paper_model, [-0.01, 0.0, 0.0], np.zeros(3), t_final=0.1)
    try:
        sc.simulate(paper_model, [-0.01, 0.0, 0.0], np.zeros(3), t_final=0.1)
    except sc.ParameterError as error:
        from_simulate = str(error).removeprefix("q0: ")
    with pytest.raises(sc.ParameterError) as from_scenario:
        Scenario(paper_model.robot, q0=(-0.01, 0.0, 0.0))
    assert str(from_scenario.value) == f"q0 {from_simulate}"  # one check, one message
    with pytest.raises(sc.ParameterError, match="bends 12.8 rad"):
        sc.simulate(paper_model, [0.064, 200.0, 0.0], np.zeros(3), t_final=0.1)


def _random_passive_creep(rng) -> tuple[sc.Creep, np.ndarray]:
    """A full (non-diagonal) passive creep: P symmetric positive definite, K = P G, rates
    drawn until P R + R P is positive semidefinite. Returns the creep and P."""
    while True:
        a = rng.normal(size=(3, 3))
        p = a @ a.T + 0.1 * np.eye(3)
        gain = rng.choice([-1.0, 1.0], 3) * rng.uniform(0.05, 1.0, 3)
        rate = rng.uniform(20.0, 300.0, 3)
        r = np.diag(rate)
        if np.linalg.eigvalsh(p @ r + r @ p)[0] > 0:
            scale = np.array([50.0, 5e-3, 5e-3])  # forces of the paper's order per coordinate
            p = p * np.sqrt(scale[:, None] * scale[None, :])
            return sc.Creep(rate, gain, p @ np.diag(gain)), p


def test_random_passive_creep_never_creates_energy(rng):
    """Without damping, gravity or input, E + lam' P lam / 2 (P = K G^-1) never grows and
    falls by the creep dissipation int lam' P R lam dt."""
    robot = sc.presets.ifac2020(damping=False).replace(gravity=[0.0, 0.0, 0.0])
    for _ in range(3):
        creep, p = _random_passive_creep(rng)
        segment = robot.segments[0].replace(creep=creep)
        model = sc.Model(robot.replace(segments=(segment,)))
        lam0 = rng.normal(size=3) * np.array([1e-3, 1.0, 1.0]) * np.abs(creep.gain)
        run = sc.simulate(model, Q0, QD0 / 3, lam0, t_final=0.3, dt=1e-4, rtol=1e-10)
        assert run.success, run.message
        storage = 0.5 * np.einsum("ti,ij,tj->t", run.lam, p, run.lam)
        total = run.energy() + storage
        magnitude = np.max(np.abs(run.energy())) + np.max(storage)
        assert np.max(np.diff(total)) <= 1e-7 * magnitude, np.max(np.diff(total)) / magnitude
        r = np.diag(creep.rate)
        dissipation = np.einsum("ti,ij,tj->t", run.lam, 0.5 * (p @ r + r @ p), run.lam)
        lost = cumulative_simpson(dissipation, x=run.t, initial=0.0)
        assert_close(total[0] - total, lost, rtol=0, atol=1e-6 * magnitude, what="balance")
        assert lost[-1] > 1e-3 * magnitude  # the balance is not trivially zero
