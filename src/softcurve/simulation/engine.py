"""Integration engines behind :func:`softcurve.simulate`: compiled CVODES and SciPy's RK45,
the state scales and tolerances, and the stiffness estimate that chooses Adams or BDF.

Both engines answer one question: starting from state ``x`` at time ``t0``, integrate over
``[t0, t0 + h]`` with a piecewise-constant input ``tau`` (one value per output interval)
and return the state at the output times ``t0 + h * tout`` (``0 < tout <= 1``).

CVODES runs inside CasADi's compiled integrator. The right-hand side is the model's
compiled ``rhs`` loaded as a CasADi ``external`` function, so an integration of
thousands of steps never returns to Python. Its Newton matrix comes from forward
differences of that compiled function (one Jacobian costs ``n_state + 1`` right-hand
sides). An exact Jacobian is no cheaper: for the paper's robot its generated code has
84,500 instructions against 10,900 for the right-hand side (7.7 right-hand sides against
10), and given to CVODES as the library's ``jac_`` function it took the same 23 us per
Jacobian as the finite differences while adding ~20 s of compilation. The state is
integrated scaled, ``x = nominal * xs``, so that every scaled state is of order one:
finite-difference steps are then well sized and one absolute tolerance serves all.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np
from scipy.integrate import RK45

STIFFNESS_RATIO = 10.0
"""``"cvodes"`` uses BDF when max decay rate > STIFFNESS_RATIO * max oscillation frequency."""

RESTART_INTERVAL = 1.0
"""CVODES is restarted (order 1, a fresh step-size estimate) at the first output time after
every RESTART_INTERVAL seconds of simulated time.

