"""The transcription layer (``sc.Transcription``) and trajectory optimization
(``sc.optimize_trajectory``): the Functions against the model and ``simulate``, their
derivatives against differences, and plans checked by simulating their inputs."""

from __future__ import annotations

import casadi as ca
import matplotlib.pyplot
import numpy as np
import pytest
import scipy.optimize

import softcurve as sc
from softcurve.base.status import Status

from .test_kinds import gripper, six_strain_segment

NODES = 3  # quadrature nodes: a smaller expression, the same physics to check


@pytest.fixture(scope="module")
def model():
    return sc.Model(sc.presets.ifac2020(), quadrature_nodes=NODES)


@pytest.fixture(scope="module")
def bellows():
    return sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)


@pytest.fixture(scope="module")
def transcription(model, bellows):
    return sc.Transcription(model, bellows)


def a_state(transcription, seed=0):
    rng = np.random.default_rng(seed)
    x = transcription.start([0.064, 8.0, -5.0], rng.normal(size=3) * [0.01, 20.0, 20.0])
    return x, np.array([3e4, 1e4, 5e3])


def test_the_right_hand_side_is_the_models(model, bellows, transcription):
    x, u = a_state(transcription)
    tau = bellows.input_matrix(x[:3]) @ u
    expected = model.state_derivative(x, tau)
    got = np.array(transcription.rhs(x, u, transcription.parameters)).ravel()
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
    assert (transcription.n_x, transcription.n_u) == (model.n_state, 3)


def test_a_lagging_actuator_adds_its_inputs_to_the_state(model):
    lagging = sc.PneumaticActuator.three_bellows(
        distance=0.01, area=2e-5, p_max=1e5, time_constant=0.05
    )
    tr = sc.Transcription(model, lagging)
    x = tr.start([0.064, 0.0, 0.0], actuator_state=[1e4, 0.0, 0.0])
    assert tr.n_x == model.n_state + 3
    xdot = np.array(tr.rhs(x, [2e4, 0.0, 0.0], tr.parameters)).ravel()
    np.testing.assert_allclose(xdot[model.n_state :], [(2e4 - 1e4) / 0.05, 0.0, 0.0])


def test_the_steps_converge_to_simulate_at_high_order(model, bellows, transcription):
    x, u = a_state(transcription)
    duration = 0.04
    run = sc.simulate(model, x[:3], x[3:6], actuator=bellows, inputs=u, t_final=duration,
                      dt=duration, rtol=1e-12, atol=1e-14)  # fmt: skip
    errors = []
    for steps in (4, 8, 16):
        rollout = transcription.rollout(steps)
        U = np.tile(u[:, None], (1, steps))
        final = np.array(rollout(x, U, transcription.parameters, duration / steps))[:, -1]
        errors.append(np.abs(final[:3] - run.q[-1]).max())
    slopes = -np.diff(np.log2(errors))
    assert np.all(slopes > 3.0), errors  # order 5 at small steps, stage order 3 when stiff


def test_the_steps_derivatives_are_exact(transcription):
    x, u = a_state(transcription, seed=1)
    p, h = transcription.parameters, 0.005
    xs, us = ca.MX.sym("x", x.size), ca.MX.sym("u", u.size)
    out = transcription.step(xs, us, p, h)
    derivative = ca.Function("d", [xs, us], [ca.jacobian(out, xs), ca.jacobian(out, us)])
    by_x, by_u = (np.array(a) for a in derivative(x, u))
    for value, exact, scale in ((x, by_x, np.maximum(np.abs(x), 1e-3)), (u, by_u, 1e4 + 0 * u)):
        for j in range(value.size):
            delta = np.zeros(value.size)
            delta[j] = 1e-6 * scale[j]
            args = (value + delta, value - delta)
            if value is x:
                plus, minus = (np.array(transcription.step(a, u, p, h)).ravel() for a in args)
            else:
                plus, minus = (np.array(transcription.step(x, a, p, h)).ravel() for a in args)
            central = (plus - minus) / (2 * delta[j])
            np.testing.assert_allclose(
                exact[:, j], central, rtol=1e-5, atol=1e-6 * np.abs(exact).max()
            )


def _stage_jacobian_case(case):
    """A model not compiled (the expressions in CasADi's virtual machine) and its
    actuator for the stage Jacobian's cases."""
    segment = sc.presets.ifac2020().segments[0]
    if case == "two-segment tendons":
        tendons = sc.TendonActuator(
            [sc.Tendon(azimuth=a, distance=0.008, t_max=5.0, anchor=anchor)
             for anchor in (0, 1) for a in (0.0, 2 * np.pi / 3)], n_segments=2,
        )  # fmt: skip
        robot = sc.Robot(segments=(segment, segment))
        return sc.Model(robot, quadrature_nodes=2, compile=False), tendons
    if case == "two segments in contact, forces":
        ceiling = sc.Plane([0.0, 0.0, 0.12], [0.0, 0.0, -1.0])
        return sc.Model(sc.Robot(segments=(segment, segment)), quadrature_nodes=2,
                        environment=sc.Environment([ceiling], sc.ContactLaw(1e4)),
                        compile=False), None  # fmt: skip
    if case == "six strains with creep and a gripper, bellows":
        robot = sc.Robot(segments=(six_strain_segment(creep=True), gripper()))
        bellows = sc.PneumaticActuator.three_bellows(
            elements=robot, distance=0.005, area=2e-5, p_max=1e5
        )
        return sc.Model(robot, quadrature_nodes=2, compile=False), bellows
    model = sc.Model(sc.presets.ifac2020(), quadrature_nodes=2, compile=False)
    if case == "lagging bellows":
        return model, sc.PneumaticActuator.three_bellows(
            distance=0.01, area=2e-5, p_max=1e5, time_constant=0.02
        )
    return model, None


