"""Equilibria, their classification, rings of equilibria, linearization, quasi-static maps."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import scipy.optimize

import softcurve as sc
from softcurve import ParameterError, PneumaticActuator
from softcurve.analysis import loads as loads_module
from softcurve.analysis.inverse_statics import inverse_statics
from softcurve.analysis.loads import StaticLoad, rest_configuration, static_function
from softcurve.analysis.quasistatic import input_sweep
from softcurve.analysis.solver import solve_equilibria
from softcurve.analysis.statics import equilibria, equilibrium, linearize, rotate_about_axis
from softcurve.base.status import Status
from softcurve.cli import main
from softcurve.compiled import _build as build_module
from softcurve.compiled import compile_function, load_function
from softcurve.simulation._simulate import simulate

from .conftest import assert_close

BUCKLING_GRAVITY = np.array([0.0, 0.0, -150.0])  # about 15 g: the upright robot buckles


def actuator():
    return PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)


def potential_force(model, q, gravity_sign=1.0):
    """Compiled ``N(q)`` with the model's gravity scaled by ``gravity_sign`` (it is linear)."""
    return model.elastic_force(q) + gravity_sign * model.gravity_force(q)


def hessian_by_differences(model, q, extra=None, gravity_sign=1.0):
    """Central differences of the compiled N(q) (- extra generalized force), symmetrised."""
    extra = extra or (lambda q: 0.0)
    scale = np.array([q[0], 1 / q[0], 1 / q[0]])
    columns = []
    for i in range(3):
        h = np.zeros(3)
        h[i] = 1e-6 * scale[i]
        f = lambda x: potential_force(model, x, gravity_sign) - extra(x)  # noqa: E731
        columns.append((f(q + h) - f(q - h)) / (2 * h[i]))
    k = np.array(columns).T
    return 0.5 * (k + k.T), scale


def signs_of_hessian(model, q, gravity_sign=1.0):
    k, scale = hessian_by_differences(model, q, gravity_sign=gravity_sign)
    return np.sign(np.linalg.eigvalsh(scale[:, None] * k * scale[None, :]))


@pytest.fixture(scope="module")
def buckled_model():
    return sc.Model(sc.presets.ifac2020().replace(gravity=BUCKLING_GRAVITY))


def test_straight_robot_is_the_only_equilibrium_upright_and_hanging(paper_model):
    segment = paper_model.robot.segments[0]
    weight = segment.mass * 9.81
    for sign in (-1.0, 1.0):  # upright, hanging
        table = equilibria(paper_model, gravity=[0, 0, sign * 9.81], starts=24)
        assert table.success and len(table) == 1, table.table()
        e = table[0]
        assert e.stability == "stable" and e.continuum is None
        assert np.all(e.q[1:] == 0.0)
        # closed form of the straight equilibrium: k_e(eps) eps = -/+ m g / 2
        eps = e.q[0] - segment.rest_length
        assert_close(segment.elongation_stiffness.force(eps), sign * weight / 2, rtol=1e-10)
        n = potential_force(paper_model, e.q, -sign)
        assert_close(n, np.zeros(3), atol=1e-12 * weight)
        assert np.all(signs_of_hessian(paper_model, e.q, -sign) > 0)


def test_buckled_upright_robot_has_a_stable_ring_and_a_saddle(buckled_model):
    table = equilibria(buckled_model, starts=24)
    assert [(e.stability, e.continuum) for e in table] == [("stable", "ring"), ("saddle", None)]
    ring, straight = table
    assert ring.q[2] == 0.0 and ring.q[1] > 0  # representative bends toward +x
    assert 2 <= table.converged_starts <= table.starts
    for angle in (0.0, 1.0, 2.5, 4.0):  # every rotated member is an equilibrium
        member = rotate_about_axis(ring.q, angle)
        assert_close(buckled_model.potential_force(member), np.zeros(3), atol=1e-10 * 0.05 * 150)
    # classification agrees with the signs of the finite-difference Hessian
    signs = signs_of_hessian(buckled_model, ring.q)
    assert signs[0] > 0 and signs[-1] > 0  # the middle one is the ring direction (zero)
    k, scale = hessian_by_differences(buckled_model, ring.q)
    eig = np.linalg.eigvalsh(scale[:, None] * k * scale[None, :])
    assert np.min(np.abs(eig)) < 1e-6 * np.max(np.abs(eig))
    assert sorted(signs_of_hessian(buckled_model, straight.q)) == [-1, -1, 1]
    assert straight.unstable_directions == 2


