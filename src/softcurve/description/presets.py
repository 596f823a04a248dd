"""Robots from the literature, as ready-made :class:`~softcurve.description.robot.Robot`
values (and the actuators that drive them)."""

from __future__ import annotations

import math

import numpy as np

from softcurve.base.validation import real_scalar
from softcurve.description.materials import Creep, LinearStiffness, TanhStiffness
from softcurve.description.robot import Robot, Segment
from softcurve.description.sections import Material, Section, section_properties
from softcurve.description.tendons import TendonActuator


def ifac2020(*, creep: bool = True, damping: bool = True) -> Robot:
    """The study case of Caasenbrood, Pogromsky and Nijmeijer (IFAC 2020), Table 1.

    m = 49.4 g, l0 = 64.4 mm, r = 23.5 mm, upright under g = 9.81 m/s^2, the
    hyper-elastic stiffness alpha and creep gamma of Table 1,
    K = diag(502.3 N/m, 1.53e-2 N m, 1.53e-2 N m) and
    R = diag(0.12 N s/m, 5.93e-7 N m s, 5.93e-7 N m s) (section 4.1).

    Parameters
    ----------
    creep : bool
        Include the creep model (three creep states).
    damping : bool
        Include the damping ``R``; without it and without creep the model conserves energy.

    Examples
    --------
    >>> import softcurve as sc
    >>> robot = sc.presets.ifac2020()
    >>> robot.n_segments, robot.n, robot.n_creep
    (1, 3, 3)
    >>> robot.mass, robot.rest_length  # [kg], [m]
    (0.0494, 0.0644)
    >>> sc.presets.ifac2020(creep=False).n_creep
    0
    """
    alpha = (2.23e3, 1.74e3, -4.55e2, 4.23e-1, 3.99e-1, -2.29e-1)
    gamma = (3.21e2, 5.22e-1, 2.84e2, 1.82e-3, 2.84e2, 1.82e-3)
    segment = Segment(
        rest_length=0.0644,
        mass=0.0494,
        radius=0.0235,
        elongation_stiffness=TanhStiffness(*alpha[:3]),
        bending_stiffness=TanhStiffness(*alpha[3:]),
        damping=np.array([0.12, 5.93e-7, 5.93e-7]) if damping else np.zeros(3),
        creep=Creep.from_gamma(gamma, [502.3, 1.53e-2, 1.53e-2]) if creep else None,
    )
    return Robot(segments=(segment,), gravity=np.array([0.0, 0.0, -9.81]))


