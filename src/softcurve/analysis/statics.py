"""Equilibria, their stability, and linearisation (section 4.2 of the paper).

An equilibrium solves ``N(q) = tau + H(q) p + J_tip(q)^T w`` for constant generalized
forces ``tau``, constant pressures ``p`` through a :class:`~softcurve.actuation.Actuator`
and a constant tip wrench ``w = (f, m)`` given in the world frame. The gravity
direction may be changed for the analysis (``gravity=``) without recompiling: it is a
run-time parameter of the model.

Stability is read from the tangent stiffness ``K = d/dq (N - loads)``. Gravity,
elasticity, constant ``tau``, constant pressures (``p_i dV_i`` is exact) and a constant
world tip force (potential ``-f . p_tip``) are conservative, so ``K`` is the Hessian of
the total potential and is symmetric: all eigenvalues positive is a strict local
minimum (``"stable"``), all negative a local maximum (``"unstable"``), mixed signs a
``"saddle"``, and a zero eigenvalue that no symmetry explains ``"degenerate"``. A
constant world tip moment is not conservative in three dimensions (rotations do not
commute): it enters ``K`` through ``d(J_w^T m)/dq``, which is not symmetric, and the
classification is then by the real parts of ``K``'s eigenvalues (static divergence
only); the eigenvalues of :func:`linearize`'s ``A`` decide the dynamic stability.

Continua: when the loads are symmetric about the base axis (gravity along it, no
lateral load), a bent equilibrium rotated about the axis is again an equilibrium. Each
solution is tested for this directly, by evaluating the residual on the rotated
configurations; such a solution is reported once as a ``"ring"`` (its representative
bends toward +x) and classified by ``K`` on the complement of the ring's tangent.

Coordinates are compared in the scaled units ``z = (l / l0, kx l0, ky l0)`` per segment,
and residuals as ``S r`` [J] with ``S = diag(l0, 1/l0, 1/l0)``, relative to the elastic
stiffness of each coordinate at rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.stats

from softcurve.analysis.linear import Linearization, linearize
from softcurve.analysis.loads import (
    StaticLoad,
    coordinate_scale,
    residual_reference,
    rest_configuration,
    static_function,
)
from softcurve.base.validation import ParameterError, real_array

__all__ = [
    "Equilibrium",
    "EquilibriumTable",
    "Linearization",
    "StaticLoad",
    "default_bounds",
    "equilibria",
    "equilibrium",
    "linearize",
    "rotate_about_axis",
]

STABILITY_KINDS = ("stable", "unstable", "saddle", "degenerate")


class _Problem:
    """Residual, tangent and scaling of one static problem."""

    def __init__(self, load: StaticLoad):
        self.load = load
        self.model = load.model
        self.function = static_function(self.model, load.actuator)
        self.scale = coordinate_scale(self.model.robot)
        self.reference = residual_reference(self.model)
        self.evaluations = 0

    def evaluate(self, q):
        self.evaluations += 1
        r, k, w, tip = self.function(q, *self.load.arguments())
        return (
            np.array(r, dtype=np.float64).ravel(),
            np.array(k, dtype=np.float64),
            float(w),
            np.array(tip, dtype=np.float64).ravel(),
        )

    def scaled_residual(self, q) -> np.ndarray:
        """``S r / reference``: dimensionless, compared with ``tol``."""
        r, *_ = self.evaluate(q)
        return self.scale * r / self.reference


def rotate_about_axis(q, angle: float) -> np.ndarray:
    """``q`` with every segment's curvature vector ``(kx, ky)`` rotated by ``angle`` [rad]
    about the base z axis (the robot's configuration turned about its base axis)."""
    q = np.array(q, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    kx, ky = q[1::3].copy(), q[2::3].copy()
    q[1::3], q[2::3] = c * kx - s * ky, s * kx + c * ky
    return q


def _ring_tangent(q) -> np.ndarray:
    tangent = np.zeros_like(q)
    tangent[1::3], tangent[2::3] = -q[2::3], q[1::3]
    return tangent


# -- results ----------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Equilibrium:
    """One equilibrium (or one representative of a ring of them).

    Attributes
    ----------
    q : ndarray, shape (n,)
        Configuration; for a ring, the member bending toward +x (first bent segment).
    converged : bool
        Whether the solver met the tolerance; ``message`` says more.
    stability : str
        ``"stable"``, ``"unstable"`` (local maximum), ``"saddle"`` or ``"degenerate"``.
    continuum : str or None
        ``"ring"`` for a continuum under rotational symmetry, else None.
    eigenvalues : ndarray, shape (n,) or (n - 1,)
        Of the scaled tangent stiffness ``S K S`` [J] (real parts), ascending; for a
        ring, on the complement of the ring's tangent.
    residual : ndarray, shape (n,)
        ``N(q) - loads`` [N, N m^2].
    potential : float
        Total potential of the conservative loads [J].
    tip_position : ndarray, shape (3,)
        World tip position [m].
    message : str
    """

    q: np.ndarray
    converged: bool
    stability: str
    continuum: str | None
    eigenvalues: np.ndarray
    residual: np.ndarray
    potential: float
    tip_position: np.ndarray
    message: str = ""

    @property
    def curvature(self) -> np.ndarray:
        """Net curvature ``kappa`` [1/m] of each segment."""
        return np.hypot(self.q[1::3], self.q[2::3])

    @property
    def unstable_directions(self) -> int:
        """Number of negative eigenvalues (the Morse index)."""
        return int(np.sum(self.eigenvalues < 0))


@dataclass(frozen=True, eq=False)
class EquilibriumTable:
    """All equilibria found in a region, deduplicated, ordered by potential.

    Attributes
    ----------
    equilibria : tuple of Equilibrium
    status : str
        ``"ok"`` or ``"none_found"``.
    message : str
    starts, converged_starts, evaluations : int
        Multi-start statistics (residual and tangent evaluations in total).
    bounds : ndarray, shape (n, 2)
        The region searched.
    load : StaticLoad
    """

    equilibria: tuple[Equilibrium, ...]
    status: str
    message: str
    starts: int
    converged_starts: int
    evaluations: int
    bounds: np.ndarray
    load: StaticLoad

    def __len__(self) -> int:
        return len(self.equilibria)

    def __iter__(self):
        return iter(self.equilibria)

    def __getitem__(self, i) -> Equilibrium:
        return self.equilibria[i]

    @property
    def stable(self) -> tuple[Equilibrium, ...]:
        return tuple(e for e in self.equilibria if e.stability == "stable")

    def table(self) -> str:
        """A plain-text table, one row per equilibrium or ring."""
        n_seg = self.load.model.robot.n_segments
        head = f"{'#':>2}  {'stability':<10} {'set':<6} "
        head += " ".join(
            f"{f'l({i}) [m]':>10} {f'kx({i}) [1/m]':>11} {f'ky({i}) [1/m]':>11}"
            for i in range(n_seg)
        )
        head += f" {'|kappa| [1/m]':>13} {'V [J]':>12} {'min eig [J]':>12}"
        rows = [head]
        for k, e in enumerate(self.equilibria):
            coords = " ".join(
                f"{e.q[3 * i]:10.6f} {e.q[3 * i + 1]:11.5f} {e.q[3 * i + 2]:11.5f}"
                for i in range(n_seg)
            )
            kappa = ",".join(f"{c:.5f}" for c in e.curvature)
            rows.append(
                f"{k:>2}  {e.stability:<10} {e.continuum or 'point':<6} {coords} {kappa:>13} "
                f"{e.potential:12.5e} {e.eigenvalues[0]:12.4e}"
            )
        return "\n".join(rows)

    def plot(self, ax=None):
        """Backbones of every equilibrium in the x-z plane (rings drawn by their
        representative); returns the Matplotlib axes."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(5, 5))
        styles = {"stable": "-", "unstable": "--", "saddle": ":", "degenerate": "-."}
        model = self.load.model
        for k, e in enumerate(self.equilibria):
            backbone = np.array(
                [np.array(model.pose(e.q, s).position) for s in np.linspace(0, 1, 40)]
            )
            label = f"#{k} {e.stability}" + (" ring" if e.continuum else "")
            ax.plot(backbone[:, 0], backbone[:, 2], styles[e.stability], label=label)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("z [m]")
        ax.set_aspect("equal")
        ax.legend(fontsize="small")
        return ax


# -- solving ----------------------------------------------------------------------------
def _classify(problem: _Problem, q, tangent_stiffness, ring: bool, zero_tolerance: float):
    scale = problem.scale
    k = scale[:, None] * tangent_stiffness * scale[None, :]
    symmetric = problem.load.conservative  # K is then a Hessian (module docstring)
    if ring:
        v = _ring_tangent(q) / scale
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


def _is_ring(problem: _Problem, q, tol: float, distinct: float) -> bool:
    """Whether ``q`` is on a ring of equilibria whose diameter in the scaled coordinates
    exceeds ``distinct`` (a smaller orbit is one point)."""
    if 2.0 * np.max(np.abs(_ring_tangent(q) / problem.scale)) <= distinct:
        return False
    for angle in (2.0 * np.pi / 3.0, np.pi / 2.0, np.pi):
        if np.max(np.abs(problem.scaled_residual(rotate_about_axis(q, angle)))) > tol:
            return False
    return True


def _canonical(q) -> np.ndarray:
    """The member of ``q``'s ring whose first bent segment bends toward +x."""
    bent = np.flatnonzero(np.hypot(q[1::3], q[2::3]) > 0)
    i = 3 * bent[0]
    turned = rotate_about_axis(q, -np.arctan2(q[i + 2], q[i + 1]))
    turned[i + 1 : i + 3] = np.hypot(q[i + 1], q[i + 2]), 0.0  # exactly, not up to round-off
    return turned


def _scaled_system(problem: _Problem, z):
    """The residual and its Jacobian in the scaled variables ``z = q / S``."""
    u = problem.scale
    r, k, *_ = problem.evaluate(z * u)
    return u * r / problem.reference, (u[:, None] * k * u[None, :]) / problem.reference[:, None]


def _newton(problem: _Problem, q0, tol: float, max_evaluations: int):
    """Solve ``r(q) = 0`` from ``q0`` (MINPACK's hybrid method in scaled variables, then
    Newton polishing); returns (q, converged, message)."""
    u = problem.scale
    solution = scipy.optimize.root(
        lambda z: _scaled_system(problem, z),
        np.asarray(q0, dtype=np.float64) / u,
        jac=True,
        method="hybr",
        options={"maxfev": max_evaluations, "xtol": 1e-13},
    )
    q = solution.x * u
    for _ in range(2):  # polish: quadratic convergence from where hybr stopped
        r, k, *_ = problem.evaluate(q)
        step = np.linalg.lstsq(k, r, rcond=None)[0]
        if not np.all(np.isfinite(step)):
            break
        q = q - step
    residual = np.max(np.abs(problem.scaled_residual(q)))
    converged = bool(np.isfinite(residual) and residual <= tol)
    message = f"scaled residual {residual:.1e} ({'<=' if converged else '>'} tol {tol:.0e})"
    return q, converged, message


def _result(problem: _Problem, q, converged: bool, message: str, tol, zero_tolerance, distinct):
    ring = converged and _is_ring(problem, q, tol, distinct)
    if ring:
        q = _canonical(q)
        message += "; a ring of equilibria (rotational symmetry about the base axis)"
    r, k, w, tip = problem.evaluate(q)
    stability, eigenvalues = _classify(problem, q, k, ring, zero_tolerance)
    if not problem.load.conservative:
        message += "; tip moment is not conservative: classification by static divergence only"
    return Equilibrium(
        q=q,
        converged=converged,
        stability=stability,
        continuum="ring" if ring else None,
        eigenvalues=eigenvalues,
        residual=r,
        potential=w,
        tip_position=tip,
        message=message,
    )


def equilibrium(
    model,
    q_guess,
    *,
    tol: float = 1e-10,
    zero_tolerance: float = 1e-8,
    distinct: float = 1e-6,
    max_evaluations: int = 400,
    **loads,
) -> Equilibrium:
    """The equilibrium nearest (in the solver's sense) to ``q_guess``, classified.

    Parameters
    ----------
    model : Model
    q_guess : array_like, shape (n,)
        Starting configuration.
    tol : float
        Acceptance: ``|S r|_i <= tol * (elastic stiffness of coordinate i at rest)``,
        dimensionless.
    zero_tolerance : float
        An eigenvalue of ``S K S`` below ``zero_tolerance`` times the largest elastic
        stiffness [J] counts as zero (``"degenerate"``).
    distinct : float
        A ring whose diameter in the scaled coordinates is below this is one point.
    max_evaluations : int
        Budget of residual evaluations of the root finder.
    **loads
        ``tau``, ``actuator`` with ``pressures``, ``tip_force``, ``tip_moment``,
        ``gravity``: see :class:`StaticLoad`.
    """
    problem = _Problem(StaticLoad(model, **loads))
    q_guess = real_array("q_guess", q_guess, (model.n,))
    q, converged, message = _newton(problem, q_guess, tol, max_evaluations)
    return _result(problem, q, converged, message, tol, zero_tolerance, distinct)


def default_bounds(robot) -> np.ndarray:
    """The region searched by default: per segment ``l`` in ``[0.5, 1.5] l0`` and
    ``|kx|, |ky| <= pi / l0`` (bending angles up to half a turn), shape (n, 2)."""
    rows = []
    for s in robot.segments:
        k = np.pi / s.rest_length
        rows += [(0.5 * s.rest_length, 1.5 * s.rest_length), (-k, k), (-k, k)]
    return np.array(rows)


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
    bounds : array_like, shape (n, 2), optional
        Box of configurations searched; default :func:`default_bounds`.
    starts : int
        Number of starting points (>= 1).
    seed : int
        Seed of the Halton scrambling.
    tol, zero_tolerance, max_evaluations
        See :func:`equilibrium`.
    distinct : float
        Minimum scaled distance (max norm of ``z = (l/l0, kx l0, ky l0)``) between two
        reported equilibria.
    **loads
        See :class:`StaticLoad`.

    Returns
    -------
    EquilibriumTable
        Ordered by total potential, lowest first.
    """
    load = StaticLoad(model, **loads)
    problem = _Problem(load)
    bounds = default_bounds(model.robot) if bounds is None else bounds
    bounds = real_array("bounds", bounds, (model.n, 2))
    if not np.all(bounds[:, 1] > bounds[:, 0]) or not np.all(bounds[0::3, 0] > 0):
        raise ParameterError("bounds must have lower < upper in every row and lengths > 0")
    if not (isinstance(starts, int) and starts >= 1):
        raise ParameterError(f"starts must be an integer >= 1, got {starts!r}")
    points = [rest_configuration(model.robot)]
    if starts > 1:
        unit = scipy.stats.qmc.Halton(d=model.n, scramble=True, seed=seed).random(starts - 1)
        points += list(bounds[:, 0] + unit * (bounds[:, 1] - bounds[:, 0]))
    found: list[Equilibrium] = []
    converged_starts = 0
    for q0 in points:
        q, converged, message = _newton(problem, q0, tol, max_evaluations)
        if not converged:
            continue
        converged_starts += 1
        if np.any(q < bounds[:, 0]) or np.any(q > bounds[:, 1]):
            continue
        candidate = _result(problem, q, True, message, tol, zero_tolerance, distinct)
        z = candidate.q / problem.scale
        if all(np.max(np.abs(z - e.q / problem.scale)) > distinct for e in found):
            found.append(candidate)
    found.sort(key=lambda e: e.potential)
    status = "ok" if found else "none_found"
    message = (
        f"{len(found)} distinct equilibria ({sum(e.continuum is not None for e in found)} "
        f"rings) from {converged_starts}/{len(points)} converged starts"
    )
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
