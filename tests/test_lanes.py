"""SX functions as C over lanes of members (:mod:`softcurve.compiled._lanes`) against
CasADi's own evaluation, and the explicit stepper's lanes period
(:mod:`softcurve.simulation.stepper._lanes`) against the scalar period per member."""

from __future__ import annotations

import ctypes
import subprocess

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.compiled import _lanes as lanes_module
from softcurve.compiled._lanes import (
    LANE_WIDTH,
    VECTOR_MATH_LIBRARY,
    lanes_function,
    lanes_prelude,
    lanes_work,
)
from softcurve.compiled._source import compile_source
from softcurve.simulation.solvers import ActuatorInput
from softcurve.simulation.stepper import _lanes as stepper_lanes
from softcurve.simulation.stepper._lanes import LanesMembers, lanes_period
from softcurve.simulation.stepper._scheme import ThreadedMembers, period_function
from softcurve.simulation.stepper._stepper import Stepper

from .conftest import compiler_refusing

PERIOD = 0.02


def every_operation() -> ca.Function:
    """``(x (3,) per member, p (2,) shared) -> (y (2,), z (26,))`` with every operation
    the lanes code writes, both branches of a conditional taken across the lanes, and
    non-finite constants."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    a, b, c = x[0], x[1], x[2]
    z = [
        a + b, a - p[0], a * b, a / p[1], -a, a**2, 2 * a, 1 / b, ca.exp(a), ca.log(b),
        ca.sqrt(b), ca.sin(a), ca.cos(a), ca.tan(a), ca.atan(a), ca.tanh(a), ca.fabs(a),
        ca.floor(a), ca.sinh(a), ca.atan2(a, b), ca.fmin(a, c), ca.fmax(a, c), b**p[0],
        ca.sign(a) + ca.sign(c - c), ca.if_else(ca.logic_and(a < c, b >= 1), ca.sin(c), c**3),
        ca.if_else(ca.logic_or(a == c, ca.logic_not(a != 0.5)), np.inf, -np.inf),
    ]  # fmt: skip
    return ca.Function("every", [x, p], [ca.vertcat(a * b + p[0], ca.erf(c)), ca.vertcat(*z)])


def lanes_library(function, vector_math):
    """``run(x (n_in0, W), p, y0 (n_out0, W), y1 ...)`` compiled: lane-major arrays."""
    n_x = function.size1_in(0)
    sizes = [function.size1_out(i) for i in range(function.n_out())]
    outputs = ", ".join(f"double* y{i}" for i in range(len(sizes)))
    body = [
        f"  sc_v x[{n_x}];",
        *(f"  sc_v o{i}[{size}];" for i, size in enumerate(sizes)),
        f"  for (int j = 0; j < {n_x}; j++)",
        "    for (int l = 0; l < SC_W; l++) x[j][l] = xs[j * SC_W + l];",
        f"  sc_v w[{lanes_work(function)}];",
        f"  lanes(x, p, {', '.join(f'o{i}' for i in range(len(sizes)))}, w);",
        *(
            f"  for (int j = 0; j < {size}; j++) for (int l = 0; l < SC_W; l++) "
            f"y{i}[j * SC_W + l] = o{i}[j][l];"
            for i, size in enumerate(sizes)
        ),
    ]
    source = "\n".join(
        [
            lanes_prelude(LANE_WIDTH, vector_math),
            lanes_function(function, "lanes", (False, True)),
            '__attribute__((visibility("default"))) void run(const double* xs, '
            f"const double* p, {outputs}) {{",
            *body,
            "}",
        ]
    )
    link = VECTOR_MATH_LIBRARY if vector_math else ()
    return compile_source("test_lanes", source, link)


@pytest.mark.parametrize(("vector_math", "stack_work"), [(False, 10**6), (True, 10**6), (True, 0)])
def test_lanes_compute_what_casadi_computes(vector_math, stack_work, rng, monkeypatch):
    """Every lane equals CasADi's evaluation of that member: to the ulp with the C
    library's functions, within libmvec's 4 ulp with the vector ones; with the work in
    local variables and in the caller's array (``STACK_WORK``)."""
    monkeypatch.setattr(lanes_module, "STACK_WORK", stack_work)
    function = every_operation()
    library = lanes_library(function, vector_math)
    if library is None:
        pytest.skip("no C compiler with vector extensions (or no libmvec) on this machine")
    x = np.stack(
        [rng.uniform(-2, 2, LANE_WIDTH), rng.uniform(0.5, 3, LANE_WIDTH), np.zeros(LANE_WIDTH)]
    )
    x[2] = [0.5, -1.0, x[0, 2], 3.0][:LANE_WIDTH]  # a == c in lane 2: both branches taken
    x[0, 1] = 0.5
    p = np.array([0.7, 1.3])
    ys = [np.zeros((function.size1_out(i), LANE_WIDTH)) for i in range(function.n_out())]
    pointer = ctypes.POINTER(ctypes.c_double)
    library.run(*(a.ctypes.data_as(pointer) for a in (np.ascontiguousarray(x), p, *ys)))
    for lane in range(LANE_WIDTH):
        expected = [np.array(y).ravel() for y in function(x[:, lane], p)]
        for got, want in zip(ys, expected, strict=True):
            finite = np.isfinite(want)
            np.testing.assert_array_equal(got[~finite, lane], want[~finite])
            np.testing.assert_allclose(got[finite, lane], want[finite], rtol=1e-15, atol=1e-15)