# Rao, Peyron, Lilge and Burgner-Kahrs, "How to model tendon-driven continuum robots and
# benchmark modelling performance", Front. Robot. AI 7:630245 (2021); the numbers are
# those of the authors' code, github.com/SvenLilge/tdcr-modeling,
# matlab/Parameters/tdcr_2segments.m and c++/main.cpp.
RAO2021_LENGTH = 0.2
"""Rest length of each of the two segments [m] (``L = [200e-3; 200e-3]``)."""
RAO2021_YOUNG = 54e9
"""Young's modulus of the nitinol backbone [Pa] (``E = 54*10^9``)."""
RAO2021_POISSON = 0.3
"""Poisson's ratio of the nitinol backbone [-] (``nu = 0.3``)."""
RAO2021_BACKBONE_RADIUS = 0.7e-3
"""Radius of the solid backbone rod [m] (``ro = 1.4/2*10^-3``, ``ri = 0``)."""
RAO2021_PITCH = 10e-3
"""Distance from each tendon to the backbone [m] (``r_disk = 10*1e-3``)."""
RAO2021_AZIMUTHS = (math.pi / 2, -math.pi / 6, 7 * math.pi / 6)
"""Azimuths of the three tendons of each segment [rad], from +x toward +y: the repo's
routing vectors ``(0, r)``, ``r (cos(-pi/6), sin(-pi/6))``, ``r (cos(7pi/6), sin(7pi/6))``
in the disk frame (z along the backbone), which is softcurve's segment base frame."""
RAO2021_DISKS = 10
"""Spacer disks per segment (``n = [10; 10]``)."""
RAO2021_BACKBONE_DENSITY = 0.0115
"""Mass of the backbone per length [kg/m] (``m_bb = 0.0115*l*g``)."""
RAO2021_DISK_MASS = 0.2e-3
"""Mass of one spacer disk [kg] (``m_disk = 0.2*1e-3``)."""
RAO2021_SECTION = Section.circle(RAO2021_BACKBONE_RADIUS, poisson_ratio=RAO2021_POISSON)
"""The backbone's solid circular section (radius :data:`RAO2021_BACKBONE_RADIUS`)."""
RAO2021_MATERIAL = Material(
    youngs_modulus=RAO2021_YOUNG,
    density=RAO2021_BACKBONE_DENSITY / RAO2021_SECTION.area,
    poisson_ratio=RAO2021_POISSON,
)
"""The backbone's nitinol: :data:`RAO2021_YOUNG`, :data:`RAO2021_POISSON` and the
density that gives the repo's mass per length :data:`RAO2021_BACKBONE_DENSITY`
(7,470 kg/m^3)."""
RAO2021_DAMPING_TIME = 0.0125
"""A damping time [s] for the dynamics of :func:`rao2021` (``damping_time=``): an
assumption, since the source models statics only. Every mode of frequency ``w`` then has
the damping ratio ``0.0125 w / 2``: 0.1 for the first bending mode at rest (15.9 rad/s),
0.99 for the second (158 rad/s), the axial modes (7,900 and 27,700 rad/s undamped)
overdamped. The undamped robot under tensions that change every control period gains
energy at every change and keeps it; with this damping its motion stays bounded and the
learning environments' stepper follows it (docs/envs.md)."""


def rao2021(*, gravity: bool = False, damping_time: float | None = None) -> Robot:
    """The two-segment tendon-driven continuum robot of Rao, Peyron, Lilge and
    Burgner-Kahrs (Front. Robot. AI 7:630245, 2021), with the numbers of the authors'
    code (github.com/SvenLilge/tdcr-modeling, matlab/Parameters/tdcr_2segments.m).

    Two segments of l0 = 200 mm on a solid nitinol backbone (E = 54 GPa, radius
    0.7 mm, :data:`RAO2021_MATERIAL` and :data:`RAO2021_SECTION`). softcurve's elastic
    energy is ``0.5 k_b (kappa l)^2 + 0.5 k_e (l - l0)^2``, a rod's with
    ``k_b = E I / l0`` = 0.0509 N m/rad and ``k_e = E A / l0`` = 4.16e5 N/m
    (:class:`~softcurve.description.sections.SectionProperties`). Mass per
    segment: backbone 0.0115 kg/m x 0.2 m plus ten 0.2 g spacer disks = 4.3 g. The
    repo has no disk radius; the slice radius (rotary inertia only) is the tendons'
    10 mm. No damping by default (statics only in the source); ``damping_time`` adds
    the rod's material damping for dynamics. Torsion and shear of the rod are not
    modelled (constant-curvature segments).

    Parameters
    ----------
    gravity : bool
        False (the default, as the repo's parameter file sets ``g = 0``): no gravity.
        True: ``(0, 0, -9.81)`` m/s^2, the robot upright on its base as in the repo's
        rod model (gravity along ``-z``).
    damping_time : float, optional
        Stiffness-proportional (Kelvin-Voigt) damping [s], > 0: ``R = damping_time K0``
        per segment, ``K0 = diag(k_e, k_b l0^2, k_b l0^2)`` the stiffness at rest in the
        coordinates ``(l, kappa_x, kappa_y)``, so that a mode of frequency ``w`` [rad/s]
        has the damping ratio ``damping_time w / 2``. :data:`RAO2021_DAMPING_TIME` is the
        value of the learning environments' tendon task. None (default): no damping.
        Statics do not depend on it.

    Examples
    --------
    >>> import softcurve as sc
    >>> robot = sc.presets.rao2021()
    >>> robot.n_segments, robot.rest_length  # [m]
    (2, 0.4)
    >>> round(robot.segments[0].bending_stiffness.k0, 6)  # E I / l0 [N m/rad]
    0.050915
    >>> round(robot.segments[0].mass, 6), robot.gravity  # [kg], [m/s^2]
    (0.0043, array([0., 0., 0.]))
    >>> damped = sc.presets.rao2021(damping_time=sc.presets.RAO2021_DAMPING_TIME)
    >>> damped.segments[0].damping.diagonal()  # [N s/m, N m^3 s, N m^3 s]
    array([5.19540885e+03, 2.54575034e-05, 2.54575034e-05])
    """
    backbone = section_properties(RAO2021_MATERIAL, RAO2021_SECTION)
    elongation = backbone.elongation_stiffness(RAO2021_LENGTH)
    bending = backbone.bending_angle_stiffness(RAO2021_LENGTH)
    damping = np.zeros(3)
    if damping_time is not None:
        damping_time = real_scalar("damping_time [s]", damping_time, positive=True)
        damping = damping_time * np.array([elongation, *[bending * RAO2021_LENGTH**2] * 2])
    segment = Segment(
        rest_length=RAO2021_LENGTH,
        mass=RAO2021_BACKBONE_DENSITY * RAO2021_LENGTH + RAO2021_DISKS * RAO2021_DISK_MASS,
        radius=RAO2021_PITCH,
        elongation_stiffness=LinearStiffness(elongation),
        bending_stiffness=LinearStiffness(bending),
        damping=damping,
    )
    g = np.array([0.0, 0.0, -9.81]) if gravity else np.zeros(3)
    return Robot(segments=(segment, segment), gravity=g)