@pytest.mark.parametrize(
    "case", ["two-segment tendons", "two segments in contact, forces", "lagging bellows",
             "forces", "six strains with creep and a gripper, bellows"],
)  # fmt: skip
def test_the_stage_jacobians_two_routes_agree(case):
    """The planners' stage Jacobian by its two routes, algorithm against algorithm: the
    derivatives of the chain algorithms through the segments' calls against CasADi's
    Jacobian of the expanded right-hand side (1e-12 of the largest entry), the inputs'
    columns with the state's, at random states (about the rest configuration, by the
    coordinates' scales), the inputs across their range."""
    model, actuator = _stage_jacobian_case(case)
    tr = sc.Transcription(model, actuator)
    p = tr.parameters
    rng = np.random.default_rng(12)
    low, high = tr.input_bounds
    rest, scale = model.robot.rest_configuration(), model.robot.coordinate_scale()
    lagging = actuator is not None and actuator.time_constant is not None
    for _ in range(2):
        q = rest + 0.3 * scale * rng.normal(size=model.n)
        qd = scale * rng.normal(size=model.n)
        lam = 1e-3 * rng.normal(size=model.n_state - 2 * model.n)
        x = tr.start(q, qd, lam, rng.uniform(low, high) if lagging else None)
        u = rng.normal(size=tr.n_u) if actuator is None else rng.uniform(low, high)
        (xdot, by_passes), (xdot_expanded, expanded) = (
            [np.array(v) for v in tr.compiled_stage_jacobian(route)(x, u, p)]
            for route in ("passes", "expanded")
        )  # fmt: skip
        assert by_passes.shape == (tr.n_x, tr.n_x + tr.n_u)
        np.testing.assert_allclose(xdot, xdot_expanded, rtol=1e-14, atol=0)
        np.testing.assert_allclose(by_passes, expanded, rtol=0,
                                   atol=1e-12 * np.abs(expanded).max())  # fmt: skip


def test_the_collocation_equations_hold_at_the_steps_stages(transcription):
    x, u = a_state(transcription, seed=2)
    p, h, n_x = transcription.parameters, 0.01, transcription.n_x

    def residual(z):
        return np.array(transcription.collocation(x, z.reshape(3, n_x).T, u, p, h)[0]).T.ravel()

    # root, not fsolve: where round-off stops the iteration short of xtol (it depends on
    # the CPU's instructions), fsolve warns and root reports it; the residual decides
    z = scipy.optimize.root(residual, np.zeros(3 * n_x), options={"xtol": 1e-14}).x
    assert np.abs(residual(z)).max() < 1e-8
    after = np.array(transcription.collocation(x, z.reshape(3, n_x).T, u, p, h)[1]).ravel()
    np.testing.assert_allclose(after, np.array(transcription.step(x, u, p, h)).ravel(), rtol=1e-9,
                               atol=1e-9)  # fmt: skip


def test_the_compiled_collocation_is_the_symbolic_one_to_second_derivatives(transcription):
    """The equations the planner solves, on the right-hand side compiled with its
    derivatives: values, Jacobian and a Hessian against the symbolic equations'."""
    n_x, n_u = transcription.n_x, transcription.n_u
    x, u = a_state(transcription, seed=3)
    p, h = transcription.parameters, 0.01
    z = np.random.default_rng(4).normal(0.0, 1e-3, (n_x, 3)) * np.abs(x)[:, None]
    w = ca.MX.sym("w", n_x * 4 + n_u)
    args = (w[:n_x], ca.reshape(w[n_x : 4 * n_x], n_x, 3), w[4 * n_x :], p, h)
    point = np.concatenate([x, z.T.ravel(), u])
    weights = np.random.default_rng(5).normal(size=3 * n_x)
    values = []
    for equations in (transcription.collocation, transcription.compiled_collocation(2)):
        residual = ca.vec(equations(*args)[0])
        weighted = ca.dot(ca.DM(weights), residual)
        function = ca.Function("f", [w], [residual, ca.jacobian(residual, w),
                                          ca.hessian(weighted, w)[0]])  # fmt: skip
        values.append([np.array(v) for v in function(point)])
    for symbolic, compiled in zip(*values, strict=True):
        scale = np.abs(symbolic).max()
        np.testing.assert_allclose(compiled, symbolic, rtol=0, atol=1e-10 * scale)


def _problems(model, actuator, **request):
    """The collocation problem of a reach (within 3 steps, at rest at the end) with the
    exact and with the Gauss-Newton Hessian from a bent and moving start, and a point
    with the nodes' states perturbed, the stages' increments random and the inputs across
    their range."""
    from softcurve.control import _problem as problem

    tr = sc.Transcription(model, actuator)
    x0 = request.pop("x0", None)
    x0 = a_state(tr, seed=7)[0] if x0 is None else tr.start(*x0)
    weights = {"reference_weight": 0.0, "effort_weight": 1e-3, "rate_weight": 1e-6,
               "time_weight": 1.0 if isinstance(request["horizon"], tuple) else 0.0}  # fmt: skip
    checked = problem.checked_request(
        model, intervals=3, targets=[sc.TipTarget(REACH, tolerance=2e-3)], reference=None,
        weights=weights, clearance=request.pop("clearance", None),
        tip_bounds=request.pop("tip_bounds", None), tolerance=1e-8, max_iterations=1, **request,
    )  # fmt: skip
    built = {
        hessian: problem.Problem.build(
            tr,
            x0,
            checked,
            rest_at_end=True,
            method="collocation",
            hessian=hessian,
            previous_inputs=False,
            threads=2,  # the stages' maps over threads, as the plans' by default
        )  # fmt: skip
        for hessian in ("exact", "gauss-newton")
    }
    rng = np.random.default_rng(11)
    exact = built["exact"]
    point = exact.rest_guess(x0) * (1.0 + 0.05 * rng.normal(size=exact.sizes[0]))
    inputs = exact.u_rows
    point[inputs] = rng.random(inputs.stop - inputs.start)  # scaled: 0 lower, 1 upper bound
    stages = slice(inputs.stop, inputs.stop + exact.z_count)
    point[stages] = 0.05 * rng.normal(size=exact.z_count)  # scaled as the states
    return built, point, rng


