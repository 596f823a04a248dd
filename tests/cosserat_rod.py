"""An independent reference for the static shape of a Cosserat rod, for the tests.

A static, extensible and shearable Cosserat rod (Simo-Reissner, Antman), solved by
shooting with SciPy alone (no softcurve code), to which the piecewise-constant-strain
segments are compared as their number grows.

Conventions (those of the strain segments): the reference coordinate ``X`` runs over
``[0, L0]``; the body frame has ``z`` along the backbone; the strain twist is
``xi = (u, v)`` in the body frame, ``u = (u_x, u_y, u_z)`` the angular strain (bending
about x, bending about y, twist) [1/m] and ``v = (v_x, v_y, v_z)`` the linear strain
(shear along x, shear along y, stretch) [-]. The linear constitutive law gives the body
moment ``m_b = K_u (u - u*)`` and force ``n_b = K_v (v - v*)`` with
``K_u = diag(EI, EI, GJ)`` and ``K_v = diag(kGA, kGA, EA)``.

The equations, with ``n``, ``m`` the internal force and moment in the world frame (the
action of the part beyond ``X`` on the part before it)::

    p' = R v,   R' = R [u]x,   n' = -f,   m' = -p' x n,
    n(L0) = F_tip,   m(L0) = M_tip,   p(0), R(0) given,

``f`` the distributed dead load per reference length (gravity: mass per length times
``g``). Dead loads make the force balance integrate in closed form,
``n(X) = F_tip + f (L0 - X)``, so the shooting unknowns are the three components of the
base moment ``m(0)`` (:func:`solve_rod`); the residual is ``m(L0) - M_tip``.

Beside it, :func:`solve_pcs` solves the same rod cut into segments of constant strain
(the strain segments' discretization), to tell their discretization error from an
error of their implementation; :func:`loaded_straight_rod` and
:func:`precurved_rod_under_gravity` are the two cases of the convergence study, and
``python tests/cosserat_rod.py`` prints their figures (:func:`report`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.integrate
import scipy.linalg
import scipy.optimize

REST_STRAIN = (0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
"""The straight, unstretched rod's strain twist ``(u, v)``."""

RTOL = 1e-12
"""Relative tolerance of the integration (DOP853); the absolute tolerances are this times
each state's scale (length, 1, moment scale)."""

SHOOTING_TOL = 1e-10
"""Accepted tip moment mismatch, relative to the moment scale: a guard against a failed
solve only. The mismatch reached is below 4e-16 of the scale on every solve of
``tests/test_cosserat_rod.py``, and the shapes are as accurate as the integration at
:data:`RTOL` (errors of 1e-12 to 1e-11 against the closed forms)."""

GRID_POINTS = 201
"""Points of the output grid ``s`` by default."""

STANDARD_GRAVITY = 9.81
"""[m/s^2]."""