def test_perturbed_simulations_confirm_the_classification(paper_model, buckled_model):
    def final_curvature(model, q0, t_final):
        run = simulate(model, q0, np.zeros(3), t_final=t_final, dt=1e-2)
        assert run.success, run.message
        return np.hypot(run.q[:, 1], run.q[:, 2])

    ring, straight = equilibria(buckled_model, starts=8)
    kappa = final_curvature(buckled_model, straight.q + [0, 0.05, 0.0], 1.0)
    assert kappa.max() > 0.5 * ring.curvature[0]  # the saddle is left
    kappa = final_curvature(buckled_model, ring.q + [0, 0.3, 0.3], 1.0)
    assert np.max(np.abs(kappa - ring.curvature[0])) < 1.5  # stays near the stable ring
    stable = equilibria(paper_model, starts=1)[0]
    kappa = final_curvature(paper_model, stable.q + [0, 0.5, 0.0], 1.0)
    assert kappa.max() < 0.6


def test_equilibrium_under_pressures_and_tip_force_balances_the_loads(paper_model):
    act, p, f = actuator(), np.array([2e4, 0.0, 5e3]), np.array([0.1, 0.2, -0.3])
    e = equilibrium(paper_model, [0.064, 0, 0], actuator=act, inputs=p, tip_force=f)
    assert e.success and e.stability == "stable"
    j = paper_model.jacobian(e.q, 1.0)
    loads = act.input_matrix(e.q) @ p + j[:3].T @ f

    def j_of(q):
        return paper_model.jacobian(q, 1.0)[:3].T

    assert_close(paper_model.potential_force(e.q), loads, rtol=1e-10, scale=np.abs(loads).max())
    assert_close(e.tip_position, paper_model.tip_pose(e.q).position, rtol=1e-13)
    # a constant force and constant pressures are conservative: K is the FD Hessian
    k, _ = hessian_by_differences(paper_model, e.q, lambda q: act.input_matrix(q) @ p + j_of(q) @ f)
    lin = linearize(paper_model, e.q, actuator=act, inputs=p, tip_force=f)
    assert_close(lin.stiffness, k, rtol=1e-6, scale=np.abs(k).max())


def test_tip_moment_is_balanced_and_flagged_non_conservative(paper_model):
    m = np.array([0.0, 2e-3, 0.0])
    e = equilibrium(paper_model, [0.064, 0, 0], tip_moment=m)
    assert e.success and "not conservative" in e.message
    j = paper_model.jacobian(e.q, 1.0)
    assert_close(paper_model.potential_force(e.q), j[3:].T @ m, rtol=1e-10, scale=1e-3)
    assert e.q[1] > 0  # a moment about +y bends the tip toward +x


def test_linearization_matches_finite_differences_of_the_rhs(paper_model, rng):
    act, p = actuator(), np.array([2e4, 0.0, 5e3])
    f, m = np.array([0.1, 0.2, -0.3]), np.array([1e-3, 0.0, 2e-3])
    x = np.concatenate([[0.066, 12.0, -9.0], rng.normal(size=3) * [0.01, 10, 10], [1e-3] * 3])
    lin = linearize(
        paper_model, x[:3], x[3:6], x[6:], actuator=act, inputs=p, tip_force=f,
        tip_moment=m, wrt="actuator",
    )  # fmt: skip

    def rhs(x, dp=None):
        q = x[:3]
        tau = (
            act.input_matrix(q) @ (p if dp is None else p + dp)
            + paper_model.jacobian(q, 1.0).T @ np.r_[f, m]
        )
        return np.array(paper_model.state_derivative(x, tau))  # a copy, never a buffer view

    steps = 1e-6 * (np.abs(x) + 1e-3)
    a = np.column_stack(
        [(rhs(x + h * e) - rhs(x - h * e)) / (2 * h) for h, e in zip(steps, np.eye(9), strict=True)]
    )
    assert_close(lin.A, a, rtol=1e-6, atol=1e-7 * np.abs(a).max())
    b = np.column_stack([(rhs(x, 10.0 * e) - rhs(x, -10.0 * e)) / 20.0 for e in np.eye(3)])
    assert_close(lin.B, b, rtol=1e-6, atol=1e-8 * np.abs(b).max())