def _case(case, model, bellows):
    """The model, actuator and request of a case of the stage-by-stage derivatives."""
    if case == "free final time":
        return model, bellows, {"horizon": (0.05, 0.3)}
    if case.startswith("lag"):
        ceiling = sc.Plane([0.0, 0.0, 0.07], [0.0, 0.0, -1.0])
        environment = sc.Environment([ceiling], sc.ContactLaw(1e4))
        model = sc.Model(sc.presets.ifac2020(), environment=environment,
                         quadrature_nodes=NODES, compile=False)  # fmt: skip
        bellows = sc.PneumaticActuator.three_bellows(
            distance=0.01, area=2e-5, p_max=1e5, time_constant=0.02
        )
        box = ([-0.05, -0.05, 0.0], [0.05, 0.05, 0.07])
        return model, bellows, {"horizon": 0.2, "clearance": 0.0, "tip_bounds": box}
    if case.startswith("six"):
        robot = sc.Robot(segments=(six_strain_segment(creep=True), gripper()))
        model = sc.Model(robot, quadrature_nodes=2, compile=False)
        bellows = sc.PneumaticActuator.three_bellows(
            elements=robot, distance=0.005, area=2e-5, p_max=1e5
        )
        bent = robot.rest_configuration() + np.array([5.0, -3.0, 4.0, 0.05, -0.02, 0.1])
        return model, bellows, {"horizon": 0.2, "x0": (bent, np.full(robot.n, 0.5))}
    return model, bellows, {"horizon": 0.2}


@pytest.mark.parametrize(
    "case",
    ["fixed horizon", "free final time", "lag, clearance and tip bounds",
     "six strains with creep and a gripper"],
)  # fmt: skip
def test_the_derivatives_by_stages_are_casadis_through_the_whole_problem(case, model, bellows):
    """IPOPT gets the exact Hessian of the Lagrangian (Problem.lagrangian_hessian) and,
    with the Gauss-Newton Hessian and with the exact one of a chain, the constraints and
    their Jacobian (Problem.constraint_jacobian) assembled from each stage's derivatives
    of the right-hand side; CasADi's differentiate the whole problem (the exact one's
    problem). At a point with the inputs across their range and random multipliers; on
    the paper's robot, and on a six-strain segment with creep carrying a rigid gripper
    (twist, shear, a fixed placement: two elements, a chain)."""
    from softcurve.control import _problem as problem

    model, bellows, request = _case(case, model, bellows)
    built, point, rng = _problems(model, bellows, **request)
    exact = built["exact"]
    w, p, nlp = exact.nlp["x"], exact.nlp["p"], exact.nlp
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", exact.sizes[1])
    lagrangian = lam_f * nlp["f"] + ca.dot(lam_g, nlp["g"])
    whole = ca.Function("whole", [w, p, lam_f, lam_g],
                        [ca.triu(ca.hessian(lagrangian, w)[0]), nlp["g"],
                         ca.jacobian(nlp["g"], w)])  # fmt: skip
    duals = rng.normal(size=exact.sizes[1])
    hessian, g, jacobian = (np.array(v) for v in whole(point, 0.0, 1.3, duals))
    by_stages = np.array(exact.lagrangian_hessian(point, 0.0, 1.3, duals))
    staged = built["gauss-newton"].constraint_jacobian(point, 0.0)
    g_staged, jacobian_staged = (np.array(v) for v in staged)
    pairs = [(by_stages, hessian), (g_staged, g), (jacobian_staged, jacobian)]
    if case.startswith("six"):  # a chain: the exact Hessian's plan takes it by stages too
        assert problem.jacobian_by_stages(exact.transcription, "exact")
        pairs.append((np.array(exact.constraint_jacobian(point, 0.0)[1]), jacobian))
    for mine, reference in pairs:
        assert np.abs(reference).max() > 0
        np.testing.assert_allclose(mine, reference, rtol=0, atol=1e-12 * np.abs(reference).max())
    # and the pattern IPOPT factors: CasADi's, with room for the stages' blocks dense (a
    # loose bound; a free final time's dense selector once filled examples/flick.py's: 28
    # times CasADi's)
    tr = exact.transcription
    dense_blocks = exact.stages.symbol.shape[1] * (tr.n_x + tr.n_u) ** 2
    entries = exact.lagrangian_hessian.sparsity_out(0).nnz(), whole.sparsity_out(0).nnz()
    assert entries[0] <= entries[1] + dense_blocks, entries


def test_a_limited_memory_hessian_reaches_the_exact_plan(model, bellows, reach):
    goal = sc.TipTarget(REACH, tolerance=2e-3)
    approximate = sc.optimize_trajectory(
        model, [0.064, 0.0, 0.0], actuator=bellows, horizon=0.2, intervals=8, targets=[goal],
        effort_weight=1e-3, rest_at_end=True, hessian="limited-memory", tolerance=1e-6,
    )  # fmt: skip
    assert approximate.success and approximate.hessian == "limited-memory"
    assert np.all(approximate.u >= bellows.lower) and np.all(approximate.u <= bellows.upper)
    assert reach.hessian == "exact" and approximate.iterations > reach.iterations
    assert approximate.cost == pytest.approx(reach.cost, rel=1e-3)