def hat(w) -> np.ndarray:
    """The skew matrix ``[w]x`` of a 3-vector, shape (3, 3): ``hat(a) @ b = a x b``."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def twist_matrix(xi) -> np.ndarray:
    """The 4x4 matrix of the strain twist ``xi = (u, v)`` in se(3), ``[[u]x, v; 0, 0]``."""
    g = np.zeros((4, 4))
    g[:3, :3] = hat(xi[:3])
    g[:3, 3] = xi[3:]
    return g


SERIES_BELOW = 0.1
"""Angle [rad] below which :func:`se3_exp` takes its coefficients' Taylor series (to the
8th power: truncation below 1e-17 there) instead of the closed forms, whose cancellation
grows as 1e-16 / angle^2 (1e-14 at this angle)."""


def se3_exp(xi, x) -> np.ndarray:
    """The SE(3) exponential ``expm(x [xi])`` in closed form, for each ``x``.

    SciPy's ``expm`` calls threaded BLAS, which slows it a thousandfold on a loaded
    machine (12 ms a call measured on 2 busy cores); the tests check the two agree.

    Parameters
    ----------
    xi : array_like, shape (6,)
        ``(u, v)`` [1/m, -].
    x : array_like, shape (k,)
        Reference coordinates [m].

    Returns
    -------
    ndarray, shape (k, 4, 4)
    """
    xi = np.asarray(xi, float)
    x = np.atleast_1d(np.asarray(x, float))
    u, v = xi[:3], xi[3:]
    theta = np.linalg.norm(u)
    phi = theta * x
    small = phi < SERIES_BELOW
    p2 = phi**2
    # sin(phi)/phi, (1 - cos(phi))/phi^2, (phi - sin(phi))/phi^3 by their series ...
    a = 1 - p2 / 6 * (1 - p2 / 20 * (1 - p2 / 42 * (1 - p2 / 72)))
    b = 0.5 * (1 - p2 / 12 * (1 - p2 / 30 * (1 - p2 / 56 * (1 - p2 / 90))))
    c = (1 - p2 / 20 * (1 - p2 / 42 * (1 - p2 / 72 * (1 - p2 / 110)))) / 6
    # ... or in closed form
    big = np.where(small, 1.0, phi)
    a = np.where(small, a, np.sin(big) / big)
    b = np.where(small, b, 2 * np.sin(big / 2) ** 2 / big**2)
    c = np.where(small, c, (big - np.sin(big)) / big**3)
    k = hat(u)
    k2 = k @ k
    g = np.zeros((len(x), 4, 4))
    g[:, :3, :3] = np.eye(3) + (a * x)[:, None, None] * k + (b * x**2)[:, None, None] * k2
    left = np.eye(3) * x[:, None, None] + (b * x**2)[:, None, None] * k
    left = left + (c * x**3)[:, None, None] * k2
    g[:, :3, 3] = left @ v
    g[:, 3, 3] = 1.0
    return g


def rest_pose(rest_strain, s, base_position=(0.0, 0.0, 0.0), base_rotation=None):
    """The unloaded rod's pose at ``s``: ``g(0) expm(s [xi*])`` (SciPy's matrix exponential).

    Parameters
    ----------
    rest_strain : array_like, shape (6,)
        ``xi* = (u*, v*)`` [1/m, -].
    s : float
        Reference coordinate [m].
    base_position : array_like, shape (3,)
        [m], world frame.
    base_rotation : array_like, shape (3, 3), optional
        Base frame in the world; default identity.

    Returns
    -------
    (ndarray, ndarray)
        Rotation, shape (3, 3), and position [m], shape (3,).
    """
    g0 = np.eye(4)
    g0[:3, :3] = np.eye(3) if base_rotation is None else np.asarray(base_rotation, float)
    g0[:3, 3] = base_position
    g = g0 @ scipy.linalg.expm(s * twist_matrix(np.asarray(rest_strain, float)))
    return g[:3, :3], g[:3, 3]


@dataclass(frozen=True)
class RodSolution:
    """The static shape of a rod, sampled on a grid of its reference coordinate.

    Attributes
    ----------
    s : ndarray, shape (k,)
        Reference coordinate [m], from 0 to ``L0``.
    positions : ndarray, shape (k, 3)
        Backbone positions [m], world frame.
    rotations : ndarray, shape (k, 3, 3)
        Body frames in the world (columns: body x, y, z axes).
    strains : ndarray, shape (k, 6)
        ``xi = (u, v)`` in the body frame [1/m, 1/m, 1/m, -, -, -].
    forces : ndarray, shape (k, 3)
        Internal force ``n`` [N], world frame.
    moments : ndarray, shape (k, 3)
        Internal moment ``m`` [N m], world frame.
    residual : ndarray, shape (3,)
        Shooting residual ``m(L0) - M_tip`` [N m].
    orthonormality : float
        ``max |R^T R - I|`` over the grid: the drift of the integrated rotations.
    """

    s: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    strains: np.ndarray
    forces: np.ndarray
    moments: np.ndarray
    residual: np.ndarray
    orthonormality: float

    @property
    def tip_position(self) -> np.ndarray:
        """[m], shape (3,)."""
        return self.positions[-1]

    @property
    def tip_rotation(self) -> np.ndarray:
        """Shape (3, 3)."""
        return self.rotations[-1]


@dataclass(frozen=True)
class _Rod:
    """The rod's data as arrays; ``f`` the distributed load [N/m]."""

    length: float
    ku: np.ndarray
    kv: np.ndarray
    rest: np.ndarray
    f: np.ndarray
    tip_force: np.ndarray
    tip_moment: np.ndarray
    p0: np.ndarray
    r0: np.ndarray

    def force(self, x):
        return self.tip_force + self.f * (self.length - x)

    def strain(self, rotation, force, moment):
        """``(u, v)`` from the world-frame internal force and moment, shape (6,)."""
        u = self.rest[:3] + rotation.T @ moment / self.ku
        v = self.rest[3:] + rotation.T @ force / self.kv
        return np.concatenate([u, v])

    def rhs(self, x, y):
        rotation = y[3:12].reshape(3, 3)
        n = self.force(x)
        xi = self.strain(rotation, n, y[12:15])
        dp = rotation @ xi[3:]
        return np.concatenate([dp, (rotation @ hat(xi[:3])).ravel(), -np.cross(dp, n)])

    def moment_scale(self) -> float:
        """[N m]: the loads' moment about the base on the rest shape, or, where it is
        zero, the moment that bends the rod by one radian."""
        moment = np.linalg.norm(self.guess())
        return moment if moment > 0 else self.ku[0] / self.length

    def guess(self) -> np.ndarray:
        """The base moment [N m] that balances the loads on the rest shape (exact for a
        rigid rod)."""
        xs = np.linspace(0.0, self.length, 65)
        ps = self.p0 + se3_exp(self.rest, xs)[:, :3, 3] @ self.r0.T
        arm = scipy.integrate.simpson(ps - self.p0, x=xs, axis=0)
        return self.tip_moment + np.cross(ps[-1] - self.p0, self.tip_force) + np.cross(arm, self.f)

    def integrate(self, m0, scale, grid=None):
        """The ODEs from the base moment ``m0`` [N m]; ``scale`` the moment scale [N m]."""
        y0 = np.concatenate([self.p0, self.r0.ravel(), m0])
        atol = RTOL * np.concatenate([np.full(3, self.length), np.ones(9), np.full(3, scale)])
        return scipy.integrate.solve_ivp(
            self.rhs,
            (0.0, self.length),
            y0,
            method="DOP853",
            rtol=RTOL,
            atol=atol,
            t_eval=grid,
        )

    def residual(self, m0, scale) -> np.ndarray:
        return self.integrate(m0, scale).y[12:15, -1] - self.tip_moment

    def scaled(self, factor: float) -> _Rod:
        """The same rod under ``factor`` times every load."""
        return _Rod(
            self.length,
            self.ku,
            self.kv,
            self.rest,
            factor * self.f,
            factor * self.tip_force,
            factor * self.tip_moment,
            self.p0,
            self.r0,
        )


