"""Robots from the literature, as ready-made :class:`~softcurve.description.robot.Robot`
values."""

from __future__ import annotations

import numpy as np

from softcurve.description.materials import Creep, TanhStiffness
from softcurve.description.robot import Robot, Segment


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