def test_the_domain_margins_are_the_models_and_the_actuators(model, transcription):
    x, _ = a_state(transcription)
    margins = np.array(transcription.domain(x, transcription.parameters)).ravel()
    assert np.all(margins >= 0)
    assert margins.size == 3 + 3  # length, bend, stretch; one chamber per bellows
    outside = x.copy()
    outside[0] = -0.01  # a negative length
    assert np.array(transcription.domain(outside, transcription.parameters)).min() < 0
    bent = x.copy()
    bent[1] = 400.0  # beyond a chamber's volume (and a turn of the segment)
    assert np.array(transcription.domain(bent, transcription.parameters)).min() < 0


def test_the_gaps_are_the_signed_distances_from_the_obstacles():
    environment = sc.Environment([sc.Plane([0.0, 0.0, 0.05], [0.0, 0.0, -1.0])], sc.ContactLaw(1e4))
    model = sc.Model(sc.presets.ifac2020(), environment=environment, quadrature_nodes=NODES)
    tr = sc.Transcription(model)
    q = np.array([0.064, 0.0, 0.0])
    gaps = np.array(tr.gaps(np.r_[q, np.zeros(6)], tr.parameters)).ravel()
    assert gaps[0] == pytest.approx(0.05)  # the base, 5 cm below the ceiling
    assert gaps.min() == pytest.approx(0.05 - 0.064)  # the tip, 14 mm inside
    assert sc.Transcription(sc.Model(sc.presets.ifac2020(), quadrature_nodes=NODES)).gaps is None


def test_a_start_outside_a_domain_is_refused(transcription):
    with pytest.raises(sc.ParameterError, match="q0"):
        transcription.start([-0.01, 0.0, 0.0])
    with pytest.raises(sc.ParameterError, match="qd0 must be finite"):
        transcription.start([0.064, 0.0, 0.0], [np.nan, 0.0, 0.0])


REACH = np.array([0.02, 0.0, 0.062])
"""A tip position the bellows reach in 0.2 s from rest [m]."""


@pytest.fixture(scope="module")
def reach(model, bellows):
    goal = sc.TipTarget(REACH, tolerance=2e-3)
    return sc.optimize_trajectory(
        model, [0.064, 0.0, 0.0], actuator=bellows, horizon=0.2, intervals=8, targets=[goal],
        effort_weight=1e-3, rest_at_end=True,
    )  # fmt: skip


def test_a_reach_plan_meets_its_target_and_simulate_agrees(model, bellows, reach):
    assert reach.success, reach.message
    assert reach.violation <= 1e-6 and reach.optimality < 1e-6
    assert np.linalg.norm(reach.tip[-1] - REACH) <= 2e-3 + 1e-9
    # within the bounds exactly (IPOPT's relaxation of them put back)
    assert np.all(reach.u >= bellows.lower) and np.all(reach.u <= bellows.upper)
    assert reach.t[-1] == pytest.approx(0.2) and reach.inputs.shape == (9, 3)
    np.testing.assert_allclose(reach.x[-1, 3:6], 0.0, atol=1e-6)  # at rest
    run = reach.simulate()
    assert run.success
    simulated = model.tip_pose(run.q[-1]).position
    # the plan's own steps against simulate's tolerance: within 1 mm at 25 ms steps
    assert np.linalg.norm(simulated - reach.tip[-1]) < 1e-3
    assert np.linalg.norm(simulated - REACH) < 3e-3
    np.testing.assert_array_equal(reach.input_function(0.026), reach.u[1])
    figure = reach.plot(targets=[sc.TipTarget(REACH)], title="reach")
    assert figure.axes[0].get_ylabel() == "tip [mm]"
    matplotlib.pyplot.close(figure)


def test_a_tendon_plan_of_two_segments_meets_its_target_and_simulate_agrees():
    """Tendons on two segments (three per segment, 0.2 to 5 N): the tip 20 mm to the side
    within 2 mm after 0.3 s and at rest, in CasADi's virtual machine (no compile)."""
    segment = sc.Segment(
        rest_length=0.1, mass=0.02, radius=0.01,
        elongation_stiffness=sc.LinearStiffness(1500.0),
        bending_stiffness=sc.LinearStiffness(0.03), damping=[1.5, 3e-4, 3e-4],
    )  # fmt: skip
    robot = sc.Robot(segments=(segment, segment), gravity=np.array([0.0, 0.0, -9.81]))
    model = sc.Model(robot, quadrature_nodes=NODES, compile=False)
    tendons = sc.TendonActuator.three_per_segment(
        distance=0.008, t_max=5.0, t_min=0.2, n_segments=2
    )
    upright = [0.1, 0.0, 0.0, 0.1, 0.0, 0.0]
    goal = model.tip_pose(upright).position + [0.02, 0.0, -0.002]
    plan = sc.optimize_trajectory(
        model, upright, actuator=tendons, horizon=0.3, intervals=4,
        targets=[sc.TipTarget(goal, tolerance=2e-3)], effort_weight=1e-3, rest_at_end=True,
    )  # fmt: skip
    assert plan.success, plan.message
    assert np.linalg.norm(plan.tip[-1] - goal) <= 2e-3 + 1e-9
    assert np.all(plan.u >= tendons.lower) and np.all(plan.u <= tendons.upper)
    run = plan.simulate()
    assert run.success, run.message
    simulated = model.tip_pose(run.q[-1]).position
    assert np.linalg.norm(simulated - plan.tip[-1]) < 1e-3


