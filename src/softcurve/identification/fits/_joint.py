"""Several experiments, one model: the joint vector of free parameters.

A fit of ``E`` experiments estimates the parameters shared by all (material, maps) once
and each parameter declared ``Free(..., per_experiment=True)`` once per experiment,
named ``name[experiment]`` (e.g. ``offset[b17]``, ``x0.lam[1][b42]``). Each experiment
has its own ``softcurve.identification.fits._parameters.FreeParameters`` (its own extra
values: its initial state, its per-experiment starting values) over the same list of
free parameters; :class:`JointParameters` maps the joint vector to each experiment's.

Each experiment is simulated on its own (never joined end to end) with its own
sensitivities; :func:`evaluate_all` evaluates them in worker processes when there are
several and ``processes > 1``.
"""

from __future__ import annotations

import re

import numpy as np

from softcurve.base.validation import ParameterError, whole_count
from softcurve.identification.experiments import Experiment
from softcurve.simulation.batch import default_threads, run_in_processes

_AMBIGUOUS = re.compile(r"^[\d, ]*$")


def experiment_list(experiment) -> tuple[list[Experiment], bool]:
    """``(experiments, single)``: a list of experiments and whether one was given bare.

    Parameters
    ----------
    experiment : Experiment or sequence of Experiment
        What the fit was given.
    """
    if isinstance(experiment, Experiment):
        return [experiment], True
    experiments = list(experiment)
    if not experiments or not all(isinstance(e, Experiment) for e in experiments):
        raise ParameterError("experiment: give an Experiment or a non-empty list of them")
    names = [e.name for e in experiments]
    if len(set(names)) != len(names):
        raise ParameterError(
            f"experiment: the names must differ (they label per-experiment parameters), "
            f"got {names}; rename with dataclasses.replace(experiment, name=...)"
        )
    bad = [n for n in names if _AMBIGUOUS.match(n)]
    if bad:
        raise ParameterError(f"experiment: names {bad} look like indices; use labels")
    return experiments, False


def split_extra(extra: dict, names: list[str]) -> tuple[dict, dict]:
    """``(shared, per)``: keys ``"name[experiment]"`` go to that experiment only.

    Parameters
    ----------
    extra : dict
        Extra parameters and their values.
    names : list of str
        The experiments' names.
    """
    shared, per = {}, {n: {} for n in names}
    for key, value in extra.items():
        head, _, tail = key.rpartition("[")
        if head and tail.endswith("]") and tail[:-1] in per:
            per[tail[:-1]][head] = value
        else:
            shared[key] = value
    return shared, per


class JointParameters:
    """The joint free vector of several experiments and each experiment's part of it.

    Parameters
    ----------
    parts : list of FreeParameters
        One per experiment, over the same list of free parameters.
    names : list of str
        The experiments' names.
    single : bool
        One experiment given bare: names carry no ``[experiment]`` suffix.
    specific : set of str, optional
        Extra parameters that are not free but set per experiment (``name[experiment]``
        keys): reported per experiment, never as shared values.
    """

    def __init__(self, parts, names, single: bool, specific=frozenset()):
        self.specific = frozenset(specific)
        free = parts[0].free
        labels, units, theta0, scale, lower, upper = [], [], [], [], [], []
        self.index = np.zeros((len(parts), len(free)), dtype=int)
        for i, f in enumerate(free):
            owners = range(len(parts)) if f.per_experiment else [0]
            for e in owners:
                for other in range(len(parts)) if not f.per_experiment else [e]:
                    self.index[other, i] = len(labels)
                part = parts[e]
                labels.append(
                    f.label if single or not f.per_experiment else f"{f.label}[{names[e]}]"
                )
                units.append(part.units[i])
                theta0.append(part.theta0[i])
                scale.append(part.scale[i])
                lower.append(part.lower[i] * part.scale[i])
                upper.append(part.upper[i] * part.scale[i])
        self.parts, self.experiments = parts, list(names)
        self.free = free
        self.names, self.units = tuple(labels), tuple(units)
        self.theta0, self.scale = np.array(theta0), np.array(scale)
        self.lower, self.upper = np.array(lower) / self.scale, np.array(upper) / self.scale

    def local(self, theta, e: int) -> np.ndarray:
        """Experiment ``e``'s free vector from the joint one.

        Parameters
        ----------
        theta : ndarray, shape (P,)
            Joint free parameters, each in its unit.
        e : int
            Index of the experiment.
        """
        return np.asarray(theta)[self.index[e]]

    def values(self, theta) -> tuple[np.ndarray, dict, dict]:
        """``(p, shared, per)``: robot vector, shared extra values, per-experiment ones.

        Parameters
        ----------
        theta : ndarray, shape (P,)
            Joint free parameters, each in its unit.
        """
        own = {t for f in self.free if f.per_experiment for t in f.targets} | self.specific
        per = {}
        for e, (part, name) in enumerate(zip(self.parts, self.experiments, strict=True)):
            p, values = part.evaluate(self.local(theta, e))
            per[name] = {k: v for k, v in values.items() if k in own}
            if e == 0:
                robot, shared = p, {k: v for k, v in values.items() if k not in own}
        return robot, shared, per