def test_undamped_eigenvalues_are_the_natural_frequencies(conservative_model):
    e = equilibria(conservative_model, starts=1)[0]
    lin = linearize(conservative_model, e.q)
    # the creep states of this model exert no force: their eigenvalues are real, apart
    oscillatory = lin.eigenvalues[lin.eigenvalues.imag != 0]
    assert oscillatory.size == 6
    omega = np.sort(np.abs(oscillatory.imag))[::2]
    assert_close(omega, 2 * np.pi * np.sort(lin.frequencies), rtol=1e-8)
    assert_close(np.abs(oscillatory.real), np.zeros(6), atol=1e-8 * omega.max())
    assert_close(lin.modes.T @ lin.mass_matrix @ lin.modes, np.eye(3), atol=1e-12)
    assert not lin.asymptotically_stable
    damped = linearize(sc.Model(sc.presets.ifac2020()), e.q)
    assert damped.asymptotically_stable and np.all(damped.damping_ratios > 0)


def test_equilibria_are_distinct_and_reproducible(buckled_model):
    a = equilibria(buckled_model, starts=16, seed=3)
    b = equilibria(buckled_model, starts=16, seed=3)
    assert [e.q.tolist() for e in a] == [e.q.tolist() for e in b]
    assert a.evaluations <= 16 * 200, "root-finder budget per start exceeded"
    assert [e.potential for e in a] == sorted(e.potential for e in a)


def test_bad_inputs(paper_model):
    with pytest.raises(ParameterError, match="inputs and actuator must be given together"):
        equilibria(paper_model, inputs=[0, 0, 0])
    with pytest.raises(ParameterError, match=r"bounds must have shape \(3, 2\)"):
        equilibria(paper_model, bounds=[[0, 1]])
    with pytest.raises(ParameterError, match="starts must be an integer >= 1"):
        equilibria(paper_model, starts=0)
    with pytest.raises(ParameterError, match="outside its bounds"):
        equilibrium(paper_model, [0.064, 0, 0], actuator=actuator(), inputs=[-1.0, 0, 0])
    with pytest.raises(ParameterError, match="wrt must be one of"):
        linearize(paper_model, [0.064, 0, 0], wrt="volts")
    with pytest.raises(ParameterError, match="needs an actuator"):
        linearize(paper_model, [0.064, 0, 0], wrt="actuator")


def test_no_equilibrium_in_region_reports_status(paper_model):
    # a box of strongly bent shapes holds no equilibrium of the upright robot
    bounds = [[0.06, 0.07], [40.0, 45.0], [-1.0, 1.0]]
    table = equilibria(paper_model, bounds=bounds, starts=4)
    assert table.status is Status.NOT_CONVERGED and not table.success and len(table) == 0
    assert "0 distinct equilibria" in table.message
    assert table.evaluations >= table.starts  # every start ran the solver
    # the only equilibrium (the straight robot) lies outside the box
    upright = equilibria(paper_model, starts=1)[0]
    inside = (upright.q >= np.array(bounds)[:, 0]) & (upright.q <= np.array(bounds)[:, 1])
    assert upright.success and not inside.all()