def test_a_warm_start_converges_at_once(model, bellows, reach):
    goal = sc.TipTarget(REACH, tolerance=2e-3)
    again = sc.optimize_trajectory(
        model, [0.064, 0.0, 0.0], actuator=bellows, horizon=0.2, intervals=8, targets=[goal],
        effort_weight=1e-3, rest_at_end=True, warm_start=reach,
    )  # fmt: skip
    assert again.success
    assert again.iterations < reach.iterations / 2
    assert again.cost == pytest.approx(reach.cost, rel=1e-4)
    # a flat optimum in the smallest pressures: the same within 1e-3 of their range
    np.testing.assert_allclose(again.u, reach.u, rtol=0, atol=1e-3 * 1e5)


def test_an_unreachable_target_is_not_a_success_and_says_what_binds(model, bellows):
    far = sc.TipTarget([0.06, 0.0, 0.02], tolerance=1e-3)  # beyond a quarter turn
    plan = sc.optimize_trajectory(
        model, [0.064, 0.0, 0.0], actuator=bellows, horizon=0.1, intervals=4, targets=[far],
        max_iterations=60,
    )  # fmt: skip
    assert not plan.success
    assert plan.status in (Status.INFEASIBLE, Status.EVALUATION_LIMIT, Status.NOT_CONVERGED)
    assert "the constraint that binds most: target 0 (TipTarget at 0.1 s)" in plan.message


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"method": "euler"}, "method must be one of collocation, shooting"),
        ({"hessian": "bfgs"}, "hessian must be one of exact, limited-memory"),
        ({"hessian": "limited-memory", "method": "shooting"}, "needs method='collocation'"),
        ({"intervals": 0}, "intervals must be an integer >= 1"),
        ({"horizon": -1.0}, "horizon must be > 0"),
        ({"horizon": (0.3, 0.1)}, "0 < shortest < longest"),
        ({"effort_weight": -1.0}, "effort_weight must be >= 0"),
        ({"targets": ["tip"]}, "targets must be TipTarget or ConfigurationTarget"),
        ({"targets": [sc.TipTarget(REACH, time=0.5)]}, "must lie in a fixed horizon"),
        ({"clearance": 0.01}, "clearance needs a model with an environment"),
        ({"tip_bounds": ([0, 0, 0], [0, 1, 1])}, "lower < upper"),
        ({"tip_bounds": ([0, 0, np.nan], [1, 1, 1])}, "lower < upper"),
        ({"tip_bounds": [0.0, 1.0]}, "tip_bounds must be"),
        ({"reference": "circle"}, "reference must be a Reference, got str"),
        ({"reference": sc.Reference.constant(np.zeros(6))}, "reference has 6 coordinates"),
        ({"actuator_state": [1e4, 0, 0]}, "actuator_state is the initial state of a lagging"),
        ({"warm_start": "plan"}, "warm_start must be a TrajectoryPlan"),
        ({"threads": 0}, "threads must be an integer >= 1"),
    ],
)
def test_bad_requests_are_refused_before_any_work(model, bellows, change, match):
    request = {"actuator": bellows, "horizon": 0.2, "intervals": 4, **change}
    with pytest.raises(sc.ParameterError, match=match):
        sc.optimize_trajectory(model, [0.064, 0.0, 0.0], **request)


def test_a_warm_start_of_another_problem_is_refused(model, bellows, reach):
    goal = sc.TipTarget(REACH, tolerance=2e-3)
    request = {"actuator": bellows, "horizon": 0.2, "targets": [goal], "effort_weight": 1e-3,
               "rest_at_end": True, "warm_start": reach}  # fmt: skip
    with pytest.raises(sc.ParameterError, match="a plan of 4 intervals"):
        sc.optimize_trajectory(model, [0.064, 0.0, 0.0], intervals=4, **request)
    with pytest.raises(sc.ParameterError, match="the same problem"):
        sc.optimize_trajectory(model, [0.064, 0.0, 0.0], intervals=8, clearance=None,
                               tip_bounds=([-1, -1, -1], [1, 1, 1]), **request)  # fmt: skip


def test_targets_check_their_fields():
    with pytest.raises(sc.ParameterError, match="TipTarget.position must be 3 finite"):
        sc.TipTarget([0.0, 0.0])
    with pytest.raises(sc.ParameterError, match="TipTarget.tolerance must be > 0"):
        sc.TipTarget(REACH, tolerance=0.0)
    with pytest.raises(sc.ParameterError, match="ConfigurationTarget.weight must be >= 0"):
        sc.ConfigurationTarget([0.064, 0.0, 0.0], weight=-1.0)


def test_a_free_final_time_rates_and_a_reference_are_honoured(model, bellows, capsys):
    """The fastest plan within (0.1, 0.4) s to a configuration, with smooth inputs, a
    reference to follow loosely, and the progress line."""
    goal = sc.ConfigurationTarget([0.065, 15.0, 0.0], tolerance=0.05)
    request = {"actuator": bellows, "intervals": 6, "targets": [goal], "rate_weight": 1e-3,
               "reference": sc.Reference.constant(goal.q), "reference_weight": 1e-3}  # fmt: skip
    fast = sc.optimize_trajectory(
        model, [0.064, 0.0, 0.0], horizon=(0.1, 0.4), time_weight=1.0, progress=True, **request
    )
    assert fast.success, fast.message
    assert fast.horizon == pytest.approx(0.1, rel=1e-6)  # the shortest allowed
    scale = model.robot.coordinate_scale()
    assert np.linalg.norm((fast.x[-1, :3] - goal.q) / scale) <= 0.05 + 1e-6
    assert "optimize_trajectory: iteration 0, cost" in capsys.readouterr().err
    smooth = sc.optimize_trajectory(
        model,
        [0.064, 0.0, 0.0],
        horizon=(0.1, 0.4),
        time_weight=1.0,
        **{**request, "rate_weight": 1.0},
    )
    assert smooth.success, smooth.message
    changes = [np.sum(np.diff(p.u, axis=0) ** 2) for p in (fast, smooth)]
    assert changes[1] < changes[0]  # a larger rate weight, gentler pressures