def _shoot(rod: _Rod, m0: np.ndarray):
    """The base moment [N m] that meets the tip moment from the guess ``m0``, or None."""
    scale = rod.moment_scale()
    root = scipy.optimize.root(
        lambda z: rod.residual(scale * z, scale) / scale, m0 / scale, method="hybr", tol=1e-14
    )
    if np.max(np.abs(root.fun)) > SHOOTING_TOL:
        return None
    return scale * root.x


CONTINUATION_STEPS = (1, 4, 16, 64)
"""Numbers of equal load steps tried in turn: the load applied at once first, then in
ever finer continuation from the unloaded rod."""


def _rod(
    length,
    EI,
    GJ,
    kGA,
    EA,
    mass_per_length=0.0,
    gravity=(0.0, 0.0, 0.0),
    tip_force=(0.0, 0.0, 0.0),
    tip_moment=(0.0, 0.0, 0.0),
    rest_strain=REST_STRAIN,
    base_position=(0.0, 0.0, 0.0),
    base_rotation=None,
) -> _Rod:
    """The rod of :func:`solve_rod`'s arguments."""
    return _Rod(
        length=float(length),
        ku=np.array([EI, EI, GJ], float),
        kv=np.array([kGA, kGA, EA], float),
        rest=np.asarray(rest_strain, float),
        f=mass_per_length * np.asarray(gravity, float),
        tip_force=np.asarray(tip_force, float),
        tip_moment=np.asarray(tip_moment, float),
        p0=np.asarray(base_position, float),
        r0=np.eye(3) if base_rotation is None else np.asarray(base_rotation, float),
    )