Why: during a transient the multistep method raises its order (Adams up to 12, BDF up to
5); once the robot has come to rest, the fast, lightly damped elongation and creep modes
keep a high-order method on the edge of its stability region, so it goes on taking steps
of a few milliseconds for nothing (absolute stability of Adams-Moulton of order >= 3 and
of BDF of order >= 3 near the imaginary axis is bounded). A restart begins again at order
one, which is A-stable, and the step grows to the output interval. Measured on the
paper's 10 s case at rtol 1e-6: 1886 steps without restarts, 958 with 1 s restarts, the
same trajectory within the tolerance (``benchmarks/bench_simulate.py``). A restart costs
about ten short steps, negligible next to a second of robot motion."""


def restart_segments(grid: np.ndarray, interval: float = RESTART_INTERVAL) -> list[tuple]:
    """Output index ranges ``(k0, k1)`` covering ``grid``, each at least one interval long
    and spanning at most ``interval`` seconds unless one output interval is longer."""
    segments, k0 = [], 0
    while k0 < grid.size - 1:
        k1 = int(np.searchsorted(grid, grid[k0] + interval, side="right")) - 1
        k1 = min(max(k1, k0 + 1), grid.size - 1)
        segments.append((k0, k1))
        k0 = k1
    return segments


def nominal_scale(model, x0: np.ndarray) -> np.ndarray:
    """A positive scale per state: ``max(|x0|, floor)``, floors from the geometry.

    Lengths scale with the rest length ``l0``, curvatures with ``1/l0`` (a 1 rad bend),
    rates with those per second, creep states with their steady response ``gain/rate``
    to such a rate (1 where the gain is zero). The default absolute tolerance is
    ``rtol`` times this scale, so every state is accurate to ``rtol`` relative to the
    larger of its value and its natural size.
    """
    q_floor = np.concatenate(
        [[s.rest_length, 1 / s.rest_length, 1 / s.rest_length] for s in model.robot.segments]
    )
    lam_floor = []
    for k, s in enumerate(model.robot.segments):
        if s.creep is not None:
            response = np.abs(s.creep.gain) / s.creep.rate * q_floor[3 * k : 3 * k + 3]
            lam_floor.extend(np.where(response > 0, response, 1.0))
    floor = np.concatenate([q_floor, q_floor, lam_floor])
    return np.maximum(np.abs(x0), floor)


def _linearisation(model, x0, tau0, nominal) -> np.ndarray:
    """Eigenvalues of ``d xdot / dx`` at ``x0`` by central differences."""
    jac = np.empty((x0.size, x0.size))
    for i in range(x0.size):
        step = 1e-6 * nominal[i]
        e = np.zeros(x0.size)
        e[i] = step
        forward = np.array(model.state_derivative(x0 + e, tau0))
        backward = np.array(model.state_derivative(x0 - e, tau0))
        jac[:, i] = (forward - backward) / (2 * step)
    return np.linalg.eigvals(jac)


def linear_rates(eigenvalues: np.ndarray) -> tuple:
    """``(stiffness ratio, fastest rate)`` from the eigenvalues of a linearisation, along
    the last axis: the fastest decay rate over the fastest oscillation frequency (at least
    ``1 rad/s``), and the largest ``|eigenvalue|`` [1/s]."""
    decay = np.max(-eigenvalues.real, axis=-1, initial=0.0)
    oscillation = np.maximum(1.0, np.max(np.abs(eigenvalues.imag), axis=-1, initial=0.0))
    return decay / oscillation, np.max(np.abs(eigenvalues), axis=-1, initial=0.0)


def stiffness_ratio(model, x0, tau0=None, nominal=None) -> float:
    """Fastest decay rate over fastest oscillation frequency of the linearisation at ``x0``
    (at least ``1 rad/s``): large for stiff problems."""
    return linearisation_rates(model, x0, tau0, nominal)[0]


def linearisation_rates(model, x0, tau0=None, nominal=None) -> tuple[float, float]:
    """:func:`linear_rates` of the central-difference linearisation at ``x0``."""
    tau0 = np.zeros(model.n) if tau0 is None else tau0
    nominal = nominal_scale(model, x0) if nominal is None else nominal
    eigenvalues = _linearisation(model, np.asarray(x0, float), tau0, nominal)
    ratio, fastest = linear_rates(eigenvalues)
    return float(ratio), float(fastest)


SETTLED_RATIO = 1000.0
"""Where ``"cvodes"`` chose Adams, it integrates a restart segment with BDF once the robot
has settled: when at the segment's start the state changes at less than 1/SETTLED_RATIO of
the fastest rate of the initial linearisation, ``max_i |xdot_i| / nominal_i <
max |eigenvalue| / SETTLED_RATIO``. The motion is then far slower than the fastest mode,
the problem is stiff along the solution, and Adams would be held to short steps by
stability rather than accuracy. Both families are error-controlled, so the choice changes
the work, not the accuracy. Measured (``benchmarks/bench_cvodes_options.py``, section 5):
five paper-case members after 2 s take 619 BDF steps against 1060 Adams steps for the
remaining 8 s, and after 1 s (still moving) no fewer; section 2 prints the batch's rate
without the switch (1020 against 1321 simulated s per CPU s on 2026-11-29)."""


def settled(xdot: np.ndarray, nominal: np.ndarray, fastest) -> np.ndarray:
    """Whether states move slower than ``fastest / SETTLED_RATIO`` (along the last axis)."""
    return np.max(np.abs(xdot) / nominal, axis=-1) * SETTLED_RATIO < fastest


class IntegrationFailure(RuntimeError):
    """The integrator stopped; ``states`` holds the outputs reached before it did."""

    def __init__(self, reason: str, states: np.ndarray):
        super().__init__(reason)
        self.reason = reason
        self.states = states


@dataclass(frozen=True)
class PressureInput:
    """Pressures as the integrator's input: the force is ``H(q) p``.

    Without a ``time_constant`` the input ``u`` is the chamber pressures themselves. With
    one, ``u`` is the command and the chamber pressures are ``m`` extra states after
    ``(q, qd, lam)``: ``p' = (clip(u, lower, upper) - p) / time_constant``.
    """

    force: ca.Function  # (q (n,), p (m,)) -> H(q) p (n,)
    lower: np.ndarray
    upper: np.ndarray
    time_constant: float | None = None

    @property
    def n_inputs(self) -> int:
        return self.lower.size

    @property
    def n_states(self) -> int:
        """Extra states: the chamber pressures when they lag their command."""
        return 0 if self.time_constant is None else self.n_inputs

    @cached_property
    def key(self) -> tuple:
        """What the compiled integrators built on it depend on (computed once)."""
        return (self.force.serialize(), self.lower.tobytes(), self.upper.tobytes(),
                self.time_constant)  # fmt: skip

    def state_derivative(self, model, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The derivative of ``(x, p)`` (or of ``x`` without lag) in NumPy, for SciPy."""
        x = y[: model.n_state]
        pressures = u if self.time_constant is None else y[model.n_state :]
        force = np.array(self.force(x[: model.n], pressures)).ravel()
        xdot = model.state_derivative(x, force)
        if self.time_constant is None:
            return xdot
        rate = (np.clip(u, self.lower, self.upper) - pressures) / self.time_constant
        return np.concatenate([xdot, rate])


