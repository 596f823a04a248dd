"""The series-safe helpers: identities across both branches, derivatives at zero, continuity."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from softcurve.base import smooth as _smooth

from .conftest import assert_close

z_sym = ca.SX.sym("z")
DERIVATIVES = {}
for name in ("sinc", "cosc", "sinc3", "tanh_squared", "y_tanh", "log_cosh"):
    f = getattr(_smooth, name)(z_sym)
    d1 = ca.gradient(f, z_sym)
    d2 = ca.gradient(d1, z_sym)
    DERIVATIVES[name] = ca.Function(name, [z_sym], [f, d1, d2])


def evaluate(name, z):
    return np.array([[float(v) for v in DERIVATIVES[name](zi)] for zi in np.atleast_1d(z)])


Z = np.concatenate(
    [[0.0, 1e-300, 1e-18, 1e-9, 1e-4], np.linspace(0.01, 0.99, 25), np.linspace(1.0, 40.0, 25)]
)


def test_identities_hold_across_branches():
    """sinc = 1 - z sinc3 and cosc = sinc(z/4)^2 / 2 relate independent series."""
    sinc, cosc, sinc3 = (evaluate(n, Z)[:, 0] for n in ("sinc", "cosc", "sinc3"))
    assert_close(sinc, 1.0 - Z * sinc3, rtol=4e-16, atol=4e-16, what="sinc = 1 - z sinc3")
    assert_close(
        cosc, 0.5 * evaluate("sinc", Z / 4)[:, 0] ** 2, rtol=4e-16, atol=4e-17, what="half angle"
    )


@pytest.mark.parametrize("z", [0.3, 0.9, 1.5, 10.0, 400.0])
def test_values_against_numpy(z):
    y = np.sqrt(z)
    expected = {
        "sinc": np.sin(y) / y,
        "tanh_squared": np.tanh(y) ** 2,
        "y_tanh": y * np.tanh(y),
        "log_cosh": np.log(np.cosh(y)),
    }
    for name, value in expected.items():
        assert_close(evaluate(name, z)[0, 0], value, rtol=2e-15, what=name)


def test_exact_derivatives_at_zero():
    expected = {  # (f, df/dz, d2f/dz2) at z = 0 from the Taylor coefficients
        "sinc": (1.0, -1 / 6, 2 / 120),
        "cosc": (0.5, -1 / 24, 2 / 720),
        "sinc3": (1 / 6, -1 / 120, 2 / 5040),
        "tanh_squared": (0.0, 1.0, -4 / 3),
        "y_tanh": (0.0, 1.0, -2 / 3),
        "log_cosh": (0.0, 0.5, -1 / 6),
    }
    for name, values in expected.items():
        assert_close(evaluate(name, 0.0)[0], values, rtol=1e-15, atol=1e-300, what=name)


@pytest.mark.parametrize("name", sorted(DERIVATIVES))
def test_continuous_with_derivatives_at_the_switch(name):
    below = evaluate(name, _smooth.SERIES_THRESHOLD * (1 - 1e-13))[0]
    above = evaluate(name, _smooth.SERIES_THRESHOLD)[0]
    assert_close(below, above, rtol=1e-12, atol=1e-15, what=name)


def test_large_arguments_do_not_overflow():
    values = evaluate("log_cosh", 1e6)[0]
    assert np.all(np.isfinite(values))
    assert_close(values[0], 1e3 - np.log(2.0), rtol=1e-15)
    assert np.all(np.isfinite(evaluate("tanh_squared", 1e8)))


@pytest.mark.parametrize(("name", "offset"), [("sinc", 1), ("cosc", 2), ("sinc3", 3)])
def test_truncated_series_are_exact_with_two_derivatives(name, offset):
    """Against 20-term series summed in Python: the value and its first two derivatives
    in z agree to a few ulps below the series threshold."""
    k = np.arange(20)
    coefficients = np.array([(-1.0) ** i / math.factorial(2 * i + offset) for i in k])
    z = np.linspace(0.0, _smooth.SERIES_THRESHOLD, 101)[:-1]
    powers = z[:, None] ** k
    reference = np.stack(
        [
            powers @ coefficients,
            (z[:, None] ** np.maximum(k - 1, 0)) @ (k * coefficients),
            (z[:, None] ** np.maximum(k - 2, 0)) @ (k * (k - 1) * coefficients),
        ],
        axis=1,
    )
    assert_close(evaluate(name, z), reference, rtol=8 * np.finfo(float).eps)