def test_lanes_refuse_what_they_cannot_write():
    x, m = ca.SX.sym("x", 2), ca.MX.sym("m")
    with pytest.raises(ValueError, match="SX function"):
        lanes_function(ca.Function("m", [m], [m * 2]), "f", (False,))
    with pytest.raises(ValueError, match="shared needs 1"):
        lanes_function(ca.Function("f", [x], [x]), "f", (False, True))
    with pytest.raises(ValueError, match="output 0 must be a dense column"):
        lanes_function(ca.Function("f", [x], [ca.diag(x)]), "f", (False,))
    with pytest.raises(NotImplementedError, match="OP_ERFINV"):
        lanes_function(ca.Function("f", [x], [ca.erfinv(x)]), "f", (False,))
    with pytest.raises(ValueError, match="width 4"):
        lanes_prelude(8, vector_math=True)


@pytest.mark.parametrize("count", [1, 3, LANE_WIDTH + 1, 9])
def test_the_lanes_period_equals_the_scalar_period_per_member(count, paper_model, rng):
    """Whole and partial vectors, on one to three threads: every member's RK4 period
    equals the scalar compiled period's (CasADi's C) to round-off, and the threads'
    shares do not change a bit."""
    entry = lanes_period(paper_model, None, 6, "RK4")
    scalar = period_function(paper_model, None, 6, "RK4", True, None, None, native=True)
    if entry is None or scalar is None:
        pytest.skip("no working C compiler")
    x, u = members(paper_model, rng, count)
    shared = [paper_model.parameters, np.array([PERIOD])]
    expected = np.empty((count, paper_model.n_state + 6))
    assert scalar.call_rows([x, u, *shared], expected, 0, count) == []
    outs = []
    for threads in (1, 2, 3):
        out = np.full_like(expected, np.nan)
        assert LanesMembers(entry, threads)(x, u, *shared, out) == []
        outs.append(out)
    scale = np.abs(expected).max(axis=0) + 1e-3
    assert (np.abs(outs[0] - expected) / scale).max() < 1e-13
    np.testing.assert_array_equal(outs[1], outs[0])
    np.testing.assert_array_equal(outs[2], outs[0])


def members(model, rng, count):
    """``count`` states of the paper robot bent up to 20 1/m and moving, and small forces."""
    x = np.zeros((count, model.n_state))
    x[:, 0] = 0.064 + rng.normal(0, 1e-3, count)
    x[:, 1:3] = rng.uniform(-20, 20, (count, 2))
    x[:, 3:6] = rng.normal(0, 1, (count, 3)) * [0.01, 10, 10]
    return x, rng.normal(0, 1e-3, (count, model.n))


@pytest.mark.parametrize(
    ("method", "substeps", "every", "tolerance"),
    [("ROS34PW2", 16, 16, 1e-8), ("ROS2", 8, 2, 1e-6)],
)
def test_the_rosenbrock_lanes_compute_the_scheme_of_the_virtual_machine(
    method, substeps, every, tolerance, paper_model, rng
):
    """The Rosenbrock methods' lanes (forward-difference Newton matrix, its QR, the
    stages) equal CasADi's virtual machine on the same scheme, to the round-off of the
    forward differences: ~1e-8 relative in the Jacobian, from round-off differences of
    ~1e-16 in the right-hand sides over a step of 1.5e-8. A W-method's step depends on
    its matrix; ROS2's more than ROS34PW2's (8.9e-8 here; CasADi's C and its virtual
    machine differ by up to 9e-7 on faster states, measured)."""
    x, u = members(paper_model, rng, 5)
    assert lanes_against_machine(paper_model, None, x, u, method, substeps, every) < tolerance