def test_bifurcation_point_is_degenerate(paper_model):
    """The upright robot buckles where the bending eigenvalue crosses zero."""

    def bending_eigenvalue(g):
        return equilibrium(paper_model, [0.0644, 0, 0], gravity=[0, 0, -g]).eigenvalues[0]

    critical = scipy.optimize.brentq(bending_eigenvalue, 20.0, 140.0, xtol=1e-12)
    assert 90.0 < critical < 96.0  # 93.13 m/s^2 (docs/statics.md)
    at = equilibrium(paper_model, [0.0644, 0, 0], gravity=[0, 0, -critical])
    assert at.stability == "degenerate"
    below = equilibrium(paper_model, [0.0644, 0, 0], gravity=[0, 0, -0.99 * critical])
    above = equilibrium(paper_model, [0.0644, 0, 0], gravity=[0, 0, -1.01 * critical])
    assert (below.stability, above.stability) == ("stable", "saddle")


def test_input_sweep_follows_a_balanced_branch(paper_model):
    act = actuator()
    path = np.zeros((9, 3))
    path[:, 0] = np.linspace(0.0, 6e4, 9)
    sweep = input_sweep(paper_model, act, path)
    assert sweep.success and all(s == "stable" for s in sweep.stability)
    assert sweep.converged.all()
    for q, p in zip(sweep.q, sweep.inputs, strict=True):
        loads = act.input_matrix(q) @ p
        assert_close(
            paper_model.potential_force(q), loads, rtol=1e-9, scale=1e-3 + np.abs(loads).max()
        )
    # bellow 1 at azimuth 0 bends the robot toward -x, more with more pressure
    assert np.all(np.diff(sweep.q[:, 1]) < 0) and np.all(sweep.q[:, 2] == 0)


def test_inverse_statics_reaches_reachable_targets_and_saturates_otherwise(paper_model):
    act = actuator()
    reachable = inverse_statics(paper_model, act, [0.02, 0.01, 0.065])
    assert reachable.success and reachable.distance < 1e-9
    assert reachable.stability == "stable" and not reachable.saturated.any()
    assert_close(paper_model.tip_pose(reachable.q).position, [0.02, 0.01, 0.065], atol=1e-9)
    far = inverse_statics(paper_model, act, [0.1, 0.0, 0.0])
    assert far.distance > 0.03 and far.saturated.any()
    assert far.status is Status.INFEASIBLE and "out of reach" in far.message
    assert np.all(far.inputs >= act.lower) and np.all(far.inputs <= act.upper)
    with pytest.raises(ParameterError, match="chooses the actuator inputs"):
        inverse_statics(paper_model, act, [0, 0, 0.07], inputs=[0, 0, 0])


def test_constant_pressure_map_equilibrium(paper_model):
    from softcurve import ConstantPressureMap

    fit = ConstantPressureMap.authors_fit(p_max=1e5)
    p = np.array([4e4, 0.0, 1e4])
    e = equilibrium(paper_model, [0.0644, 0, 0], actuator=fit, inputs=p)
    assert e.success and e.stability == "stable"
    assert_close(paper_model.potential_force(e.q), fit.constant @ p, rtol=1e-9, scale=1e-2)
    sweep = input_sweep(paper_model, fit, np.outer(np.linspace(0, 1e5, 5), [1.0, 0.0, 0.0]))
    assert sweep.success
    table = equilibria(paper_model, starts=2, actuator=fit, inputs=p)
    assert len(table) == 1


def test_constant_inputs_in_simulate_settle_at_the_static_equilibrium(paper_model):
    act, p = actuator(), np.array([2.5e4, 0.0, 1e4])
    run = simulate(
        paper_model, [0.0644, 0, 0], np.zeros(3), actuator=act, inputs=p, t_final=3.0, dt=1e-3
    )
    assert run.success, run.message
    static = equilibrium(paper_model, [0.0644, 0, 0], actuator=act, inputs=p)
    assert_close(run.q[-1], static.q, rtol=1e-5, scale=np.abs(static.q))
    with pytest.raises(
        ParameterError, match=r"pressures\[1\] = -1.0 Pa is outside .*\(at t = 0 s\)"
    ):
        simulate(
            paper_model,
            [0.0644, 0, 0],
            np.zeros(3),
            actuator=act,
            inputs=lambda t, state: [0, -1.0, 0],
            t_final=0.01,
        )


