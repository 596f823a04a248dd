"""The least-squares problem every fit of :mod:`softcurve.identification.fits` solves.

:class:`Problem` gathers the experiments, the free parameters (shared and per
experiment, ``softcurve.identification.fits._joint``), the weights
(``softcurve.identification.fits._weights``) and one evaluator per experiment
(``theta_e -> (Y_e (k, T_e), dvec(Y_e)/dtheta_e)``), and solves with the robust solver
(``softcurve.identification.fits._solve``), optionally from several starts, showing
progress on request. The report stacks the experiments' samples one after another
(:attr:`FitReport.parts` says where each begins).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from softcurve.base.progress import ProgressLine
from softcurve.base.status import Status
from softcurve.base.validation import ParameterError, whole_count
from softcurve.identification.experiments import check_units
from softcurve.identification.fits._joint import (
    JointParameters,
    evaluate_all,
    experiment_list,
    outputs_alone,
    split_extra,
)
from softcurve.identification.fits._parameters import Free, FreeParameters
from softcurve.identification.fits._report import FitReport, summarize
from softcurve.identification.fits._solve import (
    EVALUATION_ERRORS,
    SETTLED,
    robust_least_squares,
    starting_points,
)
from softcurve.identification.fits._weights import weight_matrix
from softcurve.simulation.batch import WorkerDied

AT_BOUND = 1e-8
"""Relative distance to a bound under which an estimate is reported as at the bound."""


def _signals(experiment, output, signals):
    names = list(output.names) if signals is None else list(signals)
    if len(names) != len(output.names):
        raise ParameterError(
            f"signals: the output map gives {len(output.names)} outputs {output.names}, "
            f"got {len(names)} signal names {names}"
        )
    return names, experiment.signal_matrix(names)


class FitData(NamedTuple):
    """What a fit compares its outputs with (:meth:`Problem.data`)."""

    names: list
    """The signals' names."""
    measured: list
    """Each experiment's measured values, shape (T, k)."""
    w: list
    """Each experiment's residual weights, shape (T k,)."""

    @property
    def values(self) -> int:
        """The data values that enter the residuals: finite, with a nonzero weight."""
        return sum(
            int(np.count_nonzero(np.isfinite(m).ravel() & (weight != 0)))
            for m, weight in zip(self.measured, self.w, strict=True)
        )