def solve_rod(
    length,
    EI,
    GJ,
    kGA,
    EA,
    mass_per_length=0.0,
    gravity=(0.0, 0.0, 0.0),
    tip_force=(0.0, 0.0, 0.0),
    tip_moment=(0.0, 0.0, 0.0),
    rest_strain=REST_STRAIN,
    base_position=(0.0, 0.0, 0.0),
    base_rotation=None,
    points: int = GRID_POINTS,
) -> RodSolution:
    """The static shape of a clamped Cosserat rod under dead loads, by shooting.

    Parameters
    ----------
    length : float
        Reference length ``L0`` [m].
    EI : float
        Bending stiffness about body x and y [N m^2].
    GJ : float
        Torsional stiffness [N m^2].
    kGA : float
        Shear stiffness along body x and y [N].
    EA : float
        Axial stiffness [N].
    mass_per_length : float
        [kg/m] per reference length.
    gravity : array_like, shape (3,)
        [m/s^2], world frame.
    tip_force, tip_moment : array_like, shape (3,)
        Dead loads on the tip [N], [N m], world frame.
    rest_strain : array_like, shape (6,)
        ``xi* = (u*, v*)`` [1/m, -], constant along the rod.
    base_position : array_like, shape (3,)
        The clamp [m], world frame.
    base_rotation : array_like, shape (3, 3), optional
        The clamp's frame in the world; default identity (the rod along world z).
    points : int
        Size ``k`` of the output grid (uniform in ``[0, L0]``).

    Returns
    -------
    RodSolution

    Raises
    ------
    RuntimeError
        When no continuation of :data:`CONTINUATION_STEPS` meets :data:`SHOOTING_TOL`.
    """
    rod = _rod(
        length,
        EI,
        GJ,
        kGA,
        EA,
        mass_per_length,
        gravity,
        tip_force,
        tip_moment,
        rest_strain,
        base_position,
        base_rotation,
    )
    m0 = _continued(rod)
    grid = np.linspace(0.0, rod.length, points)
    sol = rod.integrate(m0, rod.moment_scale(), grid)
    positions = sol.y[:3].T
    rotations = sol.y[3:12].T.reshape(-1, 3, 3)
    moments = sol.y[12:15].T
    forces = np.array([rod.force(x) for x in grid])
    strains = np.array(
        [rod.strain(r, n, m) for r, n, m in zip(rotations, forces, moments, strict=True)]
    )
    drift = np.einsum("kji,kjl->kil", rotations, rotations) - np.eye(3)
    return RodSolution(
        s=grid,
        positions=positions,
        rotations=rotations,
        strains=strains,
        forces=forces,
        moments=moments,
        residual=moments[-1] - rod.tip_moment,
        orthonormality=float(np.max(np.abs(drift))),
    )


def _continued(rod: _Rod) -> np.ndarray:
    """The base moment [N m], the load applied at once or in steps."""
    for steps in CONTINUATION_STEPS:
        m0 = rod.scaled(0.0).guess()
        for k in range(1, steps + 1):
            step = rod.scaled(k / steps)
            # the previous solution plus the change of the rigid-rod guess as a predictor
            m0 = _shoot(step, m0 + step.guess() - rod.scaled((k - 1) / steps).guess())
            if m0 is None:
                break
        else:
            return m0
    raise RuntimeError(f"shooting failed with {CONTINUATION_STEPS[-1]} continuation steps")


# --- The piecewise-constant-strain equilibrium by the same principle ------------------

PCS_POINTS = 33
"""Simpson points per segment of :func:`solve_pcs` (odd). Against 129 points, the tip
moves by 1e-7 of ``L0`` with one segment of case (b) (the most curved), 5e-10 with four
(the error falls as ``count^-4``): six orders below the discretization error each time.
"""