def test_cli_equilibria_prints_the_table(capsys):
    assert main(["equilibria", "--hanging", "--starts", "4", "--modes"]) == 0
    out = capsys.readouterr().out
    assert "stable" in out and "natural frequencies" in out
    assert main(["equilibria", "--gravity", "0", "0", "-150", "--starts", "8"]) == 0
    out = capsys.readouterr().out
    assert "ring" in out and "saddle" in out
    assert main(["equilibria", "--pressures", "1e9", "0", "0"]) == 2  # beyond p_max
    assert "outside its bounds" in capsys.readouterr().err


def test_initial_guesses_outside_the_domain_are_refused(paper_model):
    """Issue 11: the one configuration check (Robot.check_configuration) on statics."""
    with pytest.raises(ParameterError, match=r"q0: lengths l .* l of segment 1 \(q0\[0\]\)"):
        equilibrium(paper_model, [-0.01, 0.0, 0.0])
    with pytest.raises(ParameterError, match=r"bounds\[:, 0\] \(lower lengths\): lengths l"):
        equilibria(paper_model, bounds=[[0.0, 0.07], [-1.0, 1.0], [-1.0, 1.0]])
    with pytest.raises(ParameterError, match=r"bounds\[:, 1\] \(upper lengths\): lengths l"):
        equilibria(paper_model, bounds=[[0.06, 1.0], [-1.0, 1.0], [-1.0, 1.0]])


def test_linearize_refuses_a_configuration_outside_the_domain(paper_model):
    with pytest.raises(ParameterError, match=r"q: lengths l must be in the model's domain"):
        linearize(paper_model, [-0.01, 0.0, 0.0])


def _cubic_system(b):
    """r(q) = A q + q^3 - b per column, with its Jacobian: a batch for the solver."""
    a = np.array([[3.0, 1.0], [1.0, 2.0]])

    def batch_residual(q):
        return a @ q + q**3 - b

    def batch_system(q):
        jacobians = np.stack([a + np.diag(3 * column**2) for column in q.T])
        return batch_residual(q), jacobians

    return batch_system, batch_residual


@pytest.mark.parametrize("quality", ["near", "poor"])
def test_chord_steps_reach_newtons_solutions(quality):
    """Chord steps with Jacobians near the solutions' need no Jacobian at all; with poor
    ones (10 times too stiff: a contraction of 0.9 per step) Newton's method takes over.
    Either way the solutions are Newton's, to the tolerance."""
    rng = np.random.default_rng(4)
    b = rng.normal(size=(2, 50))
    batch_system, batch_residual = _cubic_system(b)
    counted = {"jacobians": 0}

    def counting_system(q):
        counted["jacobians"] += 1
        return batch_system(q)

    options = dict(scale=np.ones(2), reference=np.ones(2), tol=1e-12, max_evaluations=100)
    newton = solve_equilibria(batch_system, None, np.zeros((2, 50)), **options)
    solutions = np.column_stack([root.q for root in newton])
    start = solutions + 1e-3 * rng.normal(size=solutions.shape)
    near = batch_system(solutions + 1e-2)[1]
    jacobians = near if quality == "near" else 10 * near
    roots = solve_equilibria(
        counting_system, None, start, jacobians=jacobians, batch_residual=batch_residual,
        **options,
    )  # fmt: skip
    assert all(root.converged for root in roots)
    found = np.column_stack([root.q for root in roots])
    np.testing.assert_allclose(found, solutions, rtol=0, atol=1e-11)
    assert (counted["jacobians"] == 0) == (quality == "near")