def test_a_plan_is_the_same_on_any_number_of_threads(model, bellows, reach):
    """The stages' functions mapped over threads give the plan of one thread, bit for bit
    (``reach`` ran on the cores this process may use)."""
    for threads in (1, 3):
        plan = sc.optimize_trajectory(
            model, [0.064, 0.0, 0.0], actuator=bellows, horizon=0.2, intervals=8,
            targets=[sc.TipTarget(REACH, tolerance=2e-3)], effort_weight=1e-3,
            rest_at_end=True, threads=threads,
        )  # fmt: skip
        assert plan.iterations == reach.iterations
        np.testing.assert_array_equal(plan.u, reach.u)
        np.testing.assert_array_equal(plan.x, reach.x)


def test_tip_bounds_hold_where_they_bind(model, bellows, reach):
    lid = 0.0645  # [m]: the reach plan's tip rises above it
    assert reach.tip[:, 2].max() > lid + 1e-4
    box = ([-0.1, -0.1, 0.0], [0.1, 0.1, lid])
    plan = sc.optimize_trajectory(
        model, [0.064, 0.0, 0.0], actuator=bellows, horizon=0.2, intervals=8,
        targets=[sc.TipTarget(REACH, tolerance=2e-3)], effort_weight=1e-3, rest_at_end=True,
        tip_bounds=box,
    )  # fmt: skip
    assert plan.success, plan.message
    assert plan.tip[:, 2].max() <= lid + 1e-6
    assert plan.binding == "tip bounds"


def test_a_plan_keeps_its_clearance_from_an_obstacle(bellows, reach):
    ceiling = sc.Plane([0.0, 0.0, 0.0645], [0.0, 0.0, -1.0])  # 0.5 mm above the tip at rest
    environment = sc.Environment([ceiling], sc.ContactLaw(1e4))
    # not compiled: planned in CasADi's virtual machine (the compiled equations are the
    # symbolic ones, test_the_compiled_collocation_is_the_symbolic_one_to_second_derivatives)
    model = sc.Model(
        sc.presets.ifac2020(), environment=environment, quadrature_nodes=NODES, compile=False
    )
    tr = sc.Transcription(model, bellows)
    # the plan in free space passes through where the ceiling is
    assert min(np.array(tr.gaps(x, tr.parameters))[1:].min() for x in reach.x) < -1e-4
    kept = sc.optimize_trajectory(
        model, [0.064, 0.0, 0.0], actuator=bellows, horizon=0.2, intervals=8,
        targets=[sc.TipTarget(REACH, tolerance=2e-3)], effort_weight=1e-3, rest_at_end=True,
        clearance=0.0,
    )  # fmt: skip
    assert kept.success, kept.message
    kept_gaps = [np.array(tr.gaps(x, tr.parameters))[1:].min() for x in kept.x]
    assert min(kept_gaps) >= -1e-6
    assert np.linalg.norm(kept.tip[-1] - REACH) <= 2e-3 + 1e-9


def test_a_lagging_actuator_is_planned_by_its_commands_and_settles(model):
    lagging = sc.PneumaticActuator.three_bellows(
        distance=0.01, area=2e-5, p_max=1e5, time_constant=0.02
    )
    plan = sc.optimize_trajectory(
        model, [0.064, 0.0, 0.0], actuator=lagging, horizon=0.2, intervals=8,
        targets=[sc.TipTarget(REACH, tolerance=2e-3)], effort_weight=1e-3, rest_at_end=True,
        hessian="limited-memory", tolerance=1e-7,
    )  # fmt: skip
    assert plan.success, plan.message
    assert plan.x.shape == (9, model.n_state + 3)
    np.testing.assert_allclose(plan.x[-1, model.n_state :], plan.u[-1], rtol=1e-6, atol=1e-3)
    run = plan.simulate()
    assert run.success
    simulated = model.tip_pose(run.q[-1]).position
    assert np.linalg.norm(simulated - plan.tip[-1]) < 1e-3


# -- nonlinear model-predictive control ---------------------------------------------------
# the circle of docs/control.md, which these pressures hold; the model in CasADi's virtual
# machine: a compile of these pressures' second derivatives would cost more than the runs
CIRCLE = {"center": (0.02, 0.0, 0.065), "radius": 0.01, "period": 2.0}
PRESSURES = {"distance": 0.012, "area": 2e-4, "p_max": 6e4}


@pytest.fixture(scope="module")
def circle():
    from softcurve.control.references import tip_circle

    return tip_circle(**CIRCLE)


@pytest.fixture(scope="module")
def interpreted():
    return sc.Model(sc.presets.ifac2020(), quadrature_nodes=NODES, compile=False)


@pytest.fixture(scope="module")
def pressures():
    return sc.PneumaticActuator.three_bellows(**PRESSURES)


def tip_errors(model, run, reference) -> np.ndarray:
    """Distances [m] of the simulated tip from the reference's at the outputs."""
    goal = np.array([model.tip_pose(reference(t).q).position for t in run.t])
    return np.linalg.norm(run.tip - goal, axis=1)


def test_the_predictive_controllers_first_inputs_are_the_plans(interpreted, pressures, circle):
    """Its first sample solves optimize_trajectory's problem from the measured state."""
    model, start = interpreted, circle(0.0)
    mpc = sc.PredictiveController(model, pressures, circle, horizon=0.1, intervals=5,
                                  rate_weight=0.0, effort_weight=1e-4)  # fmt: skip
    first = mpc(0.0, start.q, start.qd, np.zeros(model.n_creep))
    plan = sc.optimize_trajectory(model, start.q, start.qd, actuator=pressures, horizon=0.1,
                                  intervals=5, reference=circle, effort_weight=1e-4)  # fmt: skip
    assert plan.success and mpc.log[0]["status"] is Status.SUCCESS
    np.testing.assert_allclose(first, plan.u[0], rtol=0, atol=1e-6 * PRESSURES["p_max"])
    assert mpc.log[0]["cost"] == pytest.approx(plan.cost, rel=1e-6)


