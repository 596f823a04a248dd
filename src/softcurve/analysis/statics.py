"""Equilibria and their stability (section 4.2 of the paper).

An equilibrium solves ``N(q) = tau + H(q) u + J_tip(q)^T w`` for constant generalized
forces ``tau``, constant actuator inputs ``u`` (pressures, tensions) through an
:class:`~softcurve.description.actuator.Actuator` and a constant tip wrench
``w = (f, m)`` given in the world frame. The gravity direction may be changed for the
analysis (``gravity=``) without recompiling: it is a run-time parameter of the model.

Stability is read from the tangent stiffness ``K = d/dq (N - loads)``. Gravity,
elasticity, constant ``tau``, constant actuator inputs (``p_i dV_i`` is exact for
pressures, ``-T . dL`` for tensions without friction) and a constant
world tip force (potential ``-f . p_tip``) are conservative, so ``K`` is the Hessian of
the total potential and is symmetric: all eigenvalues positive is a strict local
minimum (``"stable"``), all negative a local maximum (``"unstable"``), mixed signs a
``"saddle"``, and a zero eigenvalue that no symmetry explains ``"degenerate"``. A
constant world tip moment is not conservative in three dimensions (rotations do not
commute): it enters ``K`` through ``d(J_w^T m)/dq``, which is not symmetric, and the
classification is then by the real parts of ``K``'s eigenvalues (static divergence
only); the eigenvalues of :func:`linearize`'s ``A`` decide the dynamic stability. Tendons
with friction are not conservative either and are classified the same way.

Continua: when the loads are symmetric about the base axis (gravity along it, no
lateral load), a bent equilibrium rotated about the axis is again an equilibrium. Each
solution is tested for this directly, by evaluating the residual on the rotated
configurations; such a solution is reported once as a ``"ring"`` (its representative
bends toward +x) and classified by ``K`` on the complement of the ring's tangent.

Coordinates are compared in the scaled units ``z = (l / l0, kx l0, ky l0)`` per segment,
and residuals as ``S r`` [J] with ``S = diag(l0, 1/l0, 1/l0)``, relative to the elastic
stiffness of each coordinate at rest; :mod:`softcurve.analysis.solver` solves them.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import scipy.linalg

from softcurve.analysis.equilibrium_results import Equilibrium, EquilibriumTable
from softcurve.analysis.linear import Linearization, linearize
from softcurve.analysis.loads import (
    StaticLoad,
    coordinate_scale,
    residual_reference,
    rest_configuration,
    static_balance,
)
from softcurve.analysis.solver import Root, solve_equilibrium
from softcurve.base.status import Status
from softcurve.base.validation import ParameterError, random_seed, real_array, whole_count
from softcurve.description.domain import checked_status, state_problem

__all__ = [
    "Equilibrium",
    "EquilibriumTable",
    "Linearization",
    "StaticLoad",
    "default_bounds",
    "equilibria",
    "equilibrium",
    "linearize",
    "planar_pairs",
    "rotate_about_axis",
]


class _Problem:
    """Residual, tangent and scaling of one static problem."""

    def __init__(self, load: StaticLoad):
        self.load = load
        self.model = load.model
        self.function = static_balance(load)
        self.scale = coordinate_scale(self.model.robot)
        self.reference = residual_reference(self.model)
        self.evaluations = 0

    def evaluate(self, q):
        self.evaluations += 1
        r, k, w, tip = self.function(q, *self.load.arguments())
        return (
            np.array(r, dtype=np.float64).ravel(),
            np.array(k, dtype=np.float64).reshape(self.model.n, self.model.n),
            float(np.asarray(w, dtype=np.float64).reshape(-1)[0]),
            np.array(tip, dtype=np.float64).ravel(),
        )

    def system(self, q):
        """``(r, K)`` at ``q``, for :func:`~softcurve.analysis.solver.solve_equilibrium`."""
        r, k, *_ = self.evaluate(q)
        return r, k

    def scaled_residual(self, q) -> np.ndarray:
        """``S r / reference``: dimensionless, compared with ``tol``."""
        r, *_ = self.evaluate(q)
        return self.scale * r / self.reference

    def solve(self, q0, tol: float, max_evaluations: int) -> Root:
        """The root nearest (in the solver's sense) to ``q0``."""
        return solve_equilibrium(
            self.system,
            q0,
            scale=self.scale,
            reference=self.reference,
            tol=tol,
            max_evaluations=max_evaluations,
        )


def planar_pairs(robot) -> np.ndarray | None:
    """The pairs of coordinates of ``robot`` that turn as vectors of the base's xy plane
    when the robot turns about its base axis, each element's ``planar_pairs`` at its
    offset: rows ``(i, j, reference x, reference y)``, shape (k, 4); None where an element
    cannot be turned in its coordinates (no ring is then looked for).

    Parameters
    ----------
    robot : Robot
        The robot.
    """
    rows = []
    for segment, offset in zip(robot.segments, robot.offsets, strict=True):
        pairs = segment.planar_pairs
        if pairs is None:
            return None
        rows += [(offset + i, offset + j, *reference) for i, j, reference in pairs]
    return np.array(rows, dtype=np.float64).reshape(-1, 4)


def rotate_about_axis(q, angle: float, robot=None) -> np.ndarray:
    """``q`` with the robot turned by ``angle`` about its base z axis: every pair of
    :func:`planar_pairs` (a constant-curvature segment's ``(kx, ky)``, a constant-strain
    segment's bending and shear) rotated by ``angle``.

    Parameters
    ----------
    q : array_like, shape (n,)
        Configuration.
    angle : float
        Rotation [rad], counterclockwise seen from +z.
    robot : Robot, optional
        The robot; default a robot of constant-curvature segments, ``(l, kx, ky)`` each.

    Raises
    ------
    ParameterError
        Where an element of ``robot`` cannot be turned in its coordinates.
    """
    q = np.array(q, dtype=np.float64)
    if robot is None:
        pairs = _curvature_pairs(q.size)
    else:
        pairs = planar_pairs(robot)
        if pairs is None:
            raise ParameterError(
                "the robot cannot be turned about its axis in its coordinates: an element "
                "chooses one strain of a pair (bend_x, bend_y) or (shear_x, shear_y) alone"
            )
    return _turned(q, pairs, angle)


def _curvature_pairs(n: int) -> np.ndarray:
    """:func:`planar_pairs` of a robot of ``n // 3`` constant-curvature segments."""
    first = np.arange(1, n, 3)  # constant curvature: (l, kx, ky) per segment
    return np.column_stack([first, first + 1, np.ones(first.size), np.zeros(first.size)])


def _turned(q, pairs: np.ndarray, angle: float) -> np.ndarray:
    q = np.array(q, dtype=np.float64)
    i, j = pairs[:, 0].astype(int), pairs[:, 1].astype(int)
    c, s = np.cos(angle), np.sin(angle)
    x, y = q[i].copy(), q[j].copy()
    q[i], q[j] = c * x - s * y, s * x + c * y
    return q


def _ring_tangent(q, pairs: np.ndarray) -> np.ndarray:
    i, j = pairs[:, 0].astype(int), pairs[:, 1].astype(int)
    tangent = np.zeros_like(q)
    tangent[i], tangent[j] = -q[j], q[i]
    return tangent


# -- solving ----------------------------------------------------------------------------
def _classify(problem: _Problem, q, tangent_stiffness, ring, zero_tolerance: float):
    """``ring``: the robot's :func:`planar_pairs` where ``q`` is on a ring, else None."""
    scale = problem.scale
    k = scale[:, None] * tangent_stiffness * scale[None, :]
    symmetric = problem.load.conservative  # K is then a Hessian (module docstring)
    if ring is not None:
        v = _ring_tangent(q, ring) / scale
        basis = scipy.linalg.null_space(v[None, :])
        k = basis.T @ k @ basis
    if symmetric:
        eigenvalues = np.linalg.eigvalsh(0.5 * (k + k.T))
    else:
        eigenvalues = np.sort(np.linalg.eigvals(k).real)
    zero = np.abs(eigenvalues) <= zero_tolerance * problem.reference.max()
    if zero.any():
        return "degenerate", eigenvalues
    if np.all(eigenvalues > 0):
        return "stable", eigenvalues
    if np.all(eigenvalues < 0):
        return "unstable", eigenvalues
    return "saddle", eigenvalues


def _is_ring(problem: _Problem, q, tol: float, distinct: float, pairs) -> bool:
    """Whether ``q`` is on a ring of equilibria whose diameter in the scaled coordinates
    exceeds ``distinct`` (a smaller orbit is one point): the robot turned about its base
    axis (``pairs``, :func:`planar_pairs`; None: it cannot be) is an equilibrium too."""
    if pairs is None or 2.0 * np.max(np.abs(_ring_tangent(q, pairs) / problem.scale)) <= distinct:
        return False
    for angle in (2.0 * np.pi / 3.0, np.pi / 2.0, np.pi):
        if np.max(np.abs(problem.scaled_residual(_turned(q, pairs, angle)))) > tol:
            return False
    return True


def _canonical(q, pairs: np.ndarray) -> np.ndarray:
    """The member of ``q``'s ring whose first nonzero pair points along its reference
    (a constant-curvature robot: the first bent segment bends toward +x)."""
    i, j = pairs[:, 0].astype(int), pairs[:, 1].astype(int)
    size = np.hypot(q[i], q[j])
    first = int(np.flatnonzero(size > 0)[0])
    a, b, reference = i[first], j[first], pairs[first, 2:]
    angle = np.arctan2(reference[1], reference[0]) - np.arctan2(q[b], q[a])
    turned = _turned(q, pairs, angle)
    turned[[a, b]] = size[first] * reference  # exactly, not up to round-off
    return turned


def _result(problem: _Problem, root: Root, tol, zero_tolerance, distinct) -> Equilibrium:
    q, message = root.q, root.message
    pairs = planar_pairs(problem.load.model.robot)
    ring = root.converged and _is_ring(problem, q, tol, distinct, pairs)
    if ring:
        q = _canonical(q, pairs)
        message += "; a ring of equilibria (rotational symmetry about the base axis)"
    r, k, w, tip = problem.evaluate(q)
    stability, eigenvalues = _classify(problem, q, k, pairs if ring else None, zero_tolerance)
    if not problem.load.conservative:
        what = "tip moment" if np.any(problem.load.tip_moment) else "actuator (friction)"
        message += f"; {what} is not conservative: classification by static divergence only"
        if not np.any(problem.load.tip_moment):
            message += " (the potential counts the frictionless tendon work)"
    load = problem.load
    status, message = checked_status(load.model.robot, q, load.actuator, root.status, message)
    return Equilibrium(
        q=q,
        status=status,
        message=message,
        stability=stability,
        continuum="ring" if ring else None,
        eigenvalues=eigenvalues,
        residual=r,
        potential=w,
        tip_position=tip,
        curvature=load.model.robot.bending_curvature(q),
    )


def equilibrium(
    model,
    q0,
    *,
    tol: float = 1e-10,
    zero_tolerance: float = 1e-8,
    distinct: float = 1e-6,
    max_evaluations: int = 400,
    **loads,
) -> Equilibrium:
    """The equilibrium nearest (in the solver's sense) to ``q0``, classified.

    Parameters
    ----------
    model : Model
        The compiled model.
    q0 : array_like, shape (n,)
        Initial guess [m, 1/m, 1/m], in the model's domain
        (:meth:`~softcurve.Robot.check_configuration`).
    tol : float
        Acceptance: ``|S r|_i <= tol * (elastic stiffness of coordinate i at rest)``,
        dimensionless.
    zero_tolerance : float
        An eigenvalue of ``S K S`` below ``zero_tolerance`` times the largest elastic
        stiffness [J] counts as zero (``"degenerate"``), dimensionless.
    distinct : float
        A ring whose diameter in the scaled coordinates is below this is one point,
        dimensionless.
    max_evaluations : int
        Budget of residual evaluations of the root finder.
    **loads
        ``tau``, ``actuator`` with ``inputs``, ``tip_force``, ``tip_moment``,
        ``gravity``: see :class:`~softcurve.analysis.loads.StaticLoad`.

    Returns
    -------
    Equilibrium
        ``status`` SUCCESS when the residual met ``tol`` at a state inside the model's
        domain and the actuator's (:mod:`softcurve.description.domain`); a root outside
        it is ``LEFT_DOMAIN``, the message naming the coordinate or the actuator element,
        its value and the allowed range.

    Examples
    --------
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020())
    >>> e = sc.equilibrium(model, [0.0644, 0.0, 0.0])
    >>> e.success, e.stability
    (True, 'stable')
    >>> bool(e.q[0] < 0.0644)  # the upright robot is compressed by its weight
    True
    """
    problem = _Problem(StaticLoad(model, **loads))
    q0 = model.robot.check_configuration(real_array("q0", q0, (model.n,)), "q0")
    root = problem.solve(q0, tol, max_evaluations)
    return _result(problem, root, tol, zero_tolerance, distinct)


def default_bounds(robot) -> np.ndarray:
    """The region searched by default, each element's own box (its kind's
    ``search_bounds``): for a constant-curvature segment ``l`` in ``[0.5, 1.5] l0`` and
    ``|kx|, |ky| <= pi / l0`` (bending angles up to half a turn); for a constant-strain
    segment bending and twist within half a turn of rest, shear within 0.25, stretch
    within half of rest; shape (n, 2).

    Parameters
    ----------
    robot : Robot
        The robot.
    """
    return np.vstack([s.search_bounds() for s in robot.segments])


START_BYTES = 120
"""Bytes each starting point of :func:`equilibria` takes besides its coordinates while
the starts are drawn: its row's NumPy object (112 B) and its list entry (8 B), measured
with ``tracemalloc``."""


def physical_memory() -> int:
    """The machine's physical memory [B]; ``sys.maxsize`` where the system does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return sys.maxsize


def starts_count(name: str, value, n: int) -> int:
    """``value`` as a number of starting points of :func:`equilibria` for ``n``
    coordinates: an integer >= 1 whose starts, drawn at once, fit the machine's physical
    memory, :class:`~softcurve.ParameterError` otherwise. Each start takes
    :data:`START_BYTES` plus its ``n`` float64 coordinates in the Halton draw, in the
    scaled copy and in part of a temporary: at most ``120 + 24 n`` bytes (the peak
    measured with ``tracemalloc``: 176 B at ``n = 3``, 720 B at ``n = 30``).

    Parameters
    ----------
    name : str
        The field's name, for the message.
    value : int
        The number of starts.
    n : int
        The model's coordinates.
    """
    starts = whole_count(name, value)
    per_start = START_BYTES + 3 * 8 * n
    memory = physical_memory()
    most = memory // per_start
    if starts > most:
        raise ParameterError(
            f"{name} must be an integer in [1, {most}], got {starts} (each start of "
            f"{n} coordinates takes {per_start} bytes while the starts are drawn: "
            f"{most} fill this machine's {memory / 1e9:.3g} GB of memory)"
        )
    return starts


def equilibria(
    model,
    *,
    bounds=None,
    starts: int = 48,
    seed: int = 0,
    tol: float = 1e-10,
    zero_tolerance: float = 1e-8,
    distinct: float = 1e-6,
    max_evaluations: int = 400,
    **loads,
) -> EquilibriumTable:
    """Every equilibrium found in a region by multi-start root finding, deduplicated.

    Starts are the rest configuration and ``starts - 1`` points of a scrambled Halton
    sequence in ``bounds`` (reproducible with ``seed``). Solutions outside ``bounds`` are
    dropped; two solutions closer than ``distinct`` in the scaled coordinates are one;
    solutions on one ring are one entry.

    Parameters
    ----------
    model : Model
        The compiled model.
    bounds : array_like, shape (n, 2), optional
        Box of configurations searched [m, 1/m, 1/m]; default :func:`default_bounds`.
    starts : int
        Number of starting points, >= 1 and at most what the machine's memory holds
        (``starts_count``: ``120 + 24 n`` bytes each).
    seed : int
        Seed of the Halton scrambling.
    tol : float
        See :func:`equilibrium` (dimensionless).
    zero_tolerance : float
        See :func:`equilibrium` (dimensionless).
    distinct : float
        Minimum scaled distance (max norm of ``z = (l/l0, kx l0, ky l0)``) between two
        reported equilibria, dimensionless.
    max_evaluations : int
        Budget of residual evaluations per start.
    **loads
        See :class:`~softcurve.analysis.loads.StaticLoad`.

    Returns
    -------
    EquilibriumTable
        Ordered by total potential, lowest first; roots outside the model's or the
        actuator's domain are dropped (the message counts them and names the first
        reason); ``status`` NOT_CONVERGED when no start converged inside ``bounds``,
        LEFT_DOMAIN when the only roots found there lie outside the domain.

    Examples
    --------
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020())
    >>> table = sc.equilibria(model, starts=4)
    >>> table.success, len(table), table[0].stability
    (True, 1, 'stable')
    """
    seed = random_seed("seed", seed)
    starts = starts_count("starts", starts, model.n)
    load = StaticLoad(model, **loads)
    problem = _Problem(load)
    bounds = default_bounds(model.robot) if bounds is None else bounds
    bounds = real_array("bounds", bounds, (model.n, 2))
    if not np.all(bounds[:, 1] > bounds[:, 0]):
        raise ParameterError("bounds must have lower < upper in every row")
    extents = [
        offset + s.extent_index
        for s, offset in zip(model.robot.segments, model.robot.offsets, strict=True)
        if s.extent_index is not None
    ]
    for side, column in (("lower", 0), ("upper", 1)):  # lengths in the model's domain
        straight = np.zeros(model.n)  # straight: no bend, twist or shear
        straight[extents] = bounds[extents, column]
        model.robot.check_configuration(straight, f"bounds[:, {column}] ({side} lengths)")
    points = [rest_configuration(model.robot)]
    if starts > 1:
        from scipy.stats import qmc  # half a second to import: only here

        unit = qmc.Halton(d=model.n, scramble=True, seed=seed).random(starts - 1)
        points += list(bounds[:, 0] + unit * (bounds[:, 1] - bounds[:, 0]))
    found: list[Equilibrium] = []
    converged_starts, outside = 0, []
    for start in points:
        root = problem.solve(start, tol, max_evaluations)
        if not root.converged:
            continue
        converged_starts += 1
        reason = state_problem(model.robot, root.q, load.actuator)  # a root, but no state
        if reason is not None:
            outside.append(reason)
            continue
        if np.any(root.q < bounds[:, 0]) or np.any(root.q > bounds[:, 1]):
            continue
        candidate = _result(problem, root, tol, zero_tolerance, distinct)
        if candidate.status is Status.LEFT_DOMAIN:  # its ring's representative
            outside.append(candidate.message)
            continue
        z = candidate.q / problem.scale
        if all(np.max(np.abs(z - e.q / problem.scale)) > distinct for e in found):
            found.append(candidate)
    found.sort(key=lambda e: e.potential)
    message = (
        f"{len(found)} distinct equilibria ({sum(e.continuum is not None for e in found)} "
        f"rings) from {converged_starts}/{len(points)} converged starts"
    )
    if outside:
        message += (
            f"; {len(outside)} roots outside the model's domain dropped (first: {outside[0]})"
        )
    status = Status.SUCCESS if found else Status.LEFT_DOMAIN if outside else Status.NOT_CONVERGED
    if not found and outside:
        message += "; the loads may be too large for the robot: reduce them or stiffen it"
    elif not found:
        message += "; none inside the bounds: widen them, add starts or change the loads"
    return EquilibriumTable(
        equilibria=tuple(found),
        status=status,
        message=message,
        starts=len(points),
        converged_starts=converged_starts,
        evaluations=problem.evaluations,
        bounds=bounds,
        load=load,
    )