def parallel_layout(experiments: int, processes=None, threads=None) -> tuple[int, int]:
    """``(processes, threads)`` of a fit: worker processes evaluating the experiments and
    threads of each evaluation, validated.

    Parameters
    ----------
    experiments : int
        Experiments of the fit.
    processes : int, optional
        Default: one per experiment, at most the usable cores.
    threads : int, optional
        Default: the usable cores the processes leave, ``max(1, cores // processes)``.
    """
    cores = default_threads()
    processes = whole_count(
        "processes", min(experiments, cores) if processes is None else processes
    )
    threads = whole_count("threads", max(1, cores // processes) if threads is None else threads)
    return processes, threads


def _evaluate_task(evaluator, theta, outputs_only=False):
    """Worker side of :func:`evaluate_all`."""
    return evaluator.outputs(theta) if outputs_only else evaluator(theta)


def evaluate_all(evaluators, thetas, processes: int, outputs_only: bool = False) -> list:
    """``[evaluators[e](thetas[e]) for e]``, in worker processes when ``processes > 1``.

    An evaluation error in a worker is raised here, as it would be in this process.

    Parameters
    ----------
    evaluators : list of callable
        One picklable evaluator per experiment.
    thetas : list of ndarray, each of shape (P_e,)
        Each experiment's free vector, each entry in the unit of its parameter.
    processes : int
        Worker processes (1: evaluate here, in order).
    outputs_only : bool
        The outputs alone, ``evaluators[e].outputs(thetas[e])`` (see
        :func:`outputs_alone`), instead of the outputs with their Jacobian.
    """
    if processes <= 1 or len(evaluators) == 1:
        return [
            _evaluate_task(f, theta, outputs_only)
            for f, theta in zip(evaluators, thetas, strict=True)
        ]
    tasks = {
        e: (f, theta, outputs_only)
        for e, (f, theta) in enumerate(zip(evaluators, thetas, strict=True))
    }
    done = dict(run_in_processes(_evaluate_task, tasks, min(processes, len(tasks))))
    return [done[e] for e in range(len(evaluators))]


def outputs_alone(evaluators) -> bool:
    """Whether every evaluator computes its outputs alone for a fraction of the cost of
    the outputs with their Jacobian (an ``outputs_alone`` attribute that is true, and a
    method ``outputs(theta) -> Y``): then a fit evaluates its trial points without the
    Jacobian, and the Jacobian only at the points it accepts.

    Parameters
    ----------
    evaluators : list of callable
        One per experiment.
    """
    return bool(evaluators) and all(getattr(f, "outputs_alone", False) for f in evaluators)