def test_the_inverse_statics_figure_gives_each_quantity_its_axis_and_says_what_it_marks(
    paper_model,
):
    """examples/inverse_statics.py's figure (docs/figures/inverse_statics.png): before, the
    curvature [1/m] and the elongation [mm] shared one unlabelled axis and the red circles
    were explained nowhere."""
    import importlib.util
    from pathlib import Path

    import matplotlib.pyplot as plt

    path = Path(__file__).resolve().parents[1] / "examples" / "inverse_statics.py"
    spec = importlib.util.spec_from_file_location("inverse_statics_example", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    actuator = PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    sweep = input_sweep(paper_model, actuator, np.array([[0.0, 0, 0], [3e4, 0, 0], [6e4, 0, 0]]))
    results = [
        inverse_statics(paper_model, actuator, np.array(target))
        for target in ([0.015, 0.0, 0.066], [0.07, 0.0, 0.05])  # reached, beyond reach
    ]
    assert [r.success for r in results] == [True, False]
    figure = example.draw(paper_model, sweep, results)
    labels = sorted(a.get_ylabel() for a in figure.axes)
    assert labels == [
        "curvature |kappa| [1/m]", "elongation l - l0 [mm]", "tip position [mm]", "z [mm]"
    ]  # fmt: skip
    (statics,) = [a for a in figure.axes if a.get_ylabel() == "z [mm]"]
    legend = [t.get_text() for t in statics.get_legend().get_texts()]
    assert "closest tip (saturated pressures)" in legend and "target beyond reach" in legend
    red = [line for line in statics.lines if line.get_color() == "C3"]
    assert len(red) == 1  # the one target beyond reach
    plt.close(figure)


# -- the static balance, compiled ---------------------------------------------------------
def _balance_arguments(rng, model, act):
    """A seeded random state inside the domain and loads of every kind for ``act``."""
    q = rest_configuration(model.robot) + rng.uniform(-1, 1, model.n) * np.tile(
        [2e-3, 8.0, 8.0], model.robot.n_segments
    )
    load = StaticLoad(
        model,
        tau=rng.normal(size=model.n) * 1e-2,
        actuator=act,
        inputs=rng.uniform(act.lower, act.upper),
        tip_force=rng.normal(size=3) * 0.1,
        tip_moment=rng.normal(size=3) * 1e-3,
        gravity=rng.normal(size=3) * 5.0,
    )
    return q, load.arguments()


@pytest.mark.parametrize("segments", [1, 3])
def test_the_compiled_static_balance_is_the_virtual_machines(segments, rng):
    """The balance in C (as equilibria evaluate it once it has paid for its compile)
    equals CasADi's virtual machine at a seeded random state with an actuator and
    every load, and its ``K`` (the Hessian of the gravity's and the tip force's
    potential) is the Jacobian of its residual. Three segments leave the tip moment's
    term out (a short compile: the function equilibria without a moment take)."""
    robot = sc.presets.ifac2020().with_segments(segments)
    model = sc.Model(robot, quadrature_nodes=4, compile=False)
    act = PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4, n_segments=segments)
    q, arguments = _balance_arguments(rng, model, act)
    moment = segments == 1
    function = static_function(model, act, tip_moment=moment)
    compiled = compile_function(function, load=load_function)
    assert not isinstance(compiled, ca.Function)  # C, called through ctypes
    expected = [np.array(v, dtype=np.float64) for v in function(q, *arguments)]
    outputs = compiled(q, *arguments)
    for name, value, reference in zip(function.name_out(), outputs, expected, strict=True):
        reference = reference.ravel() if reference.shape[1] == 1 else reference
        assert_close(value, reference, rtol=1e-12, scale=np.abs(reference).max(), what=name)
    symbol = ca.SX.sym("q", model.n)
    residual = function(symbol, *arguments)[0]
    jacobian = ca.Function("j", [symbol], [ca.jacobian(residual, symbol)])
    k_of_r = np.array(jacobian(q))
    assert_close(expected[1], k_of_r, rtol=1e-12, scale=np.abs(k_of_r).max())


