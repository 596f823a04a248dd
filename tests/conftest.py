"""Shared fixtures: compiled models are built once per session (the C library is cached on disk)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")  # the tests only: the package never picks a backend

import numpy as np
import pytest

import softcurve as sc

LONGEST_FIRST = (
    "test_docs_identify.py",
    "test_examples.py",
    "test_identification_joint.py",
    "test_identify.py",
    "test_sensitivity_driver.py",
    "test_docs_site.py",
    "test_kinds.py",
    "test_strain_convergence.py",
    "test_tendons.py",
    "test_envs_press.py",
    "test_validation_goals.py",
)
"""The test files that take longest (from the 15 slowest tests of runs on two cores; the
examples' runs, about a minute in all), run first: pytest-xdist hands out whole files in
collection order, and a long file started last keeps one worker busy while the other
idles."""


def pytest_collection_modifyitems(config, items):
    """Move the files of :data:`LONGEST_FIRST` to the front, in that order (stable)."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


LONG_MODULE_PROPERTY = "long_module"
"""The property (``record_property``) under which tests/test_architecture.py records each
long module; :func:`pytest_terminal_summary` lists them."""

FIXED_STRIDE_PROPERTY = "fixed_stride"
"""The property under which tests/test_architecture.py records each place of its list of
constant-curvature strides that strides no more (its entry is to be removed)."""

SUMMARY_SECTIONS = {
    LONG_MODULE_PROPERTY: "long modules (docs/architecture.md)",
    FIXED_STRIDE_PROPERTY: "strides fixed: remove them from constant_curvature_only()",
}


def pytest_terminal_summary(terminalreporter):
    """List what the architecture test recorded (long modules, fixed strides): a report,
    not a failure (a warning would be one: pyproject.toml makes every warning an error)."""
    for property_name, heading in SUMMARY_SECTIONS.items():
        found = sorted(
            {
                value
                for report in terminalreporter.stats.get("passed", [])
                for name, value in getattr(report, "user_properties", ())
                if name == property_name
            }
        )
        if found:
            terminalreporter.section(heading)
            for line in found:
                terminalreporter.line(line)


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


def random_state(rng, model, *, curvature=30.0, rate=(0.5, 200.0), spread=0.3):
    """A random configuration and velocity of ``model``'s robot near its rest state:
    constant-curvature segments near their rest length with curvatures up to
    ``curvature``; other elements at their rest coordinates plus up to ``spread`` of
    their coordinate scale (rates up to ``rate[1] / 10`` scales per second)."""
    q, qd = [], []
    for segment in model.robot.segments:
        if isinstance(segment, sc.Segment):
            l0 = segment.rest_length
            q += [l0 * rng.uniform(0.8, 1.2), *rng.uniform(-curvature, curvature, 2)]
            qd += [rng.uniform(-rate[0], rate[0]), *rng.uniform(-rate[1], rate[1], 2)]
        else:
            scale, size = segment.coordinate_scale(), segment.n_coordinates
            q += list(segment.rest_configuration() + spread * scale * rng.uniform(-1, 1, size))
            qd += list(0.1 * rate[1] * scale * rng.uniform(-1, 1, size))
    return np.array(q), np.array(qd)


def compiler_refusing(folder, argument: str, log=None):
    """A C compiler (a shell script in ``folder``, for ``CC``) that fails when given
    ``argument`` (appending a line to ``log`` if given) and otherwise runs the system's;
    None where there is no C compiler."""
    real = shutil.which("cc") or shutil.which("gcc")
    if real is None:
        return None
    note = f" && echo x >> {log}" if log is not None else ""
    script = Path(folder) / f"cc-without{argument}"
    script.write_text(
        f'#!/bin/sh\nfor a in "$@"; do [ "$a" = {argument} ]{note} && exit 1; done\n'
        f'exec {real} "$@"\n'
    )
    script.chmod(0o755)
    return script


def sigint_default() -> None:
    """``preexec_fn`` of the Ctrl-C tests' processes: SIGINT handled as by a terminal's
    process. A shell without job control starts a background job with SIGINT ignored and
    its processes inherit that; Python then installs no KeyboardInterrupt handler and a
    Ctrl-C test would send its signal into nothing (the command ends with 0)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