def lanes_against_machine(model, inputs, x, u, method, substeps, every=None) -> float:
    """The largest difference of the lanes period from CasADi's virtual machine on the
    members ``(x, u)``, relative to each output's largest size (+ 1e-3); the members
    must move by more than 1e-3."""
    entry = lanes_period(model, inputs, substeps, method, every)
    if entry is None:
        pytest.skip("no working C compiler")
    machine = period_function(model, inputs, substeps, method, False, None, every)
    shared = [model.parameters, np.array([PERIOD])]
    out = np.full((len(x), x.shape[1] + 6), np.nan)
    assert LanesMembers(entry, 2)(x, u, *shared, out) == []
    expected = np.array([np.array(machine(x[i], u[i], *shared)).ravel() for i in range(len(x))])
    assert np.abs(out[:, : x.shape[1]] - x).max() > 1e-3  # it moved
    return float((np.abs(out - expected) / (np.abs(expected).max(axis=0) + 1e-3)).max())


@pytest.mark.parametrize("case", ["two segments", "bellows with lag"])
def test_the_rosenbrock_lanes_newton_solve_equals_the_virtual_machines(case, rng):
    """The lanes' Newton solve (``q' = qd`` eliminated, the other states by Householder
    QR in loops) against CasADi's sparse QR of the whole matrix in its virtual machine:
    two segments with creep (18 states, 12 by the QR), and the paper robot with three
    bellows whose pressures lag their commands (12 states, the lag's three after the
    creep's). To the round-off of the forward differences as above: on two segments the
    lanes differ from the machine by 3e-9 to 1.4e-8 whether their QR is in loops or
    CasADi's straight-line code (three seeds each, measured), the right-hand sides'
    round-off in C and in the machine."""
    segments = 2 if case == "two segments" else 1
    model = sc.Model(sc.presets.ifac2020().with_segments(segments), quadrature_nodes=4,
                     compile=False)  # fmt: skip  # the lanes need no library
    count, n = 5, model.n
    spread = np.tile([1e-3, 20, 20], segments)
    q = np.tile([0.064, 0.0, 0.0], segments) + rng.uniform(-1, 1, (count, n)) * spread
    qd = rng.normal(0, 1, (count, n)) * np.tile([0.01, 10, 10], segments)
    x = np.hstack([q, qd, np.zeros((count, model.n_creep))])
    if case == "two segments":
        inputs, u = None, rng.normal(0, 1e-3, (count, n))
    else:
        actuator = sc.PneumaticActuator.three_bellows(
            distance=0.012, area=2e-4, p_max=6e4, time_constant=0.02
        )
        inputs = ActuatorInput.of(actuator, n)
        u = rng.uniform(actuator.lower, actuator.upper, (count, actuator.n_inputs))
        x = np.hstack([x, rng.uniform(actuator.lower, actuator.upper, u.shape)])
    assert lanes_against_machine(model, inputs, x, u, "ROS34PW2", 16) < 5e-8


def test_the_lanes_newton_solve_takes_only_rates_that_follow_the_coordinates():
    """The lanes eliminate the rows of ``q' = qd``: a state derivative that begins with
    anything else is refused (and stepped by the scalar period)."""
    x, p = ca.SX.sym("x", 4), ca.SX.sym("p")
    follows = ca.Function("f", [x, p], [ca.vertcat(x[2], x[3], -p * x[0], -x[1])])
    scaled = ca.Function("f", [x, p], [ca.vertcat(2 * x[2], x[3], -p * x[0], -x[1])])
    swapped = ca.Function("f", [x, p], [ca.vertcat(x[3], x[2], -p * x[0], -x[1])])
    assert stepper_lanes.rates_follow_coordinates(follows, 2)
    assert not stepper_lanes.rates_follow_coordinates(scaled, 2)
    assert not stepper_lanes.rates_follow_coordinates(swapped, 2)
    assert not stepper_lanes.rates_follow_coordinates(follows, 1)