RAO2021_T_MAX = 8.0
"""Default upper tension of :func:`rao2021_tendons` [N]: the largest of the source's
cases (it gives no bound). It keeps every held tension inside the model's domain: a
proximal and a distal tendon of one azimuth both at 8 N bend segment 0 by
``2 x 8 N x 10 mm / k_b`` = 3.1 rad, half of the full turn the domain allows (above
16 N they bend it beyond)."""


def rao2021_tendons(*, t_max: float = RAO2021_T_MAX) -> TendonActuator:
    """The tendons of :func:`rao2021`: three per segment at 10 mm from the backbone, at
    the azimuths :data:`RAO2021_AZIMUTHS` (90, -30 and 210 degrees from +x toward +y),
    the proximal set (tensions 0-2) tied to the tip of segment 0 and the distal set
    (tensions 3-5, same azimuths) to the tip of segment 1, through segment 0. The
    ordering is the repo's (``F = [F1 F2 F3 F4 F5 F6]``); no friction (none in the
    source). A pulled tendon bends its segment toward itself, as in the repo.

    Parameters
    ----------
    t_max : float
        Upper tension bound of every tendon [N] (default :data:`RAO2021_T_MAX`, 8 N:
        the source gives none; its cases use up to 8 N).

    Examples
    --------
    >>> import softcurve as sc
    >>> actuator = sc.presets.rao2021_tendons()
    >>> actuator.n_inputs, [t.anchor for t in actuator.tendons]
    (6, [0, 0, 0, 1, 1, 1])
    >>> tau = actuator.generalized_force([0.2, 0, 0, 0.2, 0, 0], [1, 0, 0, 0, 0, 0])
    >>> tau.round(6) + 0.0  # [N, N m, N m] per segment: tendon 1 (+y) shortens, bends to +y
    array([-1.   ,  0.   ,  0.002,  0.   ,  0.   ,  0.   ])
    """
    return TendonActuator.three_per_segment(
        distance=RAO2021_PITCH, t_max=t_max, n_segments=2, azimuths=RAO2021_AZIMUTHS
    )
