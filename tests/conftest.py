"""Shared fixtures: compiled models are built once per session (the C library is cached on disk)."""

from __future__ import annotations

import os

os.environ.setdefault("MPLBACKEND", "Agg")  # the tests only: the package never picks a backend

import numpy as np
import pytest

import softcurve as sc


def assert_close(actual, expected, *, rtol=1e-12, atol=0.0, scale=None, what=""):
    """``|actual - expected| <= atol + rtol * scale`` elementwise; ``scale`` defaults to
    ``|expected|``, or a number such as the norm of ``expected`` for quantities whose
    entries span orders of magnitude."""
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    reference = np.abs(expected) if scale is None else scale
    error = np.abs(actual - expected)
    bound = atol + rtol * reference
    worst = np.max(error - bound)
    assert worst <= 0, (
        f"{what}: max error {np.max(error):.3e} exceeds tolerance "
        f"(atol={atol:g}, rtol={rtol:g}); actual={actual}, expected={expected}"
    )


@pytest.fixture(scope="session")
def paper_model() -> sc.Model:
    """The paper's robot with damping and creep, compiled."""
    return sc.Model(sc.presets.ifac2020())


@pytest.fixture(scope="session")
def conservative_model() -> sc.Model:
    """The paper's robot without damping and with creep that exerts no force: the same
    structure as ``paper_model``, so it reuses the compiled library (parameters are
    run-time inputs)."""
    robot = sc.presets.ifac2020(damping=False)
    segment = robot.segments[0]
    creep = sc.Creep(segment.creep.rate, segment.creep.gain, np.zeros(3))
    return sc.Model(robot.replace(segments=(segment.replace(creep=creep),)))


@pytest.fixture(scope="session")
def two_segment_model() -> sc.Model:
    """Two paper segments in series, in CasADi's virtual machine (no compile)."""
    return sc.Model(sc.presets.ifac2020().with_segments(2), compile=False)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20200712)


def random_state(rng, model, *, curvature=30.0, rate=(0.5, 200.0)):
    """A random configuration and velocity of ``model``'s robot near its rest length."""
    q, qd = [], []
    for segment in model.robot.segments:
        l0 = segment.rest_length
        q += [l0 * rng.uniform(0.8, 1.2), *rng.uniform(-curvature, curvature, 2)]
        qd += [rng.uniform(-rate[0], rate[0]), *rng.uniform(-rate[1], rate[1], 2)]
    return np.array(q), np.array(qd)