def test_the_predictive_controller_tracks_a_circle_on_its_budget(interpreted, pressures, circle):
    model, start = interpreted, circle(0.0)
    mpc = sc.PredictiveController(model, pressures, circle, horizon=0.1, intervals=5,
                                  rate_weight=1e-6, iterations=8)  # fmt: skip
    run = sc.simulate(model, start.q, start.qd, actuator=pressures, controller=mpc,
                      t_final=0.3, dt=0.02)  # fmt: skip
    assert run.success, run.message
    assert len(mpc.log) == 15 and np.all(np.isfinite(mpc.history("solve_time")))
    # every solve after the first starts from the plan moved on and converges on its budget
    assert all(entry["status"] is Status.SUCCESS for entry in mpc.log)
    assert tip_errors(model, run, circle).max() < 0.2e-3  # [m], a 10 mm circle
    mpc.reset()
    assert mpc.log == [] and mpc(0.0, start.q, start.qd).shape == (3,)


def test_the_compiled_gauss_newton_controller_is_the_interpreted_one(
    model, interpreted, pressures, circle
):
    """On the compiled model the Gauss-Newton controller runs on the compiled stage
    Jacobians and right-hand side (built by IPOPT's interface with nothing asked to
    differentiate them); its samples are those of the same model in CasADi's virtual
    machine."""
    start, logs = circle(0.0), []
    for robot in (model, interpreted):
        mpc = sc.PredictiveController(robot, pressures, circle, horizon=0.1, intervals=5,
                                      rate_weight=1e-6, iterations=8)  # fmt: skip
        run = sc.simulate(robot, start.q, start.qd, actuator=pressures, controller=mpc,
                          t_final=0.04, dt=0.02)  # fmt: skip
        assert run.success, run.message
        logs.append(mpc.history("inputs"))
    np.testing.assert_allclose(*logs, rtol=0, atol=1e-6 * PRESSURES["p_max"])


def test_a_sample_that_cannot_be_met_is_logged_and_its_inputs_stay_in_bounds(
    interpreted, pressures, circle
):
    """Tip bounds 20 mm below the tip at rest cannot be met within a step: no sample is
    logged SUCCESS (IPOPT runs out of its iterations, the first's 300 and the next's 5)
    and each logs its violation; the inputs applied are finite and within the actuator's
    bounds."""
    model, start = interpreted, circle(0.0)
    tip = model.tip_pose(start.q).position
    box = (tip - [0.05, 0.05, 0.05], tip + [0.05, 0.05, -0.02])
    mpc = sc.PredictiveController(model, pressures, circle, horizon=0.1, intervals=5,
                                  tip_bounds=box, iterations=5)  # fmt: skip
    run = sc.simulate(model, start.q, start.qd, actuator=pressures, controller=mpc,
                      t_final=0.04, dt=0.02)  # fmt: skip
    assert run.success, run.message
    assert [entry["status"] for entry in mpc.log] == [Status.EVALUATION_LIMIT] * 2
    assert mpc.history("iterations").tolist() == [sc.control.PLAN_ITERATIONS, 5]
    assert np.all(mpc.history("violation") > 1e-3)
    inputs = mpc.history("inputs")
    assert np.all(np.isfinite(inputs))
    assert np.all(inputs >= pressures.lower) and np.all(inputs <= pressures.upper)


def test_the_gauss_newton_hessian_reaches_the_exact_hessians_plans(interpreted, pressures, circle):
    """The cost's Hessian alone (the constraints' curvature left out) converges, sample
    after sample, to the plans the exact Hessian converges to."""
    model, start = interpreted, circle(0.0)
    logs = {}
    for hessian in sc.control.PREDICTIVE_HESSIANS:
        mpc = sc.PredictiveController(model, pressures, circle, horizon=0.1, intervals=5,
                                      rate_weight=1e-6, hessian=hessian, iterations=50)  # fmt: skip
        run = sc.simulate(model, start.q, start.qd, actuator=pressures, controller=mpc,
                          t_final=0.06, dt=0.02)  # fmt: skip
        assert run.success, run.message
        assert all(entry["status"] is Status.SUCCESS for entry in mpc.log)
        logs[hessian] = mpc.history("inputs")
    np.testing.assert_allclose(*logs.values(), rtol=0, atol=1e-5 * PRESSURES["p_max"])


def test_the_gauss_newton_hessian_is_the_costs_own(interpreted, pressures, circle):
    """The Hessian the controller gives IPOPT by default: the cost's exact Hessian (upper
    triangle), the same at every point and for every multiplier of the constraints."""
    from softcurve.control import _problem

    start = circle(0.0)
    mpc = sc.PredictiveController(interpreted, pressures, circle, horizon=0.1, intervals=3)
    tr = mpc.transcription
    problem = _problem.Problem.build(
        tr, tr.start(start.q, start.qd), mpc.request, rest_at_end=False,
        method="collocation", hessian="gauss-newton", previous_inputs=True,
    )  # fmt: skip
    hessian = problem.cost_hessian
    w, p, f = problem.nlp["x"], problem.nlp["p"], problem.nlp["f"]
    exact = ca.Function("exact", [w, p], [ca.hessian(f, w)[0]])
    rng = np.random.default_rng(3)
    n_w, n_g = problem.sizes
    parameters = problem.parameters(0.05, pressures.rest_inputs())
    values = []
    for _ in range(2):
        point = rng.normal(size=n_w)
        got = np.array(ca.DM(hessian(point, parameters, 2.0, rng.normal(size=n_g))))
        np.testing.assert_allclose(got, np.triu(2.0 * np.array(exact(point, parameters))),
                                   rtol=1e-12, atol=1e-12)  # fmt: skip
        values.append(got)
    np.testing.assert_array_equal(values[0], values[1])
    assert np.any(values[0] != 0)