MAX_ORDER = 5
"""Highest order of the multistep method (CVODES's default for Adams is 12, for BDF 5).

Why: the stability region of Adams-Moulton shrinks as the order rises; on the paper's
robot the lightly damped elongation and creep modes then bound the step of orders above
five, and the error test fails more often. Measured on 60 paper-case members, 10 s,
rtol 1e-6 (``benchmarks/bench_cvodes_options.py``, section 2, 2026-11-29): 1300 against
1069 simulated seconds per CPU second for order 12, the same error against rtol 1e-10
(1.1e-5 against 1.2e-5); orders 4 and 8 in between. That was before the switch to BDF
once settled (``SETTLED_RATIO``); with it, 1321 against 1217."""


def cvodes_options(multistep: str, rtol: float, abstol: float, max_steps: int) -> dict:
    """CasADi's CVODES options for a scaled problem (one absolute tolerance)."""
    return {
        "linear_multistep_method": multistep,
        "reltol": rtol,
        "abstol": abstol,
        "max_num_steps": int(max_steps),
        "max_order": MAX_ORDER,
        "disable_internal_warnings": True,
    }


def _key(inputs: PressureInput | None):
    return None if inputs is None else inputs.key


def scaled_dae(model, inputs: PressureInput | None = None) -> ca.Function:
    """``dxs/ds = h f(nominal * xs, tau, p) / nominal`` on normalised time ``s`` in [0, 1].

    Integrator parameter ``(robot parameters (n_p,), h, nominal (n_state [+ m],))``; input
    ``u`` is the input force ``tau`` or, with ``inputs``, the pressures (or their commands,
    see :class:`PressureInput`). The scale is a parameter so that one integrator serves
    every initial state and every member of a batch. The right-hand side is the model's
    compiled ``rhs`` (an ``external``, Jacobian by forward differences) or, without a
    compiled library, its symbolic form.
    """

    def build():
        rhs = model.function("rhs", {"enable_fd": True, "fd_method": "forward"})
        n_par, n_state = model.parameters.size, model.n_state
        extra = 0 if inputs is None else inputs.n_states
        xs = ca.MX.sym("x", n_state + extra)
        p = ca.MX.sym("p", n_par + 1 + n_state + extra)
        u = ca.MX.sym("u", model.n if inputs is None else inputs.n_inputs)
        scale = p[n_par + 1 :]
        x = scale * xs
        q = x[: model.n]
        rates = []
        if inputs is None:
            tau = u
        elif inputs.time_constant is None:
            tau = inputs.force(q, u)
        else:
            pressures = x[n_state:]
            tau = inputs.force(q, pressures)
            command = ca.fmin(ca.fmax(u, ca.DM(inputs.lower)), ca.DM(inputs.upper))
            rates = [(command - pressures) / inputs.time_constant]
        xdot = ca.vertcat(rhs(x[:n_state], tau, p[:n_par]), *rates)
        ode = p[n_par] * xdot / scale
        empty = ca.MX(0, 1)
        return ca.Function(
            "softcurve_dae",
            [ca.MX.sym("t"), xs, ca.MX.sym("z", 0), p, u],
            [ode, empty, empty, empty],
            ca.dyn_in(),
            ca.dyn_out(),
        )

    return model.cached(("dae", _key(inputs)), build)


def cvodes_integrator(
    model, tout: np.ndarray, options: dict, inputs: PressureInput | None = None
) -> ca.Function:
    """CVODES on :func:`scaled_dae` with outputs at normalised times ``tout``, cached."""
    key = ("cvodes", tout.tobytes(), tuple(sorted(options.items())), _key(inputs))

    def build():
        dae = scaled_dae(model, inputs)
        return ca.integrator("softcurve_cvodes", "cvodes", dae, 0.0, tout, options)

    return model.cached(key, build)