def test_the_newton_solve_of_the_lanes_does_not_grow_with_the_states():
    """The Rosenbrock step's C is loops: as many lines for 72 states as for 9, and no
    factorization written out (a QR as straight-line code grows as the states' cube)."""
    tableau = stepper_lanes.METHODS["ROS34PW2"]
    small = stepper_lanes.rosenbrock_step(tableau, 9, 3, np.ones(9), 16)
    large = stepper_lanes.rosenbrock_step(tableau, 72, 24, np.ones(72), 16)
    assert len(large.lines) == len(small.lines)
    assert sum(map(len, large.lines)) < 1.1 * sum(map(len, small.lines))


def test_without_the_vector_math_library_the_lanes_use_the_c_librarys(
    paper_model, rng, monkeypatch, tmp_path
):
    """A compiler that cannot link libmvec still gets the lanes period, with the C
    library's functions (no vector-math symbol), computing the same periods."""
    wrapper = compiler_refusing(tmp_path, "-lmvec")
    if wrapper is None:
        pytest.skip("no C compiler")
    with_vector_math = lanes_period(paper_model, None, 6, "RK4")
    monkeypatch.setenv("CC", str(wrapper))
    # the cache key holds no compiler: the library above would be loaded from the cache
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "cache"))
    model = sc.Model(sc.presets.ifac2020(), compile=False)  # the lanes need no library
    entry = lanes_period(model, None, 6, "RK4")
    assert entry is not None and with_vector_math.vector_math and not entry.vector_math
    symbols = subprocess.run(["nm", "-D", entry.library], capture_output=True, text=True)
    assert " tanh@" in symbols.stdout and "ZGV" not in symbols.stdout
    x = np.tile([0.064, 5.0, -3.0, 0.0, 10.0, -10.0, 0.0, 0.0, 0.0], (5, 1))
    x[:, 3:6] += rng.normal(0, 1, (5, 3)) * [0.01, 10, 10]
    u = np.zeros((5, model.n))
    shared = [model.parameters, np.array([PERIOD])]
    got, want = np.zeros((5, model.n_state + 6)), np.zeros((5, model.n_state + 6))
    LanesMembers(entry, 1)(x, u, *shared, got)
    LanesMembers(with_vector_math, 1)(x, u, *shared, want)
    assert (np.abs(got - want) / (np.abs(want).max(axis=0) + 1e-3)).max() < 1e-13


def test_the_lanes_check_their_arrays(paper_model):
    """The compiled code reads and writes whole rows: shapes are checked first."""
    entry = lanes_period(paper_model, None, 6, "RK4")
    if entry is None:
        pytest.skip("no working C compiler")
    members = LanesMembers(entry, 2)
    x, u = np.zeros((3, paper_model.n_state)), np.zeros((3, paper_model.n))
    x[:, 0] = 0.064
    shared = [paper_model.parameters, np.array([PERIOD])]
    with pytest.raises(ValueError, match=r"out must be float64 of shape \(3, 15\)"):
        members(x, u, *shared, np.zeros((3, 13)))
    with pytest.raises(ValueError, match=r"u must have shape \(3, 3\)"):
        members(x, u[:2], *shared, np.zeros((3, 15)))
    with pytest.raises(ValueError, match=r"p must have shape"):
        members(x, u, shared[0][:-1], shared[1], np.zeros((3, 15)))
    with pytest.raises(ValueError, match="writeable C-contiguous"):
        members(x, u, *shared, np.zeros((15, 3)).T)


def test_a_model_without_lanes_code_steps_on_the_scalar_period(monkeypatch):
    """Where the lanes cannot be written (an operation without lanes code), the stepper
    runs the scalar compiled period on each member instead."""

    def refuse(*args, **kwargs):
        raise NotImplementedError("no lanes code for CasADi's OP_REMAINDER")

    monkeypatch.setattr(stepper_lanes, "period_source", refuse)
    model = sc.Model(sc.presets.ifac2020())  # a new model: nothing kept with it yet
    assert lanes_period(model, None, 6, "RK4") is None
    stepper = Stepper(model, period=PERIOD, method="RK4")
    if stepper._members is None:
        pytest.skip("no working C compiler")
    assert isinstance(stepper._members, ThreadedMembers)
    result = stepper.step(stepper.initial_state([0.064, 5.0, 0.0])[None, :], np.zeros((1, 3)))
    assert result.ok.all() and np.all(np.isfinite(result.x))
