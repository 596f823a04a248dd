"""softcurve's C driver of CVODES (softcurve.simulation.solvers._driver) against CasADi's CVODES
integrator, the route it replaces: same results to tolerance, same statuses and messages,
less work (budgets on evaluation counts, never on wall time)."""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.simulation.batch._batch import simulate_batch
from softcurve.simulation.solvers import _driver as native
from softcurve.simulation.solvers._policy import nominal_scale

from .conftest import assert_close

Q0, QD0 = np.array([0.064, 25.0, 0.0]), np.array([0.0, 0.0, 1500.0])
RTOL = 1e-6

pytestmark = pytest.mark.skipif(
    native.driver() is None, reason="the C driver of CVODES cannot be built here"
)


def _scale(model, x):
    """Each state's magnitude along a run plus its natural scale."""
    return np.abs(x).max(axis=0) + nominal_scale(model, np.zeros(x.shape[1]))


def _both(run):
    """``run()`` with the C driver, then with CasADi's integrator."""
    fast = run()
    with native.casadi_only():
        slow = run()
    return fast, slow


@pytest.mark.parametrize("method", ["cvodes", "adams", "bdf"])
def test_the_driver_agrees_with_casadi_within_the_tolerance(paper_model, method):
    fast, slow = _both(
        lambda: sc.simulate(paper_model, Q0, QD0, t_final=3.0, dt=0.01, method=method)
    )
    assert fast.success and slow.success
    # the same algorithm on two routes, and each result says which ran
    assert fast.stats["method"] == slow.stats["method"]
    assert (fast.stats["route"], slow.stats["route"]) == ("driver", "casadi-cvodes")
    # both are within ~10 rtol of the exact solution (docs/performance.md): so of each other
    assert_close(fast.x, slow.x, rtol=50 * RTOL, scale=_scale(paper_model, slow.x))


def test_the_driver_reuses_the_jacobian(paper_model):
    """CasADi's integrator recomputes the Jacobian at every linear-solver setup; the driver
    only when CVODES asks for a fresh one (measured 24 against 120 on the paper case)."""
    fast, slow = _both(lambda: sc.simulate(paper_model, Q0, QD0, t_final=10.0, dt=0.01))
    assert fast.stats["jacobian_evaluations"] < fast.stats["linear_solver_setups"] / 2
    assert slow.stats["jacobian_evaluations"] == slow.stats["linear_solver_setups"]
    work = [s.stats["rhs_evaluations"] + 9 * s.stats["jacobian_evaluations"] for s in (fast, slow)]
    assert work[0] < 0.75 * work[1]


def test_the_first_outputs_do_not_depend_on_the_end_time(paper_model):
    """A restart's first step is sized for the next output, not for the end: a run's
    first 0.1 s is the same whether it ends there or a second later."""
    short = sc.simulate(paper_model, Q0, QD0, t_final=0.1, dt=0.01)
    long = sc.simulate(paper_model, Q0, QD0, t_final=1.0, dt=0.01)
    assert_close(long.x[:11], short.x, rtol=1e-8, scale=_scale(paper_model, short.x))


def test_the_driver_writes_into_a_given_array_or_refuses_it(paper_model):
    engine = native.problem(paper_model)
    times = np.linspace(0.0, 0.1, 11)
    x0 = np.concatenate([Q0, QD0, np.zeros(paper_model.n_creep)])[None]
    args = ([1], x0, np.zeros((1, 1, 3)), paper_model.parameters[None])
    rest = (
        nominal_scale(paper_model, x0[0])[None],
        times,
        ([10], [True]),
        native.options(RTOL, RTOL, 500, max_order=5),
    )
    fresh = native.integrate(engine, *args, *rest)[0]
    given = np.full((1, times.size, x0.shape[1]), np.nan)
    returned = native.integrate(engine, *args, *rest, out=given)[0]
    assert returned is given
    np.testing.assert_array_equal(given, fresh)
    with pytest.raises(ValueError, match="C-contiguous float64 of shape"):
        native.integrate(engine, *args, *rest, out=np.zeros((1, times.size, 3)))


@pytest.mark.parametrize("lag", [None, 0.02])
def test_actuated_runs_agree_with_casadi(paper_model, lag):
    """H(q) u compiled and called from C, with and without the pressures' lag."""
    actuator = sc.PneumaticActuator.three_bellows(
        distance=0.012, area=2e-4, p_max=6e4, time_constant=lag
    )
    pressures = np.array([2e4, 0.0, 1e4])
    steps = np.zeros(2)
    # the steps of one run jump between about 2,400 and 5,900 with the start's last digits
    # (both routes, kx0 = 25 +- 0.1 1/m): their work is compared over ten nearby starts,
    # where the driver takes 1.17-1.18 times CasADi's steps with the lag, 0.95 without
    curvatures = (25.0, 25.001, 25.01, 24.99, 25.1, 25.002, 25.02, 24.98, 24.9, 25.05)
    for curvature in curvatures:
        q0 = Q0 + [0.0, curvature - Q0[1], 0.0]
        fast, slow = _both(
            lambda q0=q0: sc.simulate(
                paper_model, q0, QD0, actuator=actuator, inputs=pressures, t_final=10.0, dt=0.001
            )
        )
        assert fast.success and slow.success
        assert_close(fast.x, slow.x, rtol=50 * RTOL, scale=_scale(paper_model, slow.x))
        np.testing.assert_allclose(fast.inputs, slow.inputs, rtol=1e-3, atol=1e-3 * 6e4)
        steps += fast.stats["steps"], slow.stats["steps"]
    # no more work than CasADi's route to within that (a Jacobian kept across restarts
    # once doubled it)
    assert steps[0] <= 1.4 * steps[1]