def _pcs_residual(rod: _Rod, count: int, xi: np.ndarray):
    """``K (xi_i - xi*)`` minus the mean body-frame internal wrench over segment ``i``,
    divided by ``K``, shape (count, 6); and the poses, shape (count, PCS_POINTS, 4, 4)."""
    step = rod.length / count
    x = np.linspace(0.0, step, PCS_POINTS)
    poses = np.empty((count, PCS_POINTS, 4, 4))
    start = np.eye(4)
    start[:3, :3], start[:3, 3] = rod.r0, rod.p0
    for i in range(count):
        poses[i] = start @ se3_exp(xi[i], x)
        start = poses[i, -1]
    rotations, positions = poses[:, :, :3, :3], poses[:, :, :3, 3]
    global_x = step * np.arange(count)[:, None] + x  # (count, PCS_POINTS)
    # int_X^L p dY: within the segment (cumulative Simpson from its end on the uniform
    # grid), then the segments after
    within = scipy.integrate.cumulative_simpson(positions[:, ::-1], x=x, axis=1, initial=0)
    within = within[:, ::-1]
    totals = within[:, 0]
    after = np.cumsum(totals[::-1], axis=0)[::-1] - totals
    beyond = within + after[:, None]
    force = rod.tip_force + rod.f * (rod.length - global_x)[..., None]
    arm = beyond - (rod.length - global_x)[..., None] * positions
    moment = (
        rod.tip_moment
        + np.cross(positions[-1, -1] - positions, rod.tip_force)
        + np.cross(arm, rod.f)
    )
    wrench = np.concatenate(
        [
            np.einsum("ijba,ijb->ija", rotations, moment),
            np.einsum("ijba,ijb->ija", rotations, force),
        ],
        axis=-1,
    )
    mean = scipy.integrate.simpson(wrench, x=x, axis=1) / step
    stiffness = np.concatenate([rod.ku, rod.kv])
    return xi - rod.rest - mean / stiffness, poses


STRAINS = ("bend_x", "bend_y", "twist", "shear_x", "shear_y", "stretch")
"""The names of the six strains in their order in ``xi = (u, v)``."""


def solve_pcs(count: int, guess=None, strains=STRAINS, **keywords):
    """The equilibrium of ``count`` equal segments of constant strain (the strain segments'
    model), by the principle of virtual work, for comparison with :func:`solve_rod`.

    For a clamped rod the internal wrench at ``X`` is the loads beyond ``X`` (statics of
    the part beyond), whatever the shape; the virtual work of the loads is that of the
    internal wrench on the strain variation, so segment ``i``'s equilibrium is
    ``K (xi_i - xi*) = (1 / l) int_segment Lambda(X) dX`` in each chosen strain,
    ``Lambda`` the body-frame internal (moment, force) and ``l = L0 / count``; the
    strains not chosen stay at rest. Solved by ``scipy.optimize.root``. Meant to tell a
    discretization error from an implementation error: a correct piecewise-constant-
    strain model meets it to the solvers' precision.

    Parameters
    ----------
    count : int
        Number of segments.
    guess : array_like, shape (count, 6), optional
        Strains to start from (e.g. :func:`segment_means` of the rod's solution), the
        load applied at once. Without it, or where it fails, the rest strains with load
        continuation as :func:`solve_rod`.
    strains : sequence of str
        The strains free in every segment, among :data:`STRAINS` (default all); e.g.
        ``("bend_x", "bend_y", "stretch")``, the constant-curvature segment.
    **keywords
        Those of :func:`solve_rod` but ``points`` (a ``"material"`` key is ignored).

    Returns
    -------
    (ndarray, ndarray, ndarray)
        The strains, shape (count, 6) [1/m, -]; the tip rotation, shape (3, 3); the tip
        position [m], shape (3,).
    """
    keywords = {k: v for k, v in keywords.items() if k != "material"}
    rod = _rod(**keywords)
    chosen = [STRAINS.index(s) for s in strains]

    def full(z):
        xi = np.tile(rod.rest, (count, 1))
        xi[:, chosen] = z.reshape(count, len(chosen))
        return xi

    def solved(step: _Rod, start: np.ndarray):
        root = scipy.optimize.root(
            lambda z: _pcs_residual(step, count, full(z))[0][:, chosen].ravel(),
            start[:, chosen].ravel(),
            method="hybr",
            tol=1e-14,
        )
        return full(root.x) if np.max(np.abs(root.fun)) <= SHOOTING_TOL else None

    attempts = [(1, guess)] if guess is not None else []
    attempts += [(steps, None) for steps in CONTINUATION_STEPS]
    for steps, start in attempts:
        xi = np.tile(rod.rest, (count, 1)) if start is None else np.reshape(start, (count, 6))
        for k in range(1, steps + 1):
            xi = solved(rod.scaled(k / steps), np.asarray(xi, float))
            if xi is None:
                break
        else:
            tip = _pcs_residual(rod, count, xi)[1][-1, -1]
            return xi, tip[:3, :3], tip[:3, 3]
    raise RuntimeError(f"no equilibrium of {count} segments with {steps} load steps")