def test_the_predictive_controller_follows_the_lag_of_its_commands(interpreted, circle):
    """A lagging actuator's inputs, which the controller does not measure, are its model's
    response to the commands it sent: the plant with that lag settles onto the circle, a
    plant whose inputs follow the commands at once (the model wrong) stays off it."""
    lagging = sc.PneumaticActuator.three_bellows(**PRESSURES, time_constant=0.02)
    start, errors = circle(0.0), {}
    at_once = sc.PneumaticActuator.three_bellows(**PRESSURES)
    for name, plant in (("modelled", lagging), ("not modelled", at_once)):
        mpc = sc.PredictiveController(interpreted, lagging, circle, horizon=0.1, intervals=5,
                                      rate_weight=1e-6, iterations=8)  # fmt: skip
        run = sc.simulate(interpreted, start.q, start.qd, actuator=plant, controller=mpc,
                          t_final=0.2, dt=0.02)  # fmt: skip
        assert run.success, run.message
        errors[name] = tip_errors(interpreted, run, circle)
    # the start (at rest, no pressure, on the circle) costs mm; modelled, it decays
    modelled, wrong = errors["modelled"], errors["not modelled"]
    assert modelled[-1] < modelled[1] / 4 and modelled[-1] < wrong[-1] / 4, errors


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"sample_time": 0.03}, "whole number of the horizon's steps"),
        ({"hessian": "newton"}, "hessian must be one of"),
        ({"iterations": 0}, "iterations must be an integer"),
        ({"horizon": (0.05, 0.1)}, "horizon must be a time"),
        ({"rate_weight": -1.0}, "rate_weight must be >= 0"),
        ({"clearance": 1e-3}, "clearance needs a model with an environment"),
        ({"sample_time": 0.12}, "at most the horizon"),
        ({"reference": None}, "reference must be a Reference"),
        ({"actuator_state": [0.0, 0.0, 0.0]}, "actuator_state is the initial state of a lag"),
    ],
)
def test_bad_predictive_controllers_are_refused(model, bellows, circle, change, match):
    request = {"horizon": 0.1, "intervals": 5, "reference": circle, **change}
    with pytest.raises(sc.ParameterError, match=match):
        sc.PredictiveController(model, bellows, **request)


@pytest.mark.parametrize("method", sc.control.PLAN_METHODS)
def test_a_receding_horizons_warm_start_is_the_plan_moved_on(model, bellows, method):
    """Every unknown and multiplier coded by its place: each block along the horizon moves
    on by the steps, its last step repeated; the others stay."""
    from softcurve.control import _problem

    tr, K, steps = sc.Transcription(model, bellows), 4, 2
    n_x, n_u = tr.n_x, tr.n_u
    request = _problem.checked_request(
        model, horizon=0.1, intervals=K, targets=[sc.TipTarget(REACH, tolerance=1e-3)],
        reference=None,
        weights={"reference_weight": 0.0, "effort_weight": 1e-3, "rate_weight": 1e-3,
                 "time_weight": 0.0},
        clearance=None, tip_bounds=None,
        tolerance=1e-8, max_iterations=1,
    )  # fmt: skip
    problem = _problem.Problem.build(
        tr, tr.start([0.064, 0.0, 0.0]), request, rest_at_end=True, method=method,
        hessian="limited-memory" if method == "collocation" else "exact", previous_inputs=True,
    )  # fmt: skip
    n_w, n_g = problem.sizes
    values, lam_x, lam_g = np.arange(n_w) + 0.5, -np.arange(n_w) - 0.5, np.arange(n_g) + 0.5
    moved, (moved_x, moved_g) = problem.shifted(values, (lam_x, lam_g), steps)
    np.testing.assert_array_equal(moved_x, -moved)
    nodes = values[: n_x * (K + 1)].reshape(K + 1, n_x)
    expected = np.vstack([nodes[steps:], nodes[-1:], nodes[-1:]])
    np.testing.assert_array_equal(moved[: n_x * (K + 1)].reshape(K + 1, n_x), expected)
    inputs = values[problem.u_rows].reshape(K, n_u)
    expected = np.vstack([inputs[steps:], inputs[-1:], inputs[-1:]])
    np.testing.assert_array_equal(moved[problem.u_rows].reshape(K, n_u), expected)
    if method == "collocation":
        stages = values[problem.u_rows.stop :].reshape(3 * K, n_x)
        expected = np.vstack([stages[3 * steps :], stages[-3:], stages[-3:]])
        np.testing.assert_array_equal(moved[problem.u_rows.stop :].reshape(3 * K, n_x), expected)
    along = {"dynamics", "model or actuator domain"}  # this problem's groups along the steps
    for first, rows, columns in problem.blocks:
        block = lam_g[first : first + rows * columns].reshape(columns, rows)
        got = moved_g[first : first + rows * columns].reshape(columns, rows)
        if problem.groups[first] in along:
            per_step = columns // K
            repeated = [block[-per_step:]] * steps
            np.testing.assert_array_equal(got, np.vstack([block[steps * per_step :], *repeated]))
        else:  # the target's and the rest's rows
            assert problem.groups[first].startswith(("target", "rest at the end"))
            np.testing.assert_array_equal(got, block)