def _counting_builds(monkeypatch):
    """Lists that grow by one per static balance built and per compiler run on one (the
    model's own library, compiled where the cache is empty, is not counted)."""
    built, compiled = [], []
    original_static, original_compile = loads_module.static_function, build_module.compile_generated

    def counting_static(*args, **kwargs):
        built.append(args[1:])
        return original_static(*args, **kwargs)

    def counting_compile(*args, **kwargs):
        if "static_balance" in args[0]:
            compiled.append(sorted(args[0]))
        return original_compile(*args, **kwargs)

    monkeypatch.setattr(loads_module, "static_function", counting_static)
    monkeypatch.setattr(build_module, "compile_generated", counting_compile)
    return built, compiled


def test_equilibria_of_one_structure_build_their_static_balance_once(monkeypatch, tmp_path):
    """The balance is kept with the model by its structure (the actuator, which tip
    loads), not by the loads' values: another equilibrium of the model builds nothing; a
    model of the same structure with other numbers loads the library its first one
    compiled (no compiler runs); the balance compiled gives the virtual machine's
    equilibrium."""
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))  # nothing of it cached
    built, compiled = _counting_builds(monkeypatch)
    monkeypatch.setattr(loads_module, "COMPILE_AFTER", 0)  # compiled at its first evaluation
    robot = sc.presets.ifac2020().with_segments(2)
    model = sc.Model(robot)
    q0 = rest_configuration(robot)
    first = equilibrium(model, q0, gravity=[0.0, 0.0, 9.81])
    assert len(built) == 1 and len(compiled) == 1
    assert loads_module.static_balance(StaticLoad(model)).in_c
    again = equilibrium(model, q0, gravity=[0.3, 0.0, 9.0], tau=np.full(6, 1e-3))
    assert len(built) == 1 and len(compiled) == 1
    assert first.success and again.success and np.abs(again.q - first.q).max() > 0
    compiled.clear()
    heavier = robot.replace(segments=[s.replace(mass=2 * s.mass) for s in robot.segments])
    other = equilibrium(sc.Model(heavier), q0, gravity=[0.0, 0.0, 9.81])
    assert len(built) == 2 and compiled == []  # built for the new model, loaded from disk
    assert other.success
    in_vm = sc.Model(robot, compile=False)
    assert not loads_module.static_balance(StaticLoad(in_vm)).in_c
    vm = equilibrium(in_vm, q0, gravity=[0.0, 0.0, 9.81])
    assert not loads_module.static_balance(StaticLoad(in_vm)).in_c  # never compiled
    assert_close(first.q, vm.q, rtol=1e-12, scale=np.abs(vm.q).max())
    assert first.stability == vm.stability
    assert_close(first.eigenvalues, vm.eigenvalues, rtol=1e-9, scale=np.abs(vm.eigenvalues).max())


def test_the_static_balance_is_compiled_once_its_evaluations_would_have_paid(monkeypatch, tmp_path):
    """In the virtual machine for ``COMPILE_AFTER`` evaluations, compiled at the next one
    (the ski-rental rule); a new model of the structure, its library now in the cache,
    loads it at once; counted, not timed."""
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))  # nothing of it cached
    built, compiled = _counting_builds(monkeypatch)
    monkeypatch.setattr(loads_module, "COMPILE_AFTER", 30)
    robot = sc.presets.ifac2020()
    model = sc.Model(robot)
    q0 = rest_configuration(robot)
    balance = loads_module.static_balance(StaticLoad(model))
    solved = 0
    while not balance.in_c and solved < 10:
        assert equilibrium(model, q0, gravity=[0.0, 0.0, 9.81]).success
        solved += 1
        assert balance.in_c or (compiled == [] and balance.evaluations <= 30)
    # 19 evaluations an equilibrium: the second stays in the virtual machine
    assert balance.in_c and solved >= 2 and len(compiled) == 1
    assert balance.evaluations == 31  # compiled at the 31st, counted no more
    fresh = loads_module.static_balance(StaticLoad(sc.Model(robot)))
    assert fresh.in_c and fresh.evaluations == 0 and len(compiled) == 1  # loaded, not built