def segment_means(solution: RodSolution, count: int) -> np.ndarray:
    """The rod's strains averaged over ``count`` equal segments, shape (count, 6): a
    start for :func:`solve_pcs` and the strain segments' equilibria (their error is of
    the order of the discretization's). ``solution`` on a grid of ``count * k + 1``
    points for an exact split."""
    edges = np.linspace(0.0, solution.s[-1], count + 1)
    return np.array(
        [
            scipy.integrate.simpson(solution.strains[m], x=solution.s[m], axis=0) / (b - a)
            for a, b in zip(edges[:-1], edges[1:], strict=True)
            for m in [(solution.s >= a - 1e-12 * b) & (solution.s <= b + 1e-12 * b)]
        ]
    )


# --- The cases of the strain segments' convergence study -------------------------------


def circle_rod(length, radius, youngs_modulus, poisson_ratio, density) -> dict:
    """Stiffnesses and mass of a solid circular rod, as keywords of :func:`solve_rod`.

    The shear coefficient of a circle is ``6 (1 + nu) / (7 + 6 nu)`` (Cowper 1966);
    ``G = E / (2 (1 + nu))``, ``J = 2 I``.
    """
    area = np.pi * radius**2
    second_moment = np.pi * radius**4 / 4
    shear_modulus = youngs_modulus / (2 * (1 + poisson_ratio))
    shear_coefficient = 6 * (1 + poisson_ratio) / (7 + 6 * poisson_ratio)
    return {
        "length": length,
        "EI": youngs_modulus * second_moment,
        "GJ": shear_modulus * 2 * second_moment,
        "kGA": shear_coefficient * shear_modulus * area,
        "EA": youngs_modulus * area,
        "mass_per_length": density * area,
    }


SOFT_ROD = {
    "radius": 0.01,
    "youngs_modulus": 1e6,
    "poisson_ratio": 0.5,
    "density": 1000.0,
}
"""A soft, thick rod (silicone-like: E = 1 MPa, incompressible, 1000 kg/m^3, radius 1 cm)
of the two cases below: thick so that shear is not negligible."""


def loaded_straight_rod(points: int = GRID_POINTS):
    """Case (a): a straight rod whose tip force and moment make every strain matter.

    ``L0 = 0.1 m`` of :data:`SOFT_ROD` (radius / length = 0.1: EI = 7.85e-3 N m^2,
    GJ = 5.24e-3 N m^2, kGA = 94.2 N, EA = 314 N, k = 0.9), clamped at the origin along
    world z, no gravity. Tip force ``(0.8, 0, 1.0)`` N: the lateral 0.8 N alone would
    bend the tip by ``F L^3 / (3 EI)`` = 34 % of ``L0`` in the linear theory (23 % with
    the axial tension and the large rotation) and shear it by ``F L / kGA`` = 0.85 % of
    ``L0`` (2.5 % of the bending deflection); the axial 1 N stretches the rod by
    ``F / EA`` = 0.32 %. Tip moment ``(0.015, 0, 0.016)`` N m: about world z it twists
    the rod by ``T L / GJ`` = 0.31 rad, about world x it bends the rod about its body x
    (out of the force's plane) by ``M L / EI`` = 0.19 rad. Both bending strains, twist,
    both shears (the twist turns the lateral force into both body directions) and
    stretch are non-zero. The section is isotropic (equal bending stiffnesses), so the
    twisting moment is constant along the rod and the backbone does not depend on ``GJ``
    (freezing the twist moves the tip by 1e-15 m): the twist shows in the tip rotation,
    not in the tip position; case (b) couples it into the position.

    Returns
    -------
    (dict, RodSolution)
        The keywords of :func:`solve_rod` (with the material in ``"material"``) and the
        solution.
    """
    parameters = circle_rod(0.1, **SOFT_ROD) | {
        "tip_force": (0.8, 0.0, 1.0),
        "tip_moment": (0.015, 0.0, 0.016),
    }
    solution = solve_rod(**parameters, points=points)
    return parameters | {"material": dict(SOFT_ROD)}, solution


