"""Convergence of the piecewise constant curvature chain to a continuous rod: a slender
cantilever under a tip force, N segments against the inextensible elastica.

Run:  python benchmarks/study_convergence.py [--segments 1 2 4 8 10 16 20 30 40] [--loads 1 3 10]

The rod: length L = 0.2 m, bending stiffness EI = 0.0102 N m^2 (the backbone of Rao et
al. 2021), axial stiffness EA = 1e8 N (its strain under the largest force, 2.6e-7, is
the error floor the inextensible reference allows), no gravity, clamped upright at its
base. A dead load F along x at the tip, of size ``alpha EI / L^2`` for each ``alpha`` of
``--loads``. Each of the N equal segments has the rest length L / N and the linear laws
``k_e = EA / (L / N)``, ``k_b = EI / (L / N)``, so that every N is the same rod.

Reference: the elastica ``EI theta'' = -F cos(theta)``, ``theta(0) = 0``,
``theta'(L) = 0`` (``theta`` the tangent's angle from the rod's axis toward x), solved
by shooting (:func:`elastica_tip`, SciPy's DOP853 at rtol 1e-13 and ``brentq``); its
small-load limit is the beam's ``F L^3 / (3 EI)``.

For each N and load it prints the tip's distance from the reference relative to L, the
observed order of convergence between successive N (``log(e1 / e2) / log(N2 / N1)``) and
the wall time per N: building the model (symbolic, nothing compiled) and the equilibria
(``softcurve.equilibrium`` from the straight rod, tol 1e-12).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import softcurve as sc

LENGTH = 0.2
"""Rod length L [m]."""
BENDING = 0.0102
"""Bending stiffness EI [N m^2]: k_b l0 of presets.rao2021() (0.0509 N m/rad x 0.2 m)."""
AXIAL = 1e8
"""Axial stiffness EA [N]: stiff enough that the rod's elongation (strain below 3e-7
at the largest load) is below the errors studied."""


def elastica_tip(alpha: float) -> np.ndarray:
    """The tip ``(x, 0, z)`` [m] of the inextensible cantilever under the dead load
    ``alpha EI / L^2`` along x, by shooting: the curvature at the base ``theta'(0)``
    for which ``theta'(L) = 0``, found by Brent's method in ``[0, F L / EI]`` (the
    base's moment is ``F z(L)``, at most ``F L``), each shot integrated by DOP853 at
    rtol 1e-13."""
    force = alpha * BENDING / LENGTH**2

    def rhs(s, y):  # y = (theta, theta', x, z)
        return [y[1], -force / BENDING * np.cos(y[0]), np.sin(y[0]), np.cos(y[0])]

    def shoot(curvature):
        return solve_ivp(
            rhs, (0.0, LENGTH), [0.0, curvature, 0.0, 0.0], method="DOP853",
            rtol=1e-13, atol=1e-16,
        ).y[:, -1]  # fmt: skip

    base = brentq(lambda k: shoot(k)[1], 0.0, force * LENGTH / BENDING, xtol=1e-15, rtol=1e-15)
    end = shoot(base)
    return np.array([end[2], 0.0, end[3]])


def chain(segments: int) -> sc.Robot:
    """The rod as ``segments`` equal constant-curvature segments."""
    rest = LENGTH / segments
    segment = sc.Segment(
        rest_length=rest,
        mass=1e-3 * rest,  # statics: the mass does not enter without gravity
        radius=0.005,
        elongation_stiffness=sc.LinearStiffness(AXIAL / rest),
        bending_stiffness=sc.LinearStiffness(BENDING / rest),
        damping=[1.0, 1e-6, 1e-6],
    )
    return sc.Robot(segments=(segment,) * segments, gravity=np.zeros(3))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 8, 10, 16, 20, 30, 40])
    parser.add_argument("--loads", type=float, nargs="+", default=[1.0, 3.0, 10.0])
    args = parser.parse_args()
    references = {alpha: elastica_tip(alpha) for alpha in args.loads}
    for alpha, tip in references.items():
        linear = alpha * LENGTH / 3.0
        print(f"alpha = {alpha:g}: elastica tip x = {tip[0] * 1e3:.6f} mm, z = "
              f"{tip[2] * 1e3:.6f} mm (linear beam x = {linear * 1e3:.3f} mm)")  # fmt: skip
    print(f"\n{'N':>3}" + "".join(f"   alpha={a:<4g} error/L  order" for a in args.loads)
          + "   wall [s]")  # fmt: skip
    last = {}
    for n in args.segments:
        start = time.perf_counter()
        model = sc.Model(chain(n), compile=False)  # its functions are built at first use
        row = f"{n:3d}"
        for alpha, reference in references.items():
            q0 = np.tile([LENGTH / n, 0.0, 0.0], n)
            force = [alpha * BENDING / LENGTH**2, 0.0, 0.0]
            e = sc.equilibrium(model, q0, tip_force=force, tol=1e-12)
            if not e.success:
                row += f"   {'FAILED: ' + e.status.value:>30s}"
                continue
            error = np.linalg.norm(model.tip_pose(e.q).position - reference) / LENGTH
            order = ""
            if alpha in last:
                n0, e0 = last[alpha]
                order = f"{np.log(e0 / error) / np.log(n / n0):5.2f}"
            last[alpha] = (n, error)
            row += f"   {'':10s}{error:9.3e} {order:>6s}"
        print(f"{row} {time.perf_counter() - start:10.2f}", flush=True)


if __name__ == "__main__":
    main()