def test_inputs_that_change_on_the_grid_agree_with_casadi(paper_model):
    """A force that steps at 0.25 s: the driver restarts CVODES there as CasADi's route."""
    grid = np.arange(0.0, 0.5 + 1e-12, 0.01)
    tau = np.zeros((grid.size, 3))
    tau[grid >= 0.25, 1] = 2e-3
    fast, slow = _both(lambda: sc.simulate(paper_model, Q0, QD0, tau=tau, t_final=0.5, dt=0.01))
    assert_close(fast.x, slow.x, rtol=50 * RTOL, scale=_scale(paper_model, slow.x))


def test_a_failure_reads_the_same(paper_model):
    """Too few steps per output: the same status, reason and advice as CasADi's route."""
    fast, slow = _both(lambda: sc.simulate(paper_model, Q0, QD0, t_final=1.0, max_steps=3))
    assert fast.status is slow.status is Status.INTEGRATION_FAILED
    assert fast.message.split(";")[0] == slow.message.split(";")[0]
    assert "CV_TOO_MUCH_WORK" in fast.message and fast.t.size >= 1
    # a run that stopped early holds its reached rows only, not the whole grid's
    assert fast.q.base is not None and fast.q.base.shape[0] == fast.t.size


def test_a_batch_on_two_threads_equals_its_members_alone(paper_model):
    rng = np.random.default_rng(6)
    q0s = np.column_stack([np.full(6, 0.064), rng.uniform(20, 30, 6), np.zeros(6)])
    qd0s = np.column_stack([np.zeros(6), np.zeros(6), rng.uniform(1000, 2000, 6)])
    batch = simulate_batch(paper_model, q0s, qd0s, t_final=2.0, dt=0.01, threads=2, lanes=False)
    assert batch.success
    for i in (0, 5):
        single = sc.simulate(paper_model, q0s[i], qd0s[i], t_final=2.0, dt=0.01)
        assert batch.stats["methods"][i] == single.stats["method"]
        np.testing.assert_allclose(batch.member(i).x, single.x, rtol=1e-12, atol=1e-14)


def test_large_newton_matrices_go_to_scipys_lapack():
    """The pin on SciPy's Cython API (the capsules of ``dgetf2``, ``dgetrs``, ``zgetf2``
    and ``zgetrs``, their signatures) and the switch at ``LAPACK_FROM`` states: a robot
    above it integrates on LAPACK as on the driver's own loops, to round-off, with the same
    steps, alone, in a batch over lanes and by Radau IIA (its complex systems too)."""
    addresses = native.lapack_addresses()
    assert len(addresses) == 4 and all(isinstance(a, int) and a > 0 for a in addresses)
    robot = sc.presets.ifac2020().with_segments(4)
    model = sc.Model(robot)
    assert model.n_state >= native.LAPACK_FROM
    q0 = np.tile(robot.rest_configuration(), (4, 1))
    q0[:, 1::3] += np.linspace(0.0, 5.0, 4)[:, None]
    runs, library = [], native.library()
    try:
        for start in (native.LAPACK_FROM, 10**6):
            library.softcurve_use_lapack(*addresses, start)
            alone = sc.simulate(model, q0[0], np.zeros(model.n), t_final=0.2, dt=0.01)
            grouped = simulate_batch(model, q0, np.zeros_like(q0), t_final=0.2, dt=0.01)
            radau = sc.simulate(model, q0[3], np.zeros(model.n), t_final=0.2, dt=0.01,
                                method="radau")  # fmt: skip
            runs.append((alone, grouped, radau))
    finally:
        library.softcurve_use_lapack(*addresses, native.LAPACK_FROM)
    (lapack, lapack_batch, lapack_radau), (loops, loops_batch, loops_radau) = runs
    assert lapack_radau.success and lapack_radau.stats["route"] == "driver-radau"
    assert lapack_radau.stats["steps"] == loops_radau.stats["steps"]
    np.testing.assert_allclose(lapack_radau.q, loops_radau.q, rtol=0,
                               atol=1e-9 * np.abs(loops_radau.q).max())  # fmt: skip
    assert not np.array_equal(lapack_radau.q, loops_radau.q)
    assert lapack.success and loops.success and lapack_batch.success
    assert lapack_batch.stats["route"] == "driver-lanes"
    assert lapack.stats["steps"] == loops.stats["steps"]
    np.testing.assert_allclose(lapack.q, loops.q, rtol=0, atol=1e-9 * np.abs(loops.q).max())
    assert not np.array_equal(lapack.q, loops.q)  # other arithmetic: LAPACK did run
    np.testing.assert_allclose(lapack_batch.q, loops_batch.q, rtol=0,
                               atol=1e-9 * np.abs(loops_batch.q).max())  # fmt: skip
    assert not np.array_equal(lapack_batch.q, loops_batch.q)