class Problem:
    """Experiments, free parameters and their starting values, for one fit.

    Parameters
    ----------
    model : Model
        The compiled model.
    output : OutputMap
        Measured signals.
    input_map : InputMap or None
        Generalized forces from the inputs.
    free : sequence of Free or str
        What is estimated.
    extra : dict or None
        Extra parameters; ``"name[experiment]"`` keys for one experiment only.
    bind : dict or None
        Robot parameter name -> ``rule(values)``.
    p : array_like, optional
        Robot parameter vector to start from.
    experiment : Experiment or sequence of Experiment
        The data.
    starts : callable, optional
        ``starts(experiment, names) -> dict`` of starting values of the extra
        parameters the experiment itself sets (its initial-state entries).
    """

    def __init__(self, model, output, input_map, free, extra, bind, p, experiment, starts=None):
        self.model, self.output, self.input_map = model, output, input_map
        problem = output.robot_problem(model.robot) if output.robot_problem else None
        if problem is not None:
            raise ParameterError(f"output: {problem}")
        if input_map is not None and input_map.robot_problem is not None:
            problem = input_map.robot_problem(model.robot)
            if problem is not None:
                raise ParameterError(f"input map: {problem}")
        self.experiments, single = experiment_list(experiment)
        names = [e.name for e in self.experiments]
        shared, per = split_extra(dict(extra or {}), names)
        maps = {**output.parameters, **(input_map.parameters if input_map else {})}
        free = [f if isinstance(f, Free) else Free(f) for f in free]
        wanted = {t for f in free for t in f.targets} | set(shared)
        fixed = input_map.fixed_fields(model.robot) if input_map and input_map.fixed_fields else ()
        held = sorted(
            t
            for t in wanted
            for name in fixed
            if t == name or t.startswith((name + "[", name + "."))
        )
        if held:
            raise ParameterError(
                f"free: {held[0]} shapes the actuator's fibers, laid along the robot it was "
                "built with; fit it without the actuator's input map, or hold it fixed"
            )
        parts = []
        for e in self.experiments:
            own = starts(e, wanted | set(per[e.name])) if starts else {}
            values = {**maps, **own, **shared, **per[e.name]}
            parts.append(FreeParameters(model, free, values, bind or {}, p))
        specific = {name for values in per.values() for name in values}
        self.parameters = JointParameters(parts, names, single, specific)

    def data(self, signals, weights) -> FitData:
        """The signals' names, each experiment's measured values and its residual
        weights, units checked: what :meth:`too_few` and :meth:`run` take.

        Parameters
        ----------
        signals : list of str or None
            Signals matched to the outputs.
        weights : see ``softcurve.identification.fits._weights``
            Residual weights.
        """
        names, measured, w = [], [], []
        if isinstance(weights, dict):
            unknown = sorted(set(weights) - {e.name for e in self.experiments})
            if unknown:
                raise ParameterError(
                    f"weights: a dict is per experiment, but {unknown} are not experiments "
                    f"of this fit ({[e.name for e in self.experiments]})"
                )
        for e in self.experiments:
            per = weights.get(e.name) if isinstance(weights, dict) else weights
            names, values = _signals(e, self.output, signals)
            check_units(e, output=self.output, input_map=self.input_map, signals=names)
            measured.append(values)
            w.append(weight_matrix(per, e.t, len(names), e.name).ravel())
        return FitData(names, measured, w)

    def too_few(self, data: FitData) -> bool:
        """Whether the free parameters outnumber the data values that enter the
        residuals (finite, nonzero weight): the Jacobian is then rank-deficient at every
        point, which no evaluation can change, and the fit is not identifiable.

        Parameters
        ----------
        data : FitData
            :meth:`data`'s.
        """
        return len(self.parameters.names) > data.values

    def run(self, evaluators, data, max_evaluations, confidence, kind, *, options) -> FitReport:
        """Fit (or, with nothing free, predict) and report.

        Parameters
        ----------
        evaluators : list of callable
            One per experiment: ``theta_e -> (Y (k, T), dvec(Y)/dtheta_e (k T, P_e))``.
        data : FitData
            :meth:`data`'s: the measured signals and their weights.
        max_evaluations : int
            Budget of residual evaluations per start.
        confidence : float
            Confidence level of the intervals.
        kind : str
            "trajectory fit" or "equilibrium fit", for messages.
        options : dict
            ``starts``, ``seed``, ``progress``, ``processes``.
        """
        J, experiments = self.parameters, self.experiments
        n_starts = whole_count("starts", options.get("starts", 1))
        processes = whole_count("processes", options.get("processes", 1))
        names, measured, w = data
        size = len(J.names)
        data_values = data.values
        too_few = self.too_few(data)

        def evaluate(theta, outputs_only=False):
            thetas = [J.local(theta, e) for e in range(len(experiments))]
            return evaluate_all(evaluators, thetas, processes, outputs_only)

        latest: list = []  # the outputs of the last evaluation
        kept: dict = {}  # start -> the outputs at its best point: the estimate not rerun

        def residuals_of(outputs):
            """The weighted residuals of every experiment's outputs ``Y (k, T)``."""
            return np.concatenate(
                [(np.asarray(y).T - measured[e]).ravel() * w[e] for e, y in enumerate(outputs)]
            )

        def residual_and_jacobian(z):
            columns = []
            results = evaluate(z * J.scale)
            for e, (_, jac) in enumerate(results):
                full = np.zeros((w[e].size, size))
                full[:, J.index[e]] = jac * w[e][:, None]
                columns.append(full)
            latest[:] = [np.asarray(y).T for y, _ in results]
            return residuals_of([y for y, _ in results]), np.vstack(columns) * J.scale

        def residuals(z):
            return residuals_of(evaluate(z * J.scale, outputs_only=True))

        points = starting_points(
            J.theta0 / J.scale, J.lower, J.upper, n_starts, options.get("seed")
        )
        bar = ProgressLine(
            max_evaluations * n_starts,
            show=bool(options.get("progress")) and size > 0,
            unit="evaluations",
            label=kind,
        )
        solutions = []
        for k, z0 in enumerate(points if size and not too_few else []):
            offset = k * max_evaluations
            solutions.append(
                robust_least_squares(
                    residual_and_jacobian,
                    z0,
                    J.lower,
                    J.upper,
                    max_evaluations,
                    on_evaluation=lambda c, o=offset: bar.update(o + c),
                    on_best=lambda k=k: kept.__setitem__(k, list(latest)),
                    settle=SETTLED,
                    residual=residuals if outputs_alone(evaluators) else None,
                )
            )
            if solutions[-1].status is Status.INTERRUPTED:  # a fault: do not start again
                break
        bar.close()
        if solutions:
            k_best = min(range(len(solutions)), key=lambda k: solutions[k].cost)
            best = solutions[k_best]
            z, status, message = best.z, best.status, best.message
            if solutions[-1].status is Status.INTERRUPTED:
                status, message = Status.INTERRUPTED, solutions[-1].message
                if best.residuals is not None:
                    message += "; the values are the best point found before"
            count = sum(s.n_evaluations for s in solutions)
            jacobians = sum(s.n_jacobians for s in solutions)
        elif too_few:
            z, status, count, jacobians = J.theta0 / J.scale, Status.NOT_IDENTIFIABLE, 0, 0
            message = (
                f"{size} free parameters on {data_values} data values (signal samples with "
                f"a nonzero weight): not identifiable, nothing integrated; fix at least "
                f"{size - data_values} of them or add data; the values are the starting "
                "values"
            )
        else:
            z, status, message, count = np.zeros(0), Status.SUCCESS, "nothing to fit", 0
            jacobians = 0
        theta = z * J.scale
        try:
            if too_few:  # nothing evaluated
                predicted = [np.full_like(m, np.nan) for m in measured]
                r, jac = np.zeros(0), np.zeros((0, size))
            elif solutions and best.residuals is None:  # nothing could be evaluated
                raise RuntimeError("no point could be evaluated")
            elif solutions:  # the best point, evaluated in the fit
                r, jac, predicted = best.residuals, best.jacobian, kept[k_best]
            else:  # a prediction: nothing free
                r, jac = residual_and_jacobian(z)
                count, jacobians, predicted = count + 1, jacobians + 1, latest
            jac = jac / J.scale
        except EVALUATION_ERRORS as exc:
            if not (solutions and best.residuals is None):
                message += f"; the model could not be evaluated at the estimate: {exc}"
            interrupted = isinstance(exc, WorkerDied) or status is Status.INTERRUPTED
            status = Status.INTERRUPTED if interrupted else Status.NOT_CONVERGED
            predicted = [np.full_like(m, np.nan) for m in measured]
            r, jac = np.zeros(0), np.zeros((0, size))
        if too_few:
            errors, corr = np.full(size, np.inf), np.full((size, size), np.nan)
            identifiable = np.zeros(size, bool)
        else:
            errors, corr, identifiable, status, message = summarize(
                J.names, theta, jac, r, status, message
            )
        at_bound = [
            name
            for name, v, lo, hi in zip(J.names, z, J.lower, J.upper, strict=True)
            if min(abs(v - lo), abs(v - hi)) <= AT_BOUND * max(1.0, abs(v))
        ]
        if at_bound:
            message += f"; at a bound (interval not meaningful there): {at_bound}"
        p_value, shared, per = J.values(theta)
        if len(experiments) == 1:  # one experiment: all its values, as before joint fits
            shared = {**shared, **per[experiments[0].name]}
        try:
            robot = self.model.robot.with_parameter_vector(p_value)
        except ParameterError as exc:
            robot, status = None, Status.INFEASIBLE
            message += f"; the estimate is not an admissible robot: {exc}"
        finished = [s for s in solutions if s.status is not Status.INTERRUPTED]  # optima
        optima = np.array([s.z * J.scale for s in finished]) if n_starts > 1 else None
        costs = np.array([s.cost for s in finished]) if n_starts > 1 else None
        return FitReport(
            status=status,
            message=f"{kind}: {message}",
            names=J.names,
            parameter_units=J.units,
            values=theta,
            standard_errors=errors,
            correlation=corr,
            abscissa=np.concatenate([e.t for e in experiments]),
            measured=np.vstack(measured),
            predicted=np.vstack(predicted),
            signals=tuple(names),
            units=tuple(
                experiments[0].units.get(n) or u
                for n, u in zip(names, self.output.units, strict=True)
            ),
            confidence=confidence,
            n_evaluations=count,
            n_jacobians=jacobians,
            identifiable=identifiable,
            parts=tuple((e.name, e.t.size) for e in experiments),
            optima=optima,
            optimum_costs=costs,
            extra={"robot": robot, "parameters": p_value, "values": shared, "per_experiment": per},
        )