class BufferedCall:
    """A CasADi function evaluated on NumPy memory through its buffer interface (no
    conversions); a lock keeps one caller at a time on the buffer.

    Inputs and the first output are C-contiguous float64 arrays laid out as CasADi's
    column-major matrices (one column after another).
    """

    def __init__(self, function: ca.Function):
        self.lock = threading.Lock()
        self.buffer, self.evaluate = function.buffer()

    def __call__(self, inputs: dict[int, np.ndarray], output: np.ndarray) -> tuple:
        """``(failure, stats)``: None or CasADi's message, and the function's statistics."""
        with self.lock:
            for i, a in inputs.items():
                self.buffer.set_arg(i, memoryview(a))
            self.buffer.set_res(0, memoryview(output))
            try:
                self.evaluate()
                status = self.buffer.ret()
                failure = None if status == 0 else f"status {status}"
            except RuntimeError as exc:
                failure = str(exc)
            return failure, self.buffer.stats()


class _Engine:
    """Shared by the engines: split the input into runs where it is constant, because an
    error-controlled integrator must not step across a jump of the input."""

    def advance(self, x, h, tout, taus) -> np.ndarray:
        """States (len(tout), n_state) at ``t0 + h * tout`` from ``x`` at ``t0``, with
        ``taus[k]`` applied on ``(tout[k-1], tout[k]]``."""
        taus = np.asarray(taus)
        out = np.empty((tout.size, x.size))
        changes = np.flatnonzero(np.any(taus[1:] != taus[:-1], axis=1)) + 1
        start = 0.0
        for k, stop in zip(np.r_[0, changes], np.r_[changes, tout.size], strict=True):
            j = stop - 1
            length = tout[j] - start
            try:
                out[k:stop] = self._constant(
                    x, h * length, (tout[k:stop] - start) / length, taus[k]
                )
            except IntegrationFailure as failure:
                done = failure.states.shape[0]
                out[k : k + done] = failure.states
                raise IntegrationFailure(failure.reason, out[: k + done].copy()) from None
            x, start = out[j], tout[j]
        return out


class CvodesEngine(_Engine):
    """SUNDIALS CVODES (variable order, variable step) with ``multistep`` = "adams" or "bdf".

    Parameters
    ----------
    model : Model
    multistep : {"adams", "bdf"}
    rtol : float
        Relative tolerance.
    atol : ndarray, shape (n_state,)
        Absolute tolerance per state; CVODES takes one number for the scaled state, so the
        tightest ``atol / nominal`` is used and every state meets its own tolerance.
    nominal : ndarray, shape (n_state,)
        Scale of each state (> 0).
    max_steps : int
        Internal steps allowed between two output times.
    inputs : PressureInput, optional
        When the inputs are pressures rather than forces.
    """

    name = "cvodes"

    def __init__(self, model, multistep, rtol, atol, nominal, max_steps, inputs=None):
        self.model = model
        self.nominal = nominal
        self.inputs = inputs
        self._settings = (rtol, float(np.min(atol / nominal)), max_steps)
        self.families = [multistep]
        self.use(multistep)
        self.counts = {
            "steps": 0,
            "rhs_evaluations": 0,
            "jacobian_evaluations": 0,
            "error_test_failures": 0,
            "newton_failures": 0,
        }

    def use(self, multistep: str) -> None:
        """Integrate from here on with ``multistep`` ("adams" or "bdf")."""
        self.options = cvodes_options(multistep, *self._settings)
        if multistep not in self.families:
            self.families.append(multistep)

    @property
    def method(self) -> str:
        """ "cvodes-adams", "cvodes-bdf", or "cvodes-adams+bdf" when both were used."""
        return "cvodes-" + "+".join(self.families)

    def _integrator(self, tout: np.ndarray) -> BufferedCall:
        """The integrator with outputs at ``tout``, cached with the model."""
        key = ("buffer", tout.tobytes(), tuple(sorted(self.options.items())), _key(self.inputs))

        def build():
            return BufferedCall(cvodes_integrator(self.model, tout, self.options, self.inputs))

        return self.model.cached(key, build)

    def _count(self, stats: dict) -> None:
        c = self.counts
        c["steps"] += int(stats.get("nsteps", 0))
        c["rhs_evaluations"] += int(stats.get("nfevals", 0))
        # one Jacobian per linear-solver setup (CasADi's call counters accumulate over calls)
        c["jacobian_evaluations"] += int(stats.get("nlinsetups", 0))
        c["error_test_failures"] += int(stats.get("netfails", 0))
        c["newton_failures"] += int(stats.get("nncfails", 0))

    def _constant(self, x, h, tout, tau) -> np.ndarray:
        x0 = np.ascontiguousarray(x / self.nominal)
        p = np.concatenate([self.model.parameters, [h], self.nominal])
        u = np.tile(np.asarray(tau, dtype=np.float64), tout.size)  # column-major (n, k)
        out = np.zeros(x.size * tout.size)  # column-major (n_state, k)
        failure, stats = self._integrator(tout)({0: x0, 2: p, 3: u}, out)
        self._count(stats)
        if failure is not None:
            raise IntegrationFailure(_cvodes_reason(failure), np.empty((0, x.size)))
        return out.reshape(tout.size, x.size) * self.nominal


