"""Bad input that used to reach the solver (issue 44, item 6): each value is refused
before any work, through the Python API with a ParameterError naming the value and its
allowed range, and through the command line with exit 2, one line on stderr, no
traceback and no output folder."""

from __future__ import annotations

import ctypes
import math
import re

import numpy as np
import pytest

import softcurve as sc
from softcurve.analysis.statics import START_BYTES, physical_memory, starts_count
from softcurve.base.status import Status
from softcurve.base.validation import FLOAT_MAX, ParameterError
from softcurve.cli import main
from softcurve.compiled._export import MAX_PREFIX, c_identifier
from softcurve.control.controllers import PDGravityElastic
from softcurve.control.references import Reference
from softcurve.description.robot import MAX_REST_LENGTH, MAX_STRETCH
from softcurve.figures.scene import build_scene
from softcurve.identification.experiments._loading import Experiment
from softcurve.identification.fits._dynamic import fit_trajectory, predict_trajectory
from softcurve.identification.fits._parameters import Free
from softcurve.identification.maps import bending_angle_map
from softcurve.simulation import MAX_STEPS, MIN_TIME, SimulationSettings
from softcurve.simulation.solvers._driver import Options

SEG = "segments[0]."


def refused(argv, capsys, option: str, folder) -> str:
    """stderr of ``softcurve argv``, checked: exit 2, one line naming ``option``, no
    traceback, ``folder`` not created."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert option in err, err
    assert not folder.exists()
    return err


# -- a segment's rest length -----------------------------------------------------------------
def test_a_rest_length_beyond_the_float_range_is_refused():
    segment = sc.presets.ifac2020().segments[0]
    with pytest.raises(ParameterError, match=r"rest_length must be in \(0, 1.16e\+76\] m.*1e\+300"):
        segment.replace(rest_length=1e300)
    assert segment.replace(rest_length=MAX_REST_LENGTH).rest_length == MAX_REST_LENGTH
    # the bound: the mass matrix's l^4 at MAX_STRETCH rest lengths is a float's size
    assert 4 * math.log(MAX_STRETCH * MAX_REST_LENGTH) <= math.log(FLOAT_MAX) * (1 + 1e-15)


# -- the step budget -----------------------------------------------------------------------
def test_a_step_budget_beyond_a_c_long_is_refused(tmp_path, capsys):
    for steps in (2**63, 2**64 + 1):
        with pytest.raises(
            ParameterError, match=rf"max_steps must be an integer in \[1, {MAX_STEPS}\]"
        ):
            SimulationSettings(max_steps=steps)
    assert SimulationSettings(max_steps=MAX_STEPS).max_steps == MAX_STEPS
    out = tmp_path / "out"
    err = refused(["simulate", "--max-steps", 2**64 + 1, "-o", out], capsys, "--max-steps", out)
    assert str(MAX_STEPS) in err and str(2**64 + 1) in err


def test_the_step_budget_bound_is_the_c_drivers_field_type():
    field = dict((name, kind) for name, kind, *_ in Options._fields_)["max_steps"]
    assert 2 ** (8 * ctypes.sizeof(field) - 1) - 1 == MAX_STEPS
    options = Options(max_steps=MAX_STEPS)
    assert options.max_steps == MAX_STEPS  # no wrap-around


# -- times too short for CVODES ------------------------------------------------------------
def test_an_end_time_and_interval_below_the_time_resolution_are_refused(tmp_path, capsys):
    with pytest.raises(ParameterError, match=r"t_final must be >= 1.49e-154 s.*1e-300"):
        SimulationSettings(t_final=1e-300, dt=1e-300)
    with pytest.raises(ParameterError, match=r"dt must be in \[1.49e-154, 1e-150\]"):
        SimulationSettings(t_final=1e-150, dt=1e-160, max_outputs=10**11)
    # t + dt == t: refused even where max_outputs would allow the count
    with pytest.raises(ParameterError, match=r"dt must be in \[2.22e-16, 1.0\]"):
        SimulationSettings(t_final=1.0, dt=1e-17, max_outputs=10**18)
    assert SimulationSettings(t_final=MIN_TIME, dt=MIN_TIME).dt == MIN_TIME
    out = tmp_path / "out"
    err = refused(
        ["simulate", "--t-final", "1e-300", "--dt", "1e-300", "-o", out], capsys, "--t-final", out
    )
    assert "1e-300" in err


def test_the_shortest_time_simulates(paper_model):
    run = sc.simulate(
        paper_model, [0.064, 25.0, 0.0], [0.0, 0.0, 0.0], t_final=MIN_TIME, dt=MIN_TIME
    )
    assert run.success, run.message


class Hold:
    """A controller of the protocol (not a softcurve class) that holds zero."""

    def __init__(self, sample_time):
        self.sample_time = sample_time

    def __call__(self, t, q, qd, lam):
        return np.zeros(3)


def test_a_controller_sample_time_below_the_time_resolution_is_refused(paper_model):
    reference = Reference.constant([0.064, 10.0, 0.0])
    with pytest.raises(ParameterError, match=r"sample_time must be >= 1.49e-154 s.*1e-300"):
        PDGravityElastic(paper_model, reference, kp=1.0, kd=0.1, sample_time=1e-300)
    q0, qd0 = [0.064, 25.0, 0.0], [0.0, 0.0, 0.0]
    with pytest.raises(ParameterError, match=r"controller.sample_time must be >= 1e-09 s.*1e-300"):
        sc.simulate(paper_model, q0, qd0, controller=Hold(1e-300), t_final=0.01, dt=0.01)
    # more samples than max_outputs: refused before the sample times are laid out
    with pytest.raises(ParameterError, match=r"controller.sample_time must be >= 1e-07 s.*1e-09"):
        sc.simulate(paper_model, q0, qd0, controller=Hold(1e-9), t_final=1.0, dt=0.01)


# -- equilibria: starts beyond the machine's memory ------------------------------------------
def test_more_starts_than_memory_holds_are_refused(two_segment_model, tmp_path, capsys):
    n = two_segment_model.n
    with pytest.raises(
        ParameterError, match=r"starts must be an integer in \[1, \d+\], got 100000000000"
    ):
        sc.equilibria(two_segment_model, starts=10**11)
    most = int(physical_memory() // (START_BYTES + 24 * n))
    assert starts_count("starts", most, n) == most
    with pytest.raises(ParameterError, match="bytes while the starts are drawn"):
        starts_count("starts", most + 1, n)
    folder = tmp_path / "figures"
    err = refused(
        ["equilibria", "--starts", 10**11, "--plot", folder / "e.png"], capsys, "--starts", folder
    )
    assert "100000000000" in err and "memory" in err


# -- codegen: a prefix longer than a file name can hold --------------------------------------
def test_a_prefix_longer_than_a_file_name_is_refused(paper_model, tmp_path, capsys):
    long = "a" * 5000
    with pytest.raises(
        ParameterError, match=rf"prefix must have 1 to {MAX_PREFIX} characters .*, got 5000"
    ):
        c_identifier("prefix", long)
    out = tmp_path / "c"
    with pytest.raises(ParameterError, match="prefix must have"):
        sc.export_c(paper_model, out, prefix=long)
    assert not out.exists()
    err = refused(["codegen", "--prefix", long, "-o", out], capsys, "--prefix", out)
    assert "5000" in err and len(err) < 400
    assert c_identifier("prefix", "a" * MAX_PREFIX)  # the longest is written (see below)


def test_the_longest_prefix_is_written(paper_model, tmp_path):
    exported = sc.export_c(paper_model, tmp_path, prefix="a" * MAX_PREFIX)
    assert exported.test.exists() and exported.source.exists()


# -- figures: a trajectory drawn with a model of another size --------------------------------
def test_a_trajectory_drawn_with_a_model_of_another_size_is_refused(paper_model, tmp_path):
    t = np.array([0.0, 0.1])
    q = np.tile([0.064, 10.0, 0.0, 0.064, 10.0, 0.0], (2, 1))
    two = sc.Trajectory(t=t, q=q, qd=np.zeros_like(q), lam=np.zeros((2, 6)))
    message = r"the trajectory has 6 coordinates, the model 3 \(1 element\(s\)\)"
    with pytest.raises(ParameterError, match=message):
        two.animate(tmp_path / "a.gif", model=paper_model)
    with pytest.raises(ParameterError, match=message):
        two.to_html(tmp_path / "a.html", model=paper_model)
    with pytest.raises(ParameterError, match=message):
        sc.figures.animate(two, tmp_path / "b.gif", paper_model)
    with pytest.raises(ParameterError, match=message):
        two.energy(paper_model)
    with pytest.raises(ParameterError, match=r"q has 6 coordinates"):
        build_scene(paper_model, q, ["a", "b"])
    assert list(tmp_path.iterdir()) == []


# -- identification --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def record():
    """Two seconds of a bending angle at 0.1 s (zeros: no integration is expected)."""
    t = np.linspace(0.0, 2.0, 21)
    return Experiment(t, {"beta": np.zeros_like(t)}, units={"beta": "deg"})


def paper_state():
    return np.array([0.064, 10.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])


def test_a_nan_initial_state_is_refused_before_integrating(paper_model, record):
    x0 = paper_state()
    x0[1] = np.nan
    free = [Free(SEG + "damping[1,1]")]
    with pytest.raises(
        ParameterError, match=r"x0 must be finite in every entry, got \[nan\] at entries \[1\]"
    ):
        fit_trajectory(paper_model, record, output=bending_angle_map(), x0=x0, free=free)


def test_more_free_parameters_than_data_values_are_not_identifiable_without_integrating(
    paper_model,
):
    t = np.array([0.0, 0.01, 0.02, 0.03])  # four data values
    data = Experiment(t, {"beta": np.zeros_like(t)}, units={"beta": "deg"})
    names = ["mass", "bending_stiffness.a1", "bending_stiffness.a2", "damping[0,0]",
             "damping[1,1]", "damping[2,2]"]  # fmt: skip
    free = [Free(SEG + name) for name in names]
    report = fit_trajectory(
        paper_model, data, output=bending_angle_map(), x0=paper_state(), free=free
    )
    assert report.status is Status.NOT_IDENTIFIABLE
    assert "6 free parameters on 4 data values" in report.message
    assert report.n_evaluations == 0 and report.n_jacobians == 0  # nothing integrated
    assert not report.identifiable.any() and np.isnan(report.predicted).all()


def test_a_prediction_window_longer_than_the_record_is_refused(paper_model, record):
    options = dict(output=bending_angle_map())
    fit = fit_trajectory(paper_model, record.trim(stop=0.2), x0=paper_state(), free=[], **options)
    assert fit.success, fit.message
    for window in (1e6, 2.0):
        with pytest.raises(
            ParameterError, match=r"window must be in \(0, 2\) s.*got " + re.escape(f"{window:g}")
        ):
            predict_trajectory(paper_model, record, fit, x0="window", window=window, **options)
