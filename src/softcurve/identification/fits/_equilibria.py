"""Quasi-static predictions for the equilibrium fit, with their exact Jacobian.

Each sample of an experiment is a static equilibrium ``N(q; p) = tau(q, u; values)``,
solved by the package's one equilibrium solver for many equilibria at once
(:func:`softcurve.analysis.solver.solve_equilibria`), each sample starting from its
solution at the previous evaluation of the fit (parameters change little between two
evaluations). At the first evaluation a long record starts from equilibria of its own:
about ``sqrt(T)`` samples spread over the record are solved first, from the given
initial guess, and every sample starts from the solution of the one among them whose
inputs are nearest its own (a robot with one equilibrium per input has nearby
equilibria at nearby inputs; along a slowly varying record that is the previous such
sample). A robot with several equilibria at one input (snap-through, buckling) may then
land on another branch than Newton's method from the initial guess would: the branch
of the nearest solved sample, as a sweep that follows its branch would. The implicit function
theorem gives the derivative of each solution with respect to the parameters,
``dq/dd = -K^-1 dr/dd`` with ``K = dr/dq``, and the chain rule the Jacobian of the
outputs; the derivatives come from CasADi, evaluated for all samples in one call (split
over the cores).
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import scipy.spatial

from softcurve.analysis.loads import coordinate_scale, residual_reference
from softcurve.analysis.solver import solve_equilibria
from softcurve.compiled import compile_function, compile_functions
from softcurve.description.domain import state_problem, states_inside
from softcurve.simulation.batch import default_threads
from softcurve.simulation.solvers import mapped

EQUILIBRIUM_TOLERANCE = 1e-10
"""Scaled residual accepted at every sample (as :func:`softcurve.equilibrium`'s default)."""

MAX_EVALUATIONS = 400
"""Residual evaluations allowed per sample and start."""

TANGENT_LIMIT = 0.25
"""Largest move along the solutions' tangent, relative to each coordinate's natural size
(:func:`~softcurve.analysis.loads.coordinate_scale`), taken as the next evaluation's
start; beyond it the first-order prediction is not trusted (near a fold, or after a far
jump of the parameters as a multi-start makes, it can throw the start out of the model's
domain) and the previous solution is the start. The fits of
``benchmarks/bench_identification.py`` move at most 0.02 (their first step, from a start
10 % off), so the bound leaves them twelve times the room."""


COMPILED_MIN = 1000
"""Records of this many samples or more are fitted with the balance and its
sensitivities compiled as the model is (CasADi's virtual machine where there is no
compiler), shorter ones in CasADi's virtual machine. Compiled, an evaluation of the
31,329 samples of ``benchmarks/bench_identification_trials.py`` (case equilibrium)
takes 1.2-1.4 s instead of 3.7 s, about 75 us less per sample, for about 3 s of the
compiler once per structure (a first fit of 4.6 s): the compiler pays from about 40,000
sample-evaluations on, e.g. 1,000 samples over 40 evaluations of a fit."""

WARM_START_MIN = 256
"""Records of fewer samples start every sample from the initial guess: there, solving
``sqrt(T)`` of them first costs more than it saves. The first evaluation of the tests'
one-segment sweep (``python benchmarks/study_warm_start.py``), with against without:
16.4 against 12.4 ms at 128 samples, 19.1 against 24.7 at 256, 27.6 against 36.9 at 400
and 56.7 against 90.0 at 999 in CasADi's virtual machine; from :data:`COMPILED_MIN` on,
where the functions are compiled and a Newton step is cheap, it saves less (29.3
against 30.8 ms at 1,000, 477 against 506 at 16,000)."""


def nearest_starts(inputs: np.ndarray, solved: np.ndarray) -> np.ndarray:
    """For every sample, the index (into ``solved``) of the solved sample whose inputs
    are nearest its own, each input measured in its range over the record.

    Parameters
    ----------
    inputs : ndarray, shape (T, m)
        The record's inputs [unit of each input].
    solved : ndarray of int, shape (C,)
        The samples solved (indices into ``inputs``), C >= 1.

    Returns
    -------
    ndarray of int, shape (T,)
        Indices into ``solved``.
    """
    if inputs.shape[1] == 0:  # no inputs: every sample has the same equilibrium
        return np.zeros(inputs.shape[0], dtype=int)
    span = np.ptp(inputs, axis=0)
    unit = inputs / np.where(span > 0, span, 1.0)
    return scipy.spatial.cKDTree(unit[solved]).query(unit)[1]


class EquilibriumPredictor:
    """``experiment -> evaluate(theta) -> (Y (k, T), dvec(Y)/dtheta (k T, P))``.

    Parameters
    ----------
    model : Model
        The compiled model.
    parameters : FreeParameters
        The free parameters and how they enter ``p`` and the extra values.
    output : OutputMap
        The measured signals.
    input_map : InputMap or None
        Generalized forces from the experiment's inputs.
    q0 : array_like, shape (n,)
        Initial guess of every sample at the first evaluation [m, 1/m, 1/m].
    """

    def __init__(self, model, parameters, output, input_map, q0):
        self.model, self.parameters = model, parameters
        self.output, self.input_map = output, input_map
        self.q0 = np.asarray(q0, dtype=np.float64)
        self.scale = coordinate_scale(model.robot)
        self.reference = residual_reference(model)

    def __call__(self, experiment):
        model, P = self.model, self.parameters
        n, n_p = model.n, P.p0.size
        keys = sorted(P.extra)
        theta = ca.MX.sym("theta", len(P.free))
        p, values = P.expressions(theta)
        d = ca.vertcat(p, *(ca.MX(values[k]) for k in keys))
        jac_d = ca.jacobian(d, theta)
        # only the entries of d that depend on the free parameters: a robot of several
        # segments has several times the parameters, most of them fixed
        active = sorted(set(jac_d.sparsity().get_triplet()[0]))
        direct = ca.Function("direct", [theta], [d, ca.densify(jac_d[active, :])])

        u_names = list(experiment.inputs)
        samples = experiment.t.size
        balance, residual_function, sensitivity_function = self._functions(
            keys, n_p, len(u_names), active, compiled=samples >= COMPILED_MIN
        )
        # the samples split over the cores: 1.7x on two for three segments, 1.4x for one
        # (measured in CasADi's virtual machine; python benchmarks/bench_identification.py)
        threads = default_threads()
        balance_all, residual_all, sensitivities = (
            mapped(f, samples, threads) for f in (balance, residual_function, sensitivity_function)
        )
        inputs = experiment.input_matrix(u_names) if u_names else np.zeros((experiment.t.size, 0))
        last = np.tile(self.q0[:, None], (1, samples))
        # the stiffness at the last solutions, for the chord steps of the next evaluation,
        # and the solutions' tangent (dq/dd (T, n, n_d) at the active entries of d)
        last_stiffness, tangent = [], []

        def batch_system(q_all, d_value, function=balance_all, rows=slice(None)):
            """``(R (n, W), K (W, n, n))`` of ``function``, ``balance`` mapped over the
            ``W`` samples ``rows`` (all of them by default)."""
            r, k = function(q_all, inputs[rows].T, d_value)
            k = np.array(k, dtype=np.float64).reshape(n, q_all.shape[1], n).transpose(1, 0, 2)
            return np.array(r, dtype=np.float64), k

        at_start = np.tile(self.q0[:, None], (1, samples))
        robot = model.robot
        actuator = None if self.input_map is None else self.input_map.actuator

        def system_of(j, d_value):
            def system(q_value):
                r, k = balance(q_value, inputs[j], d_value)
                return np.array(r, dtype=np.float64).ravel(), np.array(k, dtype=np.float64)

            return system

        options = dict(scale=self.scale, reference=self.reference, tol=EQUILIBRIUM_TOLERANCE)

        def warm_start(d_value):
            """``(Q (n, T), K (T, n, n))`` at the first evaluation: every sample starts
            from the solution, and its chord steps from the stiffness, of the sample of
            nearest inputs among about ``sqrt(T)`` solved first (the module's
            docstring); None for a short record or where none of them is solved."""
            if samples < WARM_START_MIN:
                return None
            spread = np.linspace(0, samples - 1, int(np.ceil(np.sqrt(samples))))
            solved = np.unique(spread.round().astype(int))
            some = functools.partial(
                batch_system, d_value=d_value, function=mapped(balance, solved.size, threads),
                rows=solved,
            )  # fmt: skip
            roots = solve_equilibria(
                some,
                lambda j: system_of(solved[j], d_value),
                at_start[:, solved],
                max_evaluations=MAX_EVALUATIONS,
                **options,
            )
            q_some = np.array([root.q for root in roots])
            good = np.array([root.converged for root in roots])
            good &= states_inside(robot, q_some, actuator)
            if not good.any():
                return None
            nearest = nearest_starts(inputs, solved[good])
            q_good = np.where(good[:, None], q_some, q_some[good][0])  # K at solutions only
            k_good = some(q_good.T)[1][good]
            return q_some[good][nearest].T, k_good[nearest]

        def starts(d_value) -> list[tuple[np.ndarray, np.ndarray | None]]:
            """Where the equilibria start, in turn for the samples not solved yet, with
            the stiffness for chord steps from there (None: Newton's method from the
            start): the previous solutions moved along their tangent (first-order
            prediction: the chord steps start O(|change of d|^2) from the new solutions
            instead of O(|change of d|)) where that move is small, then the previous
            solutions, then the initial guess. At the first evaluation, the solutions of
            samples of nearby inputs come first (:func:`warm_start`)."""
            chord = last_stiffness[0] if last_stiffness else None  # chord steps pay near
            found = [(last, chord), (at_start, None)]
            if tangent:
                previous_d, dq_dd = tangent
                move = (dq_dd @ (d_value - previous_d)[active]).T  # (n, T)
                near = np.max(np.abs(move) / self.scale[:, None], axis=0) <= TANGENT_LIMIT
                found.insert(0, (last + np.where(near, move, 0.0), chord))
            elif chord is None:
                warm = warm_start(d_value)
                if warm is not None:
                    found.insert(0, warm)
            unique = []
            for start, k in found:
                if not any(np.array_equal(start, other) for other, _ in unique):
                    unique.append((start, k))
            return unique

        def solve(d_value) -> np.ndarray:
            def batch_residual(q_all):
                return np.array(residual_all(q_all, inputs.T, d_value), dtype=np.float64)

            system_all = functools.partial(batch_system, d_value=d_value)
            accepted, roots = [None] * samples, []
            for start, chord in starts(d_value):
                roots = solve_equilibria(
                    system_all,
                    functools.partial(system_of, d_value=d_value),
                    start,
                    max_evaluations=MAX_EVALUATIONS,
                    jacobians=chord,
                    batch_residual=None if chord is None else batch_residual,
                    **options,
                )
                # a root outside the model's or the actuator's domain (a start thrown
                # far) is no equilibrium
                inside = states_inside(robot, np.array([root.q for root in roots]), actuator)
                for j, root in enumerate(roots):
                    if accepted[j] is None and root.converged and inside[j]:
                        accepted[j] = root
                if all(root is not None for root in accepted):
                    break
            tangent.clear()  # until evaluate sets this evaluation's
            failed = [j for j, root in enumerate(accepted) if root is None]
            if failed:
                j = failed[0]
                reason = (
                    roots[j].message
                    if not roots[j].converged
                    else "its equilibrium lies outside the model's domain: "
                    + str(state_problem(model.robot, roots[j].q, actuator))
                )
                raise RuntimeError(
                    f"no equilibrium found at {len(failed)} sample(s), the first {j} "
                    f"(t = {experiment.t[j]:g} s): {reason}; the robot may snap through or "
                    "buckle there"
                )
            solution = np.column_stack([root.q for root in accepted])
            last[:] = solution
            return solution

        def evaluate(theta_value):
            d_value, d_jacobian = (np.array(v, dtype=np.float64) for v in direct(theta_value))
            d_value = d_value.ravel()
            q_all = solve(d_value)
            y_all, r_d, y_q, y_d = (
                np.array(v, dtype=np.float64) for v in sensitivities(q_all, inputs.T, d_value)
            )
            n_d, n_y = len(active), y_all.shape[0]
            k = batch_system(q_all, d_value)[1]  # K at the solutions
            last_stiffness[:] = [k]
            r_d = r_d.reshape(n, samples, n_d).transpose(1, 0, 2)
            y_q = y_q.reshape(n_y, samples, n).transpose(1, 0, 2)
            y_d = y_d.reshape(n_y, samples, n_d).transpose(1, 0, 2)
            # implicit function theorem: dq/dd = -K^-1 dr/dd, per sample
            dq_dd = -np.linalg.solve(k, r_d)
            tangent[:] = [d_value, dq_dd]
            total = y_d + y_q @ dq_dd
            jacobian = (total @ d_jacobian).reshape(samples * n_y, -1)
            return y_all, jacobian

        return evaluate

    def _functions(self, keys, n_p, n_u, active, compiled=False):
        """``(balance, residual, sensitivities)``: per-sample Functions of ``(q, u, d)``,
        SX or, with ``compiled``, compiled (:func:`~softcurve.compiled.compile_function`),
        kept with the model (the Hessian of a three-segment robot takes 0.1 s to build; a
        joint fit builds it once for all its experiments), keyed by the maps' expressions
        themselves (serialized), not by their Python functions: a map that reads a value
        changed since the last fit gets new functions."""
        model, n = self.model, self.model.n
        q, u, ds = ca.SX.sym("q", n), ca.SX.sym("u", n_u), ca.SX.sym("d", n_p + len(keys))
        p_s, v_s = ds[:n_p], {k: ds[n_p + i] for i, k in enumerate(keys)}
        tau = ca.SX.zeros(n) if self.input_map is None else self.input_map.function(q, u, v_s)
        forces = ca.Function("tau", [q, u, ds], [tau])
        y = self.output.function(q, ca.SX.zeros(n), v_s, p_s)
        outputs = ca.Function("y", [q, u, ds], [y])

        def balance_functions():
            gravity_energy = model.symbolic["potential_energy"](q, p_s)[0]
            # K from the symmetric Hessian of V_g: half the operations of the Jacobian of
            # G on three segments (benchmarks/bench_identification.py, section 2)
            gravity_stiffness, gravity = ca.hessian(gravity_energy, q)
            elastic = model.symbolic["elastic_force"](q, p_s) - tau
            residual = gravity + elastic
            stiffness = gravity_stiffness + ca.jacobian(elastic, q)
            return (
                ca.Function("balance", [q, u, ds], [residual, stiffness]),
                ca.Function("residual", [q, u, ds], [residual]),
            )

        structure = (forces.serialize(), n_p)
        balance, residual = model.cached(("equilibrium-fit", *structure), balance_functions)

        def sensitivity_function():
            # the balance's own expressions, on its symbols
            q_b, u_b, d_b = balance.sx_in()
            r_b = balance(q_b, u_b, d_b)[0]
            y_b = outputs(q_b, u_b, d_b)
            moving = ca.vertcat(*(d_b[i] for i in active)) if active else ca.SX(0, 1)
            columns = [y_b, ca.jacobian(r_b, moving), ca.jacobian(y_b, q_b)]
            columns.append(ca.jacobian(y_b, moving))
            return ca.Function("sensitivities", [q_b, u_b, d_b], columns)

        key = ("equilibrium-fit-sensitivities", *structure, outputs.serialize(), tuple(active))
        sensitivities = model.cached(key, sensitivity_function)
        if not compiled:
            return balance, residual, sensitivities
        compiled_balance, compiled_residual = model.cached(
            ("equilibrium-fit-compiled", *structure),
            lambda: tuple(compile_functions([balance, residual])),
        )
        compiled_sensitivities = model.cached(
            (*key, "compiled"), lambda: compile_function(sensitivities)
        )
        return compiled_balance, compiled_residual, compiled_sensitivities
