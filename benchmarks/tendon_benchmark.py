"""Tendon benchmark: softcurve's statics against the two-segment tendon-driven robot of
Rao, Peyron, Lilge and Burgner-Kahrs (Frontiers in Robotics and AI 7:630245, 2021).

The robot and its tension cases come from the authors' public code, GitHub repository
SvenLilge/tdcr-modeling (commit 74121147b37d8a6e3de74d571f7cff9d19a55e54 of the MATLAB
code, 6c5f1861c6499a60ab3de1804ab6aefe1deecef0 of the C++ code). Their constant-curvature
(CC) model is geometric: it maps the tendon lengths of each segment to (kappa, phi, l)
and has no tensions and no loads. Their ``main.m`` and ``main.cpp`` feed it the tendon
lengths of a statics model's shape (a Cosserat rod with tendons); this script does the
same with its own implementation of both, from the equations:

1. a Cosserat rod with tendons routed parallel to the backbone at a constant distance,
   unshearable, extensible axially (``E A``), with torsion (``G J``), solved by shooting
   on the tip position (:func:`rod_equilibrium`);
2. the tendon lengths of each segment along that rod, as the repo's C++ measures them:
   straight chords between consecutive disks;
3. the inverse CC map from three tendon lengths to the segment's arc, with the repo's
   chord-to-arc length for ``n`` spacer disks (:func:`cc_from_tendon_lengths`), and the
   CC forward kinematics (:func:`cc_tip`).

The reference tip is step 3's; the rod's own tip and twist are printed beside it.
With ``--six-strain`` the script prints softcurve's six-strain model instead
(:func:`strain_robot`: every section of 1, 2, 4 or 8 constant-strain segments that bend,
twist, shear and stretch, the tendons routed along them) against the same rod.
:func:`cc_energy_equilibrium` re-derives softcurve's own model (least potential among
CC shapes) independently, for the tests. softcurve's tip
is ``softcurve.equilibrium(model, q0, actuator=, inputs=tensions, tip_force=)`` on
``presets.rao2021()`` with ``presets.rao2021_tendons()``.

Run: ``python benchmarks/tendon_benchmark.py [--markdown] [--six-strain]``
(docs/tendon_benchmark.md).
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root

import softcurve as sc

# -- the robot, as in the repo's matlab/Parameters/tdcr_2segments.m and c++/main.cpp ----
LENGTHS = (0.2, 0.2)  # L = [200e-3; 200e-3] [m]
YOUNG = 54e9  # E = 54*10^9 [Pa] (nitinol)
POISSON = 0.3  # nu = 0.3 [-]
BACKBONE_RADIUS = 0.7e-3  # ro = 1.4/2*10^-3 [m], solid (ri = 0)
PITCH = 10e-3  # r_disk = 10*1e-3 [m], tendon to backbone
AZIMUTHS = (math.pi / 2, -math.pi / 6, 7 * math.pi / 6)  # r1, r2, r3 of each segment [rad]
DISKS = (10, 10)  # n = [10; 10] spacer disks per segment

SECOND_MOMENT = math.pi / 4 * BACKBONE_RADIUS**4  # I [m^4]
AREA = math.pi * BACKBONE_RADIUS**2  # A [m^2]
BENDING = YOUNG * SECOND_MOMENT  # E I [N m^2]
AXIAL = YOUNG * AREA  # E A [N]
SHEAR_MODULUS = YOUNG / (2 * (1 + POISSON))  # G [Pa]
TORSION = SHEAR_MODULUS * 2 * SECOND_MOMENT  # G J, J = 2 I [N m^2]
SHEAR_COEFFICIENT = 6 * (1 + POISSON) / (7 + 6 * POISSON)
"""Cowper's shear coefficient of a solid circle (0.886): the six-strain model's ``k G A``
(the rod, unshearable, has none; the backbone's shear under the 0.05 N load is 1.5e-6)."""
PER_SECTION = (1, 2, 4, 8)
"""Constant-strain segments per section of the six-strain rows."""
SHOOTING_RESIDUAL = 1e-12
"""A shooting whose fixed-point residual is within this fraction of the tip's distance
is solved, whatever hybr's step test says (the integration's rtol is 1e-11)."""

CASES = (
    # name, tensions [N] (proximal 1-3, distal 4-6), where the case comes from
    ("A", (2.0, 0.0, 0.0, 0.0, 1.0, 0.0), "repo matlab/main.m, F = [2 0 0 0 1 0]"),
    ("B", (4.0, 0.0, 0.0, 0.0, 2.0, 0.0), "repo c++/main.cpp, q = [4 0 0 0 2 0]"),
    ("C", (8.0, 0.0, 0.0, 0.0, 0.0, 0.0), "repo tdcr_2segments.m, F = [8 0 0 0 0 0]"),
    ("D", (0.0, 3.0, 0.0, 3.0, 0.0, 0.0), "ours: an out-of-plane S-curve"),
)
LOADS = (
    # name, world-frame tip force [N]; the repo applies none (Ftex = 0)
    ("none", (0.0, 0.0, 0.0)),
    ("+x", (0.05, 0.0, 0.0)),
    ("-z", (0.0, 0.0, -0.05)),
)


# -- the reference: a Cosserat rod with tendons -----------------------------------------
def _hat(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


@dataclass(frozen=True)
class RodSolution:
    """The rod's equilibrium: tip [m]; per segment (2, 3) the lengths [m] of the three
    tendon paths (continuous) and of their straight chords between consecutive disks
    (``DISKS`` per segment plus the base disk); the twist at the tip [rad]; whether the
    shooting converged."""

    tip: np.ndarray
    tendon_lengths: np.ndarray
    chord_lengths: np.ndarray
    twist: float
    success: bool


TENDON_OFFSETS = PITCH * np.array([[math.cos(a), math.sin(a), 0.0] for a in AZIMUTHS])
"""Body-frame positions ``r`` [m] of the three tendon paths of a segment, (3, 3)."""
STIFFNESS = np.array([BENDING, BENDING, TORSION])


def _curvature(rotation, position, tip, through, force, stretch):
    """Body-frame curvature ``u`` [1/m] from the moment balance of the part beyond ``s``.

    The part of the robot beyond a cross-section (backbone, disks and the tendon pieces
    in it) carries the tip force ``F`` and, where each tendon is cut, its tension ``T``
    pulling toward the base along the tendon's unit tangent ``t`` at ``p + R r``. So the
    backbone's moment is ``m = (p_tip - p) x F - sum T (R r) x (R t)`` and
    ``u = K^-1 R^T m``, ``K = diag(EI, EI, GJ)``. A tendon of constant ``r`` has the body
    tangent ``v + u x r = (-uz ry, uz rx, a)``, ``a = 1 + eps + ux ry - uy rx``, hence
    ``r x t = (ry a, -rx a, rho^2 uz) / n``, ``n = sqrt(a^2 + (uz rho)^2)``: the tendons
    add ``sum T rho^2 / n`` to the torsional stiffness and are otherwise parallel to the
    backbone up to ``(uz rho)^2``. ``through`` (3,) sums the tensions [N] of the tendons
    at each azimuth that pass the section; a few passes solve the weak coupling through
    ``a`` and ``n`` to round-off."""
    load = rotation.T @ np.cross(tip - position, force)
    rx, ry = TENDON_OFFSETS[:, 0], TENDON_OFFSETS[:, 1]
    u = load / STIFFNESS
    for _ in range(5):
        a = stretch + u[0] * ry - u[1] * rx
        n = np.sqrt(a * a + (u[2] * PITCH) ** 2)
        w = through * a / n
        u = np.array(
            [
                (load[0] - w @ ry) / BENDING,
                (load[1] + w @ rx) / BENDING,
                load[2] / (TORSION + PITCH**2 * np.sum(through / n)),
            ]
        )
    return u


def _rhs(segment, tip, tensions, force, extensible):
    through = tensions.reshape(2, 3)[segment:].sum(axis=0)  # per azimuth [N]
    pulled = through.sum()

    def rhs(_s, y):
        position, rotation = y[:3], y[3:12].reshape(3, 3)
        stretch = 1.0 + ((rotation[:, 2] @ force - pulled) / AXIAL if extensible else 0.0)
        u = _curvature(rotation, position, tip, through, force, stretch)
        a = stretch + u[0] * TENDON_OFFSETS[:, 1] - u[1] * TENDON_OFFSETS[:, 0]
        rates = np.sqrt(a * a + (u[2] * PITCH) ** 2)  # |v + u x r| of each tendon path
        derivative = np.empty(16)
        derivative[:3] = rotation[:, 2] * stretch
        derivative[3:12] = (rotation @ _hat(u)).ravel()
        derivative[12:15] = rates
        derivative[15] = u[2]
        return derivative

    return rhs


def _integrate(tip, tensions, force, extensible, disks=False):
    """The rod from base to tip: the final state (16,), the continuous tendon path
    lengths per segment (2, 3) [m], and with ``disks`` the chords between consecutive
    disks summed per segment (2, 3) [m]."""
    y = np.concatenate([np.zeros(3), np.eye(3).ravel(), np.zeros(3), [0.0]])
    lengths, chords = [], []
    for segment, length in enumerate(LENGTHS):
        y[12:15] = 0.0
        stations = np.linspace(0.0, length, DISKS[segment] + 1)  # base disk .. end disk
        sol = solve_ivp(
            _rhs(segment, tip, tensions, force, extensible),
            (0.0, length),
            y,
            method="DOP853",
            t_eval=stations if disks else None,
            rtol=1e-11,
            atol=1e-14,
        )
        y = sol.y[:, -1].copy()
        lengths.append(y[12:15].copy())
        if not disks:
            continue
        holes = [  # (stations, 3) world positions of each tendon's hole in the disks
            sol.y[:3].T + np.einsum("sij,j->si", sol.y[3:12].T.reshape(-1, 3, 3), r)
            for r in TENDON_OFFSETS
        ]
        chords.append([np.linalg.norm(np.diff(h, axis=0), axis=1).sum() for h in holes])
    return y, np.array(lengths), np.array(chords)


def rod_equilibrium(tensions, tip_force, *, extensible: bool = True) -> RodSolution:
    """The Cosserat rod's static shape under tendon tensions [N] (6,) and a world-frame
    tip force [N] (3,), by shooting on the tip position [m]; no gravity (the repo's
    parameter file sets g = 0). ``extensible=False`` drops the axial strain."""
    tensions = np.asarray(tensions, dtype=float)
    force = np.asarray(tip_force, dtype=float)
    guess = _integrate(np.zeros(3), tensions, np.zeros(3), extensible)[0]  # CC, no load
    tip, success = guess[:3], True
    if np.any(force):
        found = root(
            lambda tip: _integrate(tip, tensions, force, extensible)[0][:3] - tip,
            guess[:3],
            method="hybr",
            options={"xtol": 1e-13},
        )
        # hybr's step test can fail at xtol 1e-13 once the residual is at rounding
        # (2.6e-16 m on case C, -z load, with NumPy 2.4.6): the residual decides.
        solved = np.abs(found.fun).max() <= SHOOTING_RESIDUAL * np.linalg.norm(found.x)
        tip, success = found.x, bool(found.success) or bool(solved)
    y, lengths, chords = _integrate(tip, tensions, force, extensible, disks=True)
    return RodSolution(y[:3], lengths, chords, float(y[15]), success)


# -- the reference: the repo's constant-curvature model ---------------------------------
def cc_from_tendon_lengths(lengths, *, disks: int | None = None) -> np.ndarray:
    """``(l, kx, ky)`` [m, 1/m, 1/m] of a CC segment from the lengths [m] (3,) of its
    tendon paths at ``AZIMUTHS`` and distance ``PITCH``.

    A path of a CC arc has length ``lbar (1 - rho (kx cos phi + ky sin phi))``: three
    paths give ``(lbar, lbar kx, lbar ky)`` by one linear solve (for three tendons 120
    degrees apart this is the repo's closed form, configuration.m). With ``disks = n``
    the repo reads ``lbar`` as the sum of ``n`` equal chords of the backbone's arc and
    returns the arc length ``l = (2 n / kappa) asin(kappa lbar / (2 n))``.
    """
    rows = [[1.0, -PITCH * math.cos(a), -PITCH * math.sin(a)] for a in AZIMUTHS]
    mean, bx, by = np.linalg.solve(np.array(rows), np.asarray(lengths, dtype=float))
    kx, ky = bx / mean, by / mean
    kappa = math.hypot(kx, ky)
    length = mean
    if disks is not None and kappa > 0:
        length = 2 * disks / kappa * math.asin(kappa * mean / (2 * disks))
    return np.array([length, kx, ky])


def cc_tip(q) -> np.ndarray:
    """Tip [m] of CC segments ``q = (l, kx, ky, ...)`` [m, 1/m, 1/m] chained without
    twist: segment ``i`` bends in its base frame about ``(-ky, kx, 0) / kappa`` by ``kappa
    l``. Complex-safe for ``kappa != 0`` (complex-step derivatives)."""
    q = np.asarray(q).reshape(-1, 3)
    position, rotation = np.zeros(3, dtype=q.dtype), np.eye(3, dtype=q.dtype)
    for length, kx, ky in q:
        kappa = np.sqrt(kx * kx + ky * ky)
        if kappa == 0:
            local, turn = np.array([0.0, 0.0, length]), np.eye(3)
        else:
            c, s = np.cos(kappa * length), np.sin(kappa * length)
            cx, cy = kx / kappa, ky / kappa
            local = np.array([cx * (1 - c), cy * (1 - c), s]) / kappa
            axis = np.array([-cy, cx, 0.0 * cx])
            turn = c * np.eye(3) + s * _hat(axis) + (1 - c) * np.outer(axis, axis)
        position = position + rotation @ local
        rotation = rotation @ turn
    return position


def cc_potential(q, tensions, tip_force):
    """Potential [J] of softcurve's model for this robot, written out independently:
    ``sum 0.5 (EA/l0) (l - l0)^2 + 0.5 (EI/l0) (kappa l)^2 + sum T L(q) - F . p_tip(q)``,
    ``L`` the tendon paths ``sum_j l_j (1 - rho (kx_j cos phi + ky_j sin phi))``."""
    q = np.asarray(q).reshape(2, 3)
    energy = 0.0
    for (length, kx, ky), l0 in zip(q, LENGTHS, strict=True):
        energy = energy + 0.5 * AXIAL / l0 * (length - l0) ** 2
        energy = energy + 0.5 * BENDING / l0 * (kx * kx + ky * ky) * length**2
    for j in range(2):  # tendon set j runs through segments 0 .. j
        for k, a in enumerate(AZIMUTHS):
            path = sum(
                q[i, 0] * (1 - PITCH * (q[i, 1] * math.cos(a) + q[i, 2] * math.sin(a)))
                for i in range(j + 1)
            )
            energy = energy + tensions[3 * j + k] * path
    return energy - np.dot(np.asarray(tip_force, dtype=float), cc_tip(q.ravel()))


def cc_energy_equilibrium(tensions, tip_force, q0) -> np.ndarray:
    """The stationary point [m, 1/m, 1/m] (6,) of :func:`cc_potential` nearest ``q0``:
    its gradient by complex steps (exact to round-off), the root by MINPACK's hybrid
    method in the coordinates ``(l / l0, kx l0, ky l0)``. An independent check of
    softcurve's equilibrium solver and symbolic model (needs ``kappa != 0``)."""
    scale = np.array([v for l0 in LENGTHS for v in (l0, 1 / l0, 1 / l0)])
    tensions = np.asarray(tensions, dtype=float)

    def gradient(x):
        q = x * scale
        g = np.empty(6)
        for i in range(6):
            step = np.zeros(6, dtype=complex)
            step[i] = 1e-30j
            g[i] = cc_potential(q + step, tensions, tip_force).imag / 1e-30
        return g * scale / (BENDING / LENGTHS[0])  # dimensionless

    found = root(gradient, np.asarray(q0, dtype=float) / scale, method="hybr", tol=1e-14)
    return found.x * scale


def reference(tensions, tip_force, *, chords: bool = True) -> tuple[np.ndarray, RodSolution]:
    """The repo's CC tip [m] from the rod's tendon lengths, and the rod itself.

    ``chords=True`` (the repo's reading, c++/src/tendondrivenrobot.cpp,
    ``getTendonDisplacements``): the tendon lengths are the straight chords between the
    disks, inverted with the disk count. ``chords=False``: the continuous path lengths,
    inverted without it (the continuum limit)."""
    rod = rod_equilibrium(tensions, tip_force)
    if chords:
        arcs = [cc_from_tendon_lengths(rod.chord_lengths[j], disks=DISKS[j]) for j in range(2)]
    else:
        arcs = [cc_from_tendon_lengths(rod.tendon_lengths[j]) for j in range(2)]
    return cc_tip(np.concatenate(arcs)), rod


# -- softcurve --------------------------------------------------------------------------
def softcurve_tip(model, actuator, tensions, tip_force) -> np.ndarray:
    """softcurve's equilibrium tip [m], solved from the straight robot."""
    q0 = [v for l0 in LENGTHS for v in (l0, 0.0, 0.0)]
    e = sc.equilibrium(model, q0, actuator=actuator, inputs=tensions, tip_force=tip_force)
    if not e.success:
        raise RuntimeError(e.message)
    return e.tip_position


def run(cases=CASES, loads=LOADS) -> list[dict]:
    """One row per (case, load): tensions, force, the reference, rod and softcurve tips."""
    model = sc.Model(sc.presets.rao2021())
    actuator = sc.presets.rao2021_tendons()
    rows = []
    for name, tensions, _ in cases:
        for load, force in loads:
            ref, rod = reference(tensions, force)
            ours = softcurve_tip(model, actuator, tensions, force)
            rows.append(
                dict(case=name, tensions=tensions, load=load, force=force,
                     reference=ref, rod=rod.tip, twist=rod.twist, softcurve=ours,
                     rod_success=rod.success)
            )  # fmt: skip
    return rows


# -- softcurve's six-strain model -------------------------------------------------------
def strain_robot(per_section: int) -> sc.Robot:
    """The benchmark's robot as ``2 per_section`` constant-strain segments with all six
    strains: ``EI``, ``GJ``, ``k G A``, ``E A`` of the nitinol backbone (linear laws),
    mass per length as :func:`softcurve.presets.rao2021`'s, radius the tendons' 10 mm,
    gravity off. (Built by hand from the repo's numbers; ``StrainSegment.from_material``
    with a ``Material`` and a ``Section`` gives the same laws.)"""
    rest_length = LENGTHS[0] / per_section
    preset = sc.presets.rao2021().segments[0]
    segment = sc.StrainSegment(
        rest_length=rest_length,
        mass=preset.mass * rest_length / preset.rest_length,
        radius=PITCH,
        strains=sc.STRAINS,
        bending_stiffness=sc.LinearStiffness(BENDING),
        torsion_stiffness=sc.LinearStiffness(TORSION),
        shear_stiffness=sc.LinearStiffness(SHEAR_COEFFICIENT * SHEAR_MODULUS * AREA),
        stretch_stiffness=sc.LinearStiffness(AXIAL),
    )
    return sc.Robot(segments=(segment,) * (2 * per_section), gravity=np.zeros(3))


def strain_tendons(robot: sc.Robot, per_section: int) -> sc.TendonActuator:
    """The repo's six tendons on :func:`strain_robot`: the proximal set tied to the tip of
    section 0 (its last segment), the distal set to the robot's tip."""
    tendons = [
        sc.Tendon(azimuth, PITCH, 8.0, anchor=(k + 1) * per_section - 1)
        for k in range(2)
        for azimuth in AZIMUTHS
    ]
    return sc.TendonActuator(tendons, elements=robot)


def strain_equilibrium(model, actuator, tensions, tip_force):
    """softcurve's six-strain equilibrium: the tendons alone from the straight robot, then
    the tip load from there. Returns the result and the twist angle at the tip [rad]
    (the sum of ``twist L0`` over the segments)."""
    robot = model.robot
    e = sc.equilibrium(model, robot.rest_configuration(), actuator=actuator, inputs=tensions)
    if np.any(tip_force) and e.success:
        e = sc.equilibrium(model, e.q, actuator=actuator, inputs=tensions, tip_force=tip_force)
    if not e.success:
        raise RuntimeError(e.message)
    twist = sum(
        float(robot.element_coordinates(e.q, i)[2]) * s.rest_length
        for i, s in enumerate(robot.segments)
    )
    return e, twist


def strain_run(per_section=PER_SECTION, cases=CASES, loads=LOADS[1:]) -> list[dict]:
    """One row per (case, load, segments per section): the rod's tip and twist, the
    constant-curvature model's tip and the six-strain model's tip and twist."""
    cc_model, cc_tendons = sc.Model(sc.presets.rao2021()), sc.presets.rao2021_tendons()
    rods = {(c, ld): rod_equilibrium(t, f) for c, t, _ in cases for ld, f in loads}
    rows = []
    for count in per_section:
        robot = strain_robot(count)
        model, actuator = sc.Model(robot, compile=False), strain_tendons(robot, count)
        for name, tensions, _ in cases:
            for load, force in loads:
                e, twist = strain_equilibrium(model, actuator, tensions, force)
                rod = rods[name, load]
                rows.append(
                    dict(case=name, tensions=tensions, load=load, force=force, count=count,
                         rod=rod.tip, rod_twist=rod.twist, strain=e.tip_position, twist=twist,
                         curvature=softcurve_tip(cc_model, cc_tendons, tensions, force))
                )  # fmt: skip
    return rows


def strain_table(rows, *, markdown: bool = False) -> str:
    """The six-strain rows: tips in mm, distances to the rod's tip of the six-strain and
    of the constant-curvature model, twists in degrees."""
    head = [
        "case", "tip load [N]", "segments per section", "six-strain tip [mm]",
        "diff to rod [mm]", "CC diff to rod [mm]", "twist [deg]", "rod twist [deg]",
    ]  # fmt: skip
    lines = [
        [
            r["case"], " ".join(f"{f:g}" for f in r["force"]), str(r["count"]),
            _mm(r["strain"]), f"{1e3 * np.linalg.norm(r['strain'] - r['rod']):.3f}",
            f"{1e3 * np.linalg.norm(r['curvature'] - r['rod']):.3f}",
            f"{math.degrees(r['twist']):.2f}", f"{math.degrees(r['rod_twist']):.2f}",
        ]
        for r in sorted(rows, key=lambda r: (r["case"], r["load"], r["count"]))
    ]  # fmt: skip
    return _format(head, lines, markdown)


def closed_form_check(tension: float = 8.0) -> tuple[float, float, float]:
    """Segment 1 under one proximal tendon (tendon 1 alone, no load): ``T rho / EI``
    [1/m], softcurve's curvature ``kappa`` [1/m] and its bending angle per rest length
    ``kappa l / l0`` [1/m]."""
    model = sc.Model(sc.presets.rao2021())
    e = sc.equilibrium(
        model, [LENGTHS[0], 0, 0, LENGTHS[1], 0, 0],
        actuator=sc.presets.rao2021_tendons(), inputs=[tension, 0, 0, 0, 0, 0],
    )  # fmt: skip
    kappa = float(e.curvature[0])
    return tension * PITCH / BENDING, kappa, kappa * e.q[0] / LENGTHS[0]


def _mm(v) -> str:
    return "(" + ", ".join(f"{round(1e3 * x, 3) + 0.0:8.3f}" for x in v) + ")"  # no -0.000


def table(rows, *, markdown: bool = False) -> str:
    """The rows as a text (or Markdown) table; tips in mm, differences to the reference
    CC tip and to the rod's tip, also as % of the robot's length 400 mm."""
    total = sum(LENGTHS)
    head = [
        "case", "tensions [N]", "tip load [N]", "reference CC tip [mm]",
        "softcurve tip [mm]", "diff [mm]", "diff/L [%]", "Cosserat rod tip [mm]",
        "diff to rod [mm]", "rod twist [deg]",
    ]  # fmt: skip
    lines = []
    for r in rows:
        d = np.linalg.norm(r["softcurve"] - r["reference"])
        d_rod = np.linalg.norm(r["softcurve"] - r["rod"])
        lines.append([
            r["case"], " ".join(f"{t:g}" for t in r["tensions"]),
            " ".join(f"{f:g}" for f in r["force"]), _mm(r["reference"]), _mm(r["softcurve"]),
            f"{1e3 * d:.3f}", f"{100 * d / total:.3f}", _mm(r["rod"]), f"{1e3 * d_rod:.3f}",
            f"{math.degrees(r['twist']):.2f}",
        ])  # fmt: skip
    return _format(head, lines, markdown)


def _format(head, lines, markdown: bool) -> str:
    if markdown:
        out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        return "\n".join(out + ["| " + " | ".join(line) + " |" for line in lines])
    widths = [max(len(x) for x in col) for col in zip(head, *lines, strict=True)]
    fmt = "  ".join(f"{{:>{w}}}" for w in widths)
    return "\n".join([fmt.format(*head)] + [fmt.format(*line) for line in lines])


def _orders(rows) -> None:
    """The observed order of the six-strain tips' convergence to the rod, per doubling."""
    errors = {}
    for r in rows:
        errors.setdefault(r["count"], []).append(np.linalg.norm(r["strain"] - r["rod"]))
    counts = sorted(errors)
    for a, b in zip(counts, counts[1:], strict=False):
        ratios = np.array(errors[a]) / np.array(errors[b])
        orders = np.log2(ratios) / math.log2(b / a)
        print(
            f"observed order {a} -> {b} segments per section: "
            f"{orders.min():.2f} to {orders.max():.2f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    parser.add_argument(
        "--six-strain",
        action="store_true",
        help="the six-strain model (1, 2, 4, 8 segments per section) against the rod instead",
    )
    args = parser.parse_args()
    start = time.perf_counter()
    if args.six_strain:
        rows = strain_run()
        print(strain_table(rows, markdown=args.markdown))
        _orders(rows)
        print(f"({time.perf_counter() - start:.1f} s)")
        return
    rows = run()
    print(table(rows, markdown=args.markdown))
    for name, _, source in CASES:
        print(f"case {name}: {source}")
    exact, kappa, angle = closed_form_check()
    print(
        f"closed form, 8 N on tendon 1: T rho / EI = {exact:.9f} 1/m; softcurve kappa = "
        f"{kappa:.9f} 1/m (relative {kappa / exact - 1:.2e}: the tendon shortens the "
        f"segment), kappa l / l0 = {angle:.9f} 1/m (relative {angle / exact - 1:.1e})"
    )
    if not all(r["rod_success"] for r in rows):
        print("WARNING: the rod's shooting did not converge for some rows")
    print(f"({time.perf_counter() - start:.1f} s)")


if __name__ == "__main__":
    main()