def _cvodes_reason(text: str) -> str:
    for flag, meaning in (
        ("CV_TOO_MUCH_WORK", "too many internal steps between two output times (max_steps)"),
        ("CV_TOO_CLOSE", "the output interval is too short for the step size"),
        ("CV_ERR_FAILURE", "the error test failed repeatedly (step size became too small)"),
        ("CV_CONV_FAILURE", "the Newton iteration failed repeatedly"),
        ("CV_RHSFUNC_FAIL", "the right-hand side failed (non-finite values)"),
        ("CV_REPTD_RHSFUNC_ERR", "the right-hand side failed (non-finite values)"),
        ("CV_LSETUP_FAIL", "the linear solver setup failed (singular Newton matrix)"),
        ("CV_LSOLVE_FAIL", "the linear solve failed"),
    ):
        if flag in text:
            return f"CVODES {flag}: {meaning}"
    return "CVODES failed: " + text.strip().splitlines()[-1][:300]


class ScipyEngine(_Engine):
    """SciPy's explicit Runge-Kutta 4(5) (Dormand-Prince, like MATLAB's ode45), stepped
    from Python over the model's compiled right-hand side."""

    name = "rk45"
    method = "rk45"

    def __init__(self, model, rtol, atol, max_steps, inputs=None):
        self.model = model
        self.inputs = inputs
        self.rtol = rtol
        self.atol = atol
        self.max_steps = int(max_steps)
        self.counts = {"steps": 0, "rhs_evaluations": 0, "jacobian_evaluations": 0}

    def _constant(self, x, h, tout, tau) -> np.ndarray:
        out = np.empty((tout.size, x.size))
        if self.inputs is None:
            rhs = self.model.rhs(tau)
        else:
            rhs = lambda t, y: self.inputs.state_derivative(self.model, y, tau)  # noqa: E731
        # RK45 keeps references to earlier derivatives: give it arrays of its own
        self._run(lambda t, y: np.array(rhs(t, y)), x, 0.0, h * tout, out)
        return out

    def _run(self, f, x, t0, times, out) -> np.ndarray:
        solver = RK45(f, t0, x, times[-1], rtol=self.rtol, atol=self.atol)
        i, steps = 0, 0
        while i < times.size:
            if solver.status != "running":
                break
            message = solver.step()
            self.counts["steps"] += 1
            steps += 1
            if solver.status == "failed" or not np.all(np.isfinite(solver.y)):
                self.counts["rhs_evaluations"] += solver.nfev
                reason = f"RK45: {message or 'non-finite state'} at t = {solver.t:.6g} s"
                raise IntegrationFailure(reason, out[:i].copy())
            if steps > self.max_steps * times.size:
                self.counts["rhs_evaluations"] += solver.nfev
                raise IntegrationFailure(
                    "RK45: too many steps (max_steps per output interval)", out[:i].copy()
                )
            if i < times.size and solver.t >= times[i]:
                dense = solver.dense_output()
                while i < times.size and solver.t >= times[i]:
                    out[i] = solver.y if times[i] == solver.t else dense(times[i])
                    i += 1
        self.counts["rhs_evaluations"] += solver.nfev
        return out[-1].copy()
