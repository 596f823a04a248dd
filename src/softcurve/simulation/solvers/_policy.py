"""The one integration engine's shared pieces, used by
:func:`~softcurve.simulation.simulate`,
:func:`~softcurve.simulation.batch.simulate_batch` and the sensitivities of
``softcurve.simulation.sensitivity._sensitivity``: the state scales, the finite-difference
linearization and the choice of Adams or BDF made from it, the restarts, CasADi's CVODES
options and the text of a failure. The integrators themselves (CVODES on the compiled
right-hand side, SciPy's RK45) are in ``softcurve.simulation.solvers._cvodes``.

The state is integrated scaled, ``x = nominal * xs`` (:func:`nominal_scale`), so that
every scaled state is of order one: finite-difference steps are then well sized and one
absolute tolerance serves all.
"""

from __future__ import annotations

import numpy as np

from softcurve.base.status import Status
from softcurve.simulation.solvers import _driver as c_driver
from softcurve.simulation.solvers._along import rhs_along

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
    and spanning at most ``interval`` seconds unless one output interval is longer.

    Parameters
    ----------
    grid : ndarray, shape (T,)
        Output times [s].
    interval : float
        Restart interval [s].
    """
    segments, k0, last = [], 0, grid.size - 1
    search = grid.searchsorted  # the method: NumPy's function wrapper costs as much again
    while k0 < last:
        k1 = int(search(grid[k0] + interval, "right")) - 1
        k1 = min(max(k1, k0 + 1), last)
        segments.append((k0, k1))
        k0 = k1
    return segments


def nominal_scale(model, x0: np.ndarray) -> np.ndarray:
    """A positive scale per state: ``max(|x0|, floor)``, floors from the geometry.

    Lengths scale with the rest length ``l0``, curvatures with ``1/l0`` (a 1 rad bend),
    strains with 1 (:meth:`Robot.coordinate_scale`), rates with those per second, creep
    states with their steady response ``gain/rate``
    to such a rate (1 where the gain is zero). The default absolute tolerance is
    ``rtol`` times this scale, so every state is accurate to ``rtol`` relative to the
    larger of its value and its natural size.

    Parameters
    ----------
    model : Model
        A model (only its robot is read).
    x0 : ndarray, shape (n_state,)
        The initial state.
    """
    if not hasattr(model, "cached"):  # a batch's holder of a robot alone
        return np.maximum(np.abs(x0), _state_floor(model.robot))
    floor = model.cached("nominal floor", lambda: _state_floor(model.robot))
    return np.maximum(np.abs(x0), floor)


def lag_scale(inputs) -> np.ndarray:
    """The scale of lagging inputs (m,): the larger bound of each, ``max(|lower|, |upper|)``
    (in the inputs' unit).

    Parameters
    ----------
    inputs : ActuatorInput or Actuator
        What has the bounds ``lower`` and ``upper`` (m,).
    """
    return np.maximum(np.abs(inputs.lower), np.abs(inputs.upper))


def state_scale(model, x0: np.ndarray, inputs=None) -> np.ndarray:
    """The one state scale of an integration (N,): :func:`nominal_scale` of ``(q, qd, lam)``
    and, where the actuator's inputs lag their commands, :func:`lag_scale` of them.

    Parameters
    ----------
    model : Model
        A model (only its robot is read).
    x0 : ndarray, shape (n_state,)
        The initial state ``(q, qd, lam)``.
    inputs : ActuatorInput, optional
        The actuator's input (None: forces, no extra states).
    """
    nominal = nominal_scale(model, x0[: model.n_state])
    if inputs is None or not inputs.n_states:
        return nominal
    return np.concatenate([nominal, lag_scale(inputs)])


def _state_floor(robot) -> np.ndarray:
    """The floors of :func:`nominal_scale` (n_state,), read-only: they depend on the robot
    alone, so a model computes them once."""
    q_floor = robot.coordinate_scale()
    lam_floor = []
    for k, s in enumerate(robot.segments):
        if s.n_creep:
            own = robot.element_coordinates(q_floor, k)
            response = np.abs(s.creep.gain) / s.creep.rate * own
            lam_floor.extend(np.where(response > 0, response, 1.0))
    floor = np.concatenate([q_floor, q_floor, lam_floor])
    floor.setflags(write=False)
    return floor


DIFFERENCE_STEP = 1e-6
"""Central-difference step of the linearization, relative to each state's nominal scale:
near the cube root of the machine epsilon (6e-6), where the truncation error of central
differences and the round-off of the right-hand side balance."""


def difference_points(x0: np.ndarray, nominal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The states at which a central-difference linearization evaluates the right-hand
    side, ``(points (..., 2 n_state, n_state), steps (..., n_state))``: ``x0 + h_j e_j``
    for every state ``j``, then ``x0 - h_j e_j``, with ``h = DIFFERENCE_STEP * nominal``.
    Leading axes (members of a batch) pass through.

    Parameters
    ----------
    x0 : ndarray, shape (..., n_state)
        The state(s) to linearize at.
    nominal : ndarray, shape (..., n_state)
        State scales.
    """
    steps = DIFFERENCE_STEP * nominal
    offsets = steps[..., :, None] * np.eye(x0.shape[-1])
    points = np.concatenate([x0[..., None, :] + offsets, x0[..., None, :] - offsets], axis=-2)
    return points, steps


def difference_eigenvalues(values: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Eigenvalues [1/s] of the Jacobian from the right-hand side's ``values`` at the
    :func:`difference_points` (same leading axes).

    Parameters
    ----------
    values : ndarray, shape (..., 2 n_state, n_state)
        Right-hand side at the points.
    steps : ndarray, shape (..., n_state)
        The steps of :func:`difference_points`.
    """
    n_state = steps.shape[-1]
    # columns[..., j, i] = d xdot_i / d x_j
    columns = (values[..., :n_state, :] - values[..., n_state:, :]) / (2 * steps[..., :, None])
    return np.linalg.eigvals(np.swapaxes(columns, -1, -2))


def linear_rates(eigenvalues: np.ndarray) -> tuple:
    """``(stiffness ratio, fastest rate)`` from the eigenvalues of a linearization, along
    the last axis: the fastest decay rate over the fastest oscillation frequency (at least
    ``1 rad/s``), and the largest ``|eigenvalue|`` [1/s].

    Parameters
    ----------
    eigenvalues : ndarray, shape (..., n_state)
        Eigenvalues of a linearization [1/s].
    """
    # the methods rather than NumPy's function wrappers: the same reductions, cheaper
    decay = (-eigenvalues.real).max(axis=-1, initial=0.0)
    oscillation = np.maximum(1.0, np.abs(eigenvalues.imag).max(axis=-1, initial=0.0))
    return decay / oscillation, np.abs(eigenvalues).max(axis=-1, initial=0.0)


def linearization_rates(model, x0, tau0=None, nominal=None, parameters=None, threads=1):
    """:func:`linear_rates` of the eigenvalues of the central-difference linearization of
    ``model``'s right-hand side at ``x0``: ``(stiffness ratio, fastest rate [1/s])``. The
    stiffness ratio, the fastest decay rate over the fastest oscillation frequency (at
    least ``1 rad/s``), is large for stiff problems. The one rule of the fastest mode at a
    state: for one run (floats) or for every member of a batch at once (arrays (B,), all
    points in one compiled map over the members' own parameters).

    Parameters
    ----------
    model : Model
        The compiled model.
    x0 : array_like, shape (n_state,) or (B, n_state)
        The state, or each member's.
    tau0 : array_like, shape (n,) or (B, n), optional
        Input force [N, N m^2, N m^2] (default zero).
    nominal : ndarray, shape (n_state,) or (B, n_state), optional
        State scales, relative to which the steps are taken (default
        :func:`nominal_scale`, one state only).
    parameters : ndarray, shape (B, n_p), optional
        Each member's parameter vector (with ``x0`` (B, n_state); default the model's).
    threads : int
        Threads of the members' compiled map.
    """
    x0 = np.asarray(x0, dtype=np.float64)
    tau0 = np.zeros(x0.shape[:-1] + (model.n,)) if tau0 is None else np.asarray(tau0)
    nominal = nominal_scale(model, x0) if nominal is None else nominal
    points, steps = difference_points(x0, nominal)
    if x0.ndim == 2:  # members: (B, 2 n_state, n_state) points
        if parameters is None:
            parameters = np.tile(model.parameters, (x0.shape[0], 1))
        taus = np.broadcast_to(tau0[:, None, :], (*points.shape[:2], model.n))
        values = rhs_along(model, points, taus, parameters, threads)
        return linear_rates(difference_eigenvalues(values, steps))
    problem = c_driver.problem(model) if x0.size == model.n_state else None
    if problem is not None:  # one compiled call rather than 2 n_state calls from Python
        taus = np.empty((points.shape[0], model.n))  # contiguous: evaluate copies no input
        taus[:] = tau0
        values = c_driver.evaluate(problem, points, taus, model.parameters)
    else:
        values = np.array([model.state_derivative(x, tau0) for x in points])
    ratio, fastest = linear_rates(difference_eigenvalues(values, steps))
    return float(ratio), float(fastest)


def multistep_family(ratio, contact: bool = False):
    """CVODES's family for ``method="cvodes"``: ``"bdf"`` where the stiffness ``ratio``
    exceeds ``STIFFNESS_RATIO`` or the model has obstacles, else ``"adams"``
    (elementwise for arrays).

    A robot that starts clear of its obstacles has the free model's stiffness at the
    start, but a penalty contact is far stiffer than the robot (docs/contact.md) once it
    touches, which the start cannot show: with obstacles the stiff family is chosen from
    the start.

    Parameters
    ----------
    ratio : float or ndarray
        Stiffness ratio(s), dimensionless; for a Python float the family comes back as a
        str.
    contact : bool
        Whether the model has an environment.
    """
    if type(ratio) is float:  # one run's ratio: the rule without arrays
        return "bdf" if ratio > STIFFNESS_RATIO or contact else "adams"
    stiff = (np.asarray(ratio) > STIFFNESS_RATIO) | contact
    return np.where(stiff, "bdf", "adams")


AUTO_INTERVAL = 10.0
"""``method="auto"`` integrates with Radau IIA where the input on the output grid changes
on average within ``AUTO_INTERVAL`` over the fastest rate of the initial linearization
(seconds), else as ``"cvodes"`` (:func:`auto_method`). CVODES restarts at every change of
the input, at order one with a fresh Jacobian, where Radau IIA goes on with its step size
and Jacobian. Measured on the paper's robot under a slow moment held between outputs
(fastest rate 283 1/s; ``python benchmarks/bench_radau.py --case slow --dt DT``): a
change every 1 ms (0.28 over the fastest rate), Radau IIA 4.3 to 5.6 times faster at the
same error (rtol 1e-4 and 1e-3; at 1e-6 and 1e-5 no CVODES run was as accurate); every
10 ms (2.8), 1.3 to 2.6 times; every 100 ms (28), CVODES 1.2 to 1.4 times faster.
Without changes (the paper's case, chains, a constant moment) CVODES is as fast or faster
(docs/performance.md, "Radau IIA")."""


def auto_method(
    fastest: float, interval: float | None, sampled: bool = False, within: float = AUTO_INTERVAL
) -> tuple[str, str]:
    """What ``method="auto"`` integrates with, and why in a phrase: ``("radau", why)`` or
    ``("cvodes", why)``.

    Parameters
    ----------
    fastest : float
        The fastest rate of the initial linearization [1/s]
        (:func:`linearization_rates`).
    interval : float or None
        The mean time between changes of the input on the output grid [s]
        (:func:`~softcurve.simulation.solvers.change_interval`), None where it changes at
        fewer than half of the output intervals.
    sampled : bool
        The inputs are computed during the run (a controller, a callable): integrated
        piece by piece, each piece a fresh start of either method (not measured: CVODES).
    within : float
        A dimensionless ratio: Radau IIA where ``interval < within / fastest``
        (:data:`AUTO_INTERVAL` for a simulation; a fit's sensitivities have their own
        measured bound, ``softcurve.simulation.sensitivity.AUTO_WITHIN``).
    """
    if sampled:
        return "cvodes", "auto: inputs computed during the run, integrated piece by piece"
    if interval is None:
        return "cvodes", "auto: the input changes at fewer than half of the outputs"
    bound = within / fastest if fastest > 0.0 else np.inf
    relation = "within" if interval < bound else "beyond"
    why = (f"auto: the input changes every {interval:.3g} s on average, {relation} "
           f"{within:g} / fastest rate ({bound:.3g} s)")  # fmt: skip
    return ("radau" if interval < bound else "cvodes"), why


def method_name(family: str) -> str:
    """The integrator's name as results carry it (``stats["method"]``, messages) for the
    family a member ran: ``"radau"``, or CVODES's ``"cvodes-adams"``, ``"cvodes-bdf"``,
    ``"cvodes-adams+bdf"``.

    Parameters
    ----------
    family : {"adams", "bdf", "adams+bdf", "radau"}
        The family.
    """
    return str(family) if family == "radau" else f"cvodes-{family}"


SETTLED_RATIO = 1000.0
"""Where ``"cvodes"`` chose Adams, it integrates a restart segment with BDF once the robot
has settled: when at the segment's start the state changes at less than 1/SETTLED_RATIO of
the fastest rate of the initial linearization, ``max_i |xdot_i| / nominal_i <
max |eigenvalue| / SETTLED_RATIO``. The motion is then far slower than the fastest mode,
the problem is stiff along the solution, and Adams would be held to short steps by
stability rather than accuracy. Both families are error-controlled, so the choice changes
the work, not the accuracy. Measured (``benchmarks/bench_cvodes_options.py``, section 5):
five paper-case members after 2 s take 619 BDF steps against 1060 Adams steps for the
remaining 8 s, and after 1 s (still moving) no fewer; section 2 prints the batch's rate
without the switch (1020 against 1321 simulated s per CPU s, CasADi's
integrator; the C driver applies the same rule inside its one call)."""


def settled(xdot: np.ndarray, nominal: np.ndarray, fastest) -> np.ndarray:
    """Whether states move slower than ``fastest / SETTLED_RATIO`` (along the last axis).

    Parameters
    ----------
    xdot : ndarray, shape (..., n_state)
        State derivatives.
    nominal : ndarray, shape (..., n_state)
        State scales.
    fastest : float or ndarray
        Fastest rate of the initial linearization [1/s].
    """
    return np.max(np.abs(xdot) / nominal, axis=-1) * SETTLED_RATIO < fastest


class IntegrationFailure(RuntimeError):
    """The integrator stopped; ``states`` holds the outputs reached before it did."""

    def __init__(self, reason: str, states: np.ndarray):
        super().__init__(reason)
        self.reason = reason
        self.states = states


MAX_ORDER = 5
"""Highest order of the multistep method (CVODES's default for Adams is 12, for BDF 5).

Why: the stability region of Adams-Moulton shrinks as the order rises; on the paper's
robot the lightly damped elongation and creep modes then bound the step of orders above
five, and the error test fails more often. Measured on 60 paper-case members, 10 s,
rtol 1e-6 (``benchmarks/bench_cvodes_options.py``, section 2): 1300 against
1069 simulated seconds per CPU second for order 12, the same error against rtol 1e-10
(1.1e-5 against 1.2e-5); orders 4 and 8 in between. That was before the switch to BDF
once settled (``SETTLED_RATIO``); with it, 1321 against 1217 (CasADi's integrator; the C
driver of ``softcurve.simulation.solvers._driver`` takes the same cap)."""


def cvodes_options(
    multistep: str, rtol: float, abstol: float, max_steps: int, *, max_order=MAX_ORDER, **extra
) -> dict:
    """CasADi's CVODES options: ``multistep`` ("adams" or "bdf"), ``rtol``, one absolute
    tolerance ``abstol`` (of the scaled state), ``max_steps`` internal steps per output
    interval, the order cap ``max_order`` (None: CVODES's own) and ``extra`` options.

    Parameters
    ----------
    multistep : {"adams", "bdf"}
        The family.
    rtol : float
        Relative tolerance.
    abstol : float
        Absolute tolerance of the scaled state (a tolerance, dimensionless).
    max_steps : int
        Internal steps per output interval.
    max_order : int or None
        Highest order; None leaves CVODES's own.
    **extra : dict
        Further CasADi CVODES options.
    """
    options = {
        "linear_multistep_method": multistep,
        "reltol": rtol,
        "abstol": abstol,
        "max_num_steps": int(max_steps),
        "disable_internal_warnings": True,
        # no timing: CasADi otherwise reads the process CPU clock (a system call) around
        # every evaluation of the model, a third of a paper-case run (docs/performance.md)
        "record_time": False,
        "print_time": False,
        **extra,
    }
    if max_order is not None:
        options["max_order"] = max_order
    return options


TOO_MUCH_WORK = "too many internal steps between two output times (max_steps)"
"""Why an integrator stopped at its step budget: ``max_steps`` internal steps between two
output times, the one meaning of the budget for every method (``SimulationSettings``)."""


def cvodes_reason(text: str) -> str:
    """What a CVODES error ``text`` means, in a sentence.

    Parameters
    ----------
    text : str
        CasADi's error text.
    """
    for flag, meaning in (
        ("CV_TOO_MUCH_WORK", TOO_MUCH_WORK),
        ("CV_TOO_CLOSE", "the output interval is too short for the step size"),
        ("CV_ERR_FAILURE", "the error test failed repeatedly (step size became too small)"),
        ("CV_CONV_FAILURE", "the Newton iteration failed repeatedly"),
        ("CV_RHSFUNC_FAIL", "the right-hand side failed (non-finite values)"),
        ("CV_FIRST_RHSFUNC_ERR", "the right-hand side failed (non-finite values)"),
        ("CV_TOO_MUCH_ACC", "the tolerances are too tight for float64 arithmetic"),
        ("CV_REPTD_RHSFUNC_ERR", "the right-hand side failed (non-finite values)"),
        ("CV_LSETUP_FAIL", "the linear solver setup failed (singular Newton matrix)"),
        ("CV_LSOLVE_FAIL", "the linear solve failed"),
    ):
        if flag in text:
            return f"CVODES {flag}: {meaning}"
    return "CVODES failed: " + text.strip().splitlines()[-1][:300]


LEFT_DOMAIN = "the state left the model's domain"
"""How the reason of a run stopped by the domain check at an output time begins
(:func:`softcurve.simulation.solvers.outside_domain`, status ``LEFT_DOMAIN``)."""


def failure_status(reason: str) -> Status:
    """``LEFT_DOMAIN`` where the state left the model's domain or the right-hand side
    became non-finite, else ``INTEGRATION_FAILED``.

    Parameters
    ----------
    reason : str
        Why the run stopped.
    """
    left = "non-finite" in reason or reason.startswith(LEFT_DOMAIN)
    return Status.LEFT_DOMAIN if left else Status.INTEGRATION_FAILED


def success_message(t_final: float, family: str) -> str:
    """What a run that reached ``t_final`` [s] with the integrator ``family`` says.

    Parameters
    ----------
    t_final : float
        End time [s].
    family : str
        The integrator, e.g. ``"cvodes-adams"``.
    """
    return f"integrated to t = {t_final:.6g} s with {family}"


def failure_message(reason: str, grid: np.ndarray, reached: int, family: str) -> str:
    """Why a run stopped, where, and what to try: ``reached`` outputs of ``grid`` [s] were
    computed with the integrator ``family`` before ``reason``.

    Parameters
    ----------
    reason : str
        Why the run stopped.
    grid : ndarray, shape (T,)
        Output times [s].
    reached : int
        Number of outputs computed.
    family : str
        The integrator, e.g. ``"cvodes-adams"``.
    """
    where = (
        f"{reason}; the trajectory stops at t = {grid[reached - 1]:.6g} s "
        f"(output {reached - 1} of {grid.size - 1})"
    )
    if reason.startswith(LEFT_DOMAIN):
        return (
            f"{where}, the last output inside the domain. Likely cause: the robot is too soft "
            "for its loads or inputs (a length crossing zero or stretching without bound), "
            "or an initial rate qd0 too large for it; rarely a tolerance too loose. What to "
            "try: stiffen the robot or reduce the loads, inputs or initial rates; tighten "
            "rtol; check that the initial state and inputs are physical"
        )
    advice = ["loosen rtol/atol", "raise max_steps"]
    if family not in ("cvodes-bdf", "radau", "radau-scipy"):
        advice.insert(0, "method='bdf' or 'radau' if the problem is stiff")
    advice.append("check that the initial state and inputs are physical")
    return f"{where}. What to try: " + "; ".join(advice)