def precurved_rod_under_gravity(points: int = GRID_POINTS):
    """Case (b): a precurved rod that sags out of its plane under its own weight.

    ``L0 = 0.2 m`` of :data:`SOFT_ROD`, clamped at the origin along world z, with a rest
    curvature ``u*_y = (pi / 2) / L0`` (bending about body y: the rest shape is a quarter
    circle in the x-z plane, radius 0.127 m) and gravity 9.81 m/s^2 along world -y, out of
    that plane. The weight (0.616 N, 3.08 N/m) bends the rod out of its plane by about
    ``w L^4 / (8 EI)`` (of a straight rod) = 7.9 % of ``L0``, and, acting at an arm from
    the clamp's axis, twists it; the weight's in-plane components shear and stretch it.
    ``L0 = 0.2 m`` (rather than the 0.1 m of case (a)) so that the deflection is not
    small: it grows as ``L0^4``.

    Returns
    -------
    (dict, RodSolution)
        The keywords of :func:`solve_rod` (with the material in ``"material"``) and the
        solution.
    """
    length = 0.2
    parameters = circle_rod(length, **SOFT_ROD) | {
        "gravity": (0.0, -STANDARD_GRAVITY, 0.0),
        "rest_strain": (0.0, np.pi / 2 / length, 0.0, 0.0, 0.0, 1.0),
    }
    solution = solve_rod(**parameters, points=points)
    return parameters | {"material": dict(SOFT_ROD)}, solution


def strain_summary(solution: RodSolution, rest_strain=REST_STRAIN) -> np.ndarray:
    """``max |xi - xi*|`` over the rod per strain component, shape (6,)."""
    return np.max(np.abs(solution.strains - np.asarray(rest_strain, float)), axis=0)


STIFFNESS_GROUPS = {"bending": "EI", "torsion": "GJ", "shear": "kGA", "stretch": "EA"}
"""The strain kinds and the stiffness of each."""

RIGID_FACTOR = 1e6
"""How much stiffer a strain kind is made to freeze it in :func:`tip_shifts` (its strain
then falls below 1e-6 of its value, below the printed digits)."""


def tip_shifts(parameters: dict, solution: RodSolution) -> dict:
    """How far the tip moves and turns when each strain kind is frozen (its stiffness times
    :data:`RIGID_FACTOR`): each kind's share of the tip pose.

    Parameters
    ----------
    parameters : dict
        Keywords of :func:`solve_rod` (others, such as ``"material"``, are ignored).
    solution : RodSolution
        The solution with ``parameters``.

    Returns
    -------
    dict
        Strain kind -> (``|tip - tip with that kind frozen|`` [m], the angle of the tip
        rotation between the two [rad]).
    """
    keywords = {k: v for k, v in parameters.items() if k != "material"}
    shifts = {}
    for kind, name in STIFFNESS_GROUPS.items():
        frozen = solve_rod(**keywords | {name: RIGID_FACTOR * keywords[name]}, points=2)
        turn = frozen.tip_rotation.T @ solution.tip_rotation
        angle = np.arccos(np.clip((np.trace(turn) - 1) / 2, -1.0, 1.0))
        shifts[kind] = (
            float(np.linalg.norm(frozen.tip_position - solution.tip_position)),
            float(angle),
        )
    return shifts


def report() -> str:
    """The two cases' tip positions, strains and each strain kind's share, as text."""
    names = STRAINS
    lines = []
    for case in (loaded_straight_rod, precurved_rod_under_gravity):
        parameters, solution = case()
        lines.append(f"{case.__name__} (L0 = {parameters['length']} m)")
        lines.append(f"  tip position [m]: {np.array2string(solution.tip_position, precision=8)}")
        rest = parameters.get("rest_strain", REST_STRAIN)
        for name, value in zip(names, strain_summary(solution, rest), strict=True):
            lines.append(f"  max |{name} - rest| = {value:.4g}")
        for kind, (shift, angle) in tip_shifts(parameters, solution).items():
            lines.append(f"  {kind} frozen: the tip moves {shift:.4g} m, turns {angle:.4g} rad")
        lines.append(
            f"  shooting residual {np.max(np.abs(solution.residual)):.2e} N m, "
            f"rotation drift {solution.orthonormality:.2e}"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    print(report())
