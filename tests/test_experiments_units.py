"""Experiments carry units (converted once to SI, the recorded unit kept), mismatches with
a map's units are caught, and MATLAB struct arrays of trials load with clear errors."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io

import softcurve as sc
from softcurve.identification.experiments._loading import load_csv, load_mat, load_mat_trials
from softcurve.identification.experiments._units import POUND_FORCE_PER_SQUARE_INCH, check_units
from softcurve.identification.maps import bellows_input_map, bending_angle_map, curvature_map

T = np.linspace(0.0, 1.0, 6)


def test_psi_is_the_pound_force_per_square_inch():
    # 1 lbf = 0.45359237 kg * 9.80665 m/s^2 and 1 in = 0.0254 m, both exact by definition
    assert POUND_FORCE_PER_SQUARE_INCH == pytest.approx(6894.757293168361, rel=1e-15)


@pytest.mark.parametrize(
    ("unit", "si", "factor"),
    [
        ("psi", "Pa", POUND_FORCE_PER_SQUARE_INCH),
        ("kPa", "Pa", 1e3),
        ("bar", "Pa", 1e5),
        ("mbar", "Pa", 1e2),
        ("Pa", "Pa", 1.0),
        ("mm", "m", 1e-3),
        ("cm", "m", 1e-2),
        ("1/cm", "1/m", 1e2),
        ("deg", "deg", 1.0),  # angles stay in the unit recorded
        ("rad", "rad", 1.0),
        ("", "", 1.0),
    ],
)
def test_columns_are_converted_once_to_si_and_the_recorded_unit_is_kept(unit, si, factor):
    raw = 3.0 + 7.0 * T
    e = sc.Experiment(T, {"y": raw}, {"p": 2 * raw}, {"y": unit, "p": unit}, "run")
    np.testing.assert_array_equal(e.signals["y"], raw * factor)  # exactly one multiplication
    np.testing.assert_array_equal(e.inputs["p"], 2 * raw * factor)
    assert e.units == {"y": si, "p": si}
    assert e.source_units == {"y": unit, "p": unit}
    # trimming, resampling and replacing signals do not convert again
    for copy in (e.trim(0.2), e.resample(0.25), e.with_signals(y=e.signals["y"])):
        assert copy.units == e.units and copy.source_units == e.source_units
    np.testing.assert_array_equal(e.with_signals(y=e.signals["y"]).signals["y"], e.signals["y"])
    np.testing.assert_array_equal(e.trim(0.2).signals["y"], e.signals["y"][1:])


def test_an_unknown_unit_names_the_signal_the_unit_and_the_known_ones():
    with pytest.raises(sc.ExperimentError, match=r"'p' has the unknown unit 'inH2O'.*'psi'"):
        sc.Experiment(T, {"y": T}, {"p": T}, {"p": "inH2O"}, "run")
    with pytest.raises(sc.ExperimentError, match=r"units given for \['q'\]"):
        sc.Experiment(T, {"y": T}, {"p": T}, {"q": "Pa"}, "run")


def test_a_unit_mismatch_with_a_map_is_caught_by_name():
    pressures = {f"p{i}": 1e4 + T for i in range(3)}
    psi = sc.Experiment(T, {"kx": T, "ky": T}, pressures, dict.fromkeys(pressures, "psi"))
    inputs = bellows_input_map(area=2e-5, distance=0.01)
    check_units(psi, output=curvature_map(), input_map=inputs)  # psi became Pa at load
    newtons = sc.Experiment(T, {"kx": T, "ky": T}, pressures, {"p1": "N", "kx": "1/cm"})
    with pytest.raises(sc.ExperimentError, match=r"input 'p1' is in 'N' but the input map "
                       r"expects 'Pa'; label it with one of \['MPa', 'Pa', 'bar'"):  # fmt: skip
        check_units(newtons, output=curvature_map(), input_map=inputs)
    # a map in millimetres against data labelled mm: the data were converted to metres
    millimetres = sc.Experiment(T, {"x": T, "y": T, "z": T}, units=dict.fromkeys("xyz", "mm"))
    frame = sc.SensorFrame("camera", scale=1000.0, unit="mm")
    model = sc.Model(sc.presets.ifac2020(), compile=False)
    with pytest.raises(sc.ExperimentError, match=r"signal 'x' is in 'm' \(recorded in 'mm'\), "
                       r"converted at load, but the output map gives 'mm'.*build the map "
                       r"in 'm' \(a scale of 1\)"):  # fmt: skip
        check_units(millimetres, output=sc.tip_position_map(model, frame=frame))
    check_units(millimetres, output=sc.tip_position_map(model, frame=sc.SensorFrame("camera")))
    metres = sc.Experiment(T, {"x": T, "y": T, "z": T}, units=dict.fromkeys("xyz", "m"))
    with pytest.raises(sc.ExperimentError, match=r"'x' is in 'm' but the output map expects "
                       r"'mm'; label it"):  # fmt: skip
        check_units(metres, output=sc.tip_position_map(model, frame=frame))
    angles = sc.Experiment(T, {"beta": T}, units={"beta": "rad"})
    with pytest.raises(sc.ExperimentError, match=r"signal 'beta' is in 'rad' but the output "
                       "map expects 'deg'"):  # fmt: skip
        check_units(angles, output=bending_angle_map())
    check_units(angles, output=bending_angle_map(degrees=False))
    unlabelled = sc.Experiment(T, {"beta": T}, {"p0": T})
    check_units(unlabelled, output=bending_angle_map())  # nothing to check
    with pytest.raises(sc.ExperimentError, match="reads 3 inputs"):
        check_units(unlabelled, input_map=inputs)


def test_csv_units_are_converted_at_load(tmp_path):
    path = tmp_path / "run.csv"
    path.write_text("t,x [mm],p\n0,10,1\n0.1,20,2\n")
    e = load_csv(path, signals={"x": "x [mm]"}, inputs=["p"], units={"x": "mm", "p": "bar"})
    np.testing.assert_array_equal(e.signals["x"], np.array([10.0, 20.0]) * 1e-3)
    np.testing.assert_array_equal(e.inputs["p"], np.array([1.0, 2.0]) * 1e5)
    assert e.source_units == {"x": "mm", "p": "bar"}


# -- MATLAB struct arrays -------------------------------------------------------------------


@pytest.fixture
def trials_file(tmp_path):
    """A 1x3 struct array ``train`` of trials (fields t, y, p) and a nested struct."""
    trials = np.empty((1, 3), dtype=[("t", "O"), ("y", "O"), ("p", "O")])
    for k in range(3):
        pressures = np.column_stack([T, 2 * T, 3 * T]) * (k + 1)
        trials[0, k] = (T[:, None], (k + T)[None, :], pressures)
    nested = {"rig": {"pos": np.column_stack([T, -T]), "name": "arm"}, "rate": 12.0}
    path = tmp_path / "trials.mat"
    scipy.io.savemat(path, {"train": trials, "meta": nested, "U_": np.column_stack([T, 5 * T])})
    return path


def test_struct_array_trials_load_by_root_or_selector(trials_file):
    inputs = {f"p{i}": f"p:{i}" for i in range(3)}
    units = dict.fromkeys(inputs, "psi")
    e = load_mat(trials_file, root="train:1", time="t", signals={"y": "y"}, inputs=inputs,
                 units=units)  # fmt: skip
    assert e.name == "trials:train:1"
    np.testing.assert_array_equal(e.signals["y"], 1 + T)
    np.testing.assert_array_equal(e.inputs["p2"], 3 * T * 2 * POUND_FORCE_PER_SQUARE_INCH)
    same = load_mat(trials_file, time="train[1].t", signals={"y": "train[1].y"})
    np.testing.assert_array_equal(same.signals["y"], e.signals["y"])
    nested = load_mat(trials_file, time="train[0].t", signals={"z": "meta.rig.pos:1"})
    np.testing.assert_array_equal(nested.signals["z"], -T)
    old = load_mat(trials_file, time="train[0].t", signals={"u": "U_:1"})  # a matrix column
    np.testing.assert_array_equal(old.signals["u"], 5 * T)
    every = load_mat_trials(trials_file, "train", time="t", signals={"y": "y"})
    assert [x.name for x in every] == [f"trials:train[{k}]" for k in range(3)]
    for k, x in enumerate(every):
        np.testing.assert_array_equal(x.signals["y"], k + T)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        (
            {"signals": {"y": "train:0"}},
            r"'train:0' is a struct with fields \['p', 't', 'y'\], "
            r"not numbers \(select a field, e.g. 'train\[0\].t'\)",
        ),
        ({"signals": {"y": "train"}}, r"'train' is a struct or cell array of 3 elements"),
        ({"signals": {"y": "train[7].y"}}, r"'train' has 3 elements, \[7\] does not exist"),
        ({"signals": {"y": "train[0].w"}}, r"'train\[0\]' has no field 'w'; fields: \['p', 't'"),
        ({"signals": {"y": "meta.rig.name"}}, r"'meta.rig.name' is the text 'arm'"),
        ({"signals": {"y": "meta.rig.pos:5"}}, r"has 2 columns, column 5 does not exist"),
        ({"signals": {"y": "U_[0]"}}, r"'U_' is an array of shape \(6, 2\), not an array of"),
        ({"signals": {"y": "y"}, "root": "train"}, r"root 'train' is not a struct.*'train\[0\]'"),
        ({"signals": {"y": "y"}, "root": "meta.rig.pos"}, r"root 'meta.rig.pos' is not a struct"),
        ({"signals": {"y": "bad name!"}}, r"'bad name!' is not a selector"),
    ],
)
def test_every_loader_error_is_an_experiment_error_naming_the_file_and_field(
    trials_file, options, match
):
    options = {"time": "train[0].t", **options}
    with pytest.raises(sc.ExperimentError, match=match) as caught:
        load_mat(trials_file, **options)
    assert str(trials_file) in str(caught.value)


def test_missing_and_unreadable_files_are_experiment_errors(tmp_path):
    with pytest.raises(sc.ExperimentError, match="does not exist") as caught:
        load_mat(tmp_path / "missing.mat", time="t", signals={"y": "y"})
    assert isinstance(caught.value, FileNotFoundError)  # as before, for old callers
    (tmp_path / "junk.mat").write_bytes(b"not a mat file at all")
    with pytest.raises(sc.ExperimentError, match="junk.mat: not a readable MATLAB file"):
        load_mat(tmp_path / "junk.mat", time="t", signals={"y": "y"})
    with pytest.raises(sc.ExperimentError, match=r"'train' is an array of shape"):
        scipy.io.savemat(tmp_path / "flat.mat", {"train": T})
        load_mat_trials(tmp_path / "flat.mat", "train", time="t", signals={"y": "y"})


def test_csv_loader_errors_name_the_file(tmp_path):
    path = tmp_path / "run.csv"
    path.write_text("p,y\n1,2\n3,4\n")
    with pytest.raises(sc.ExperimentError, match=r"run.csv: sample_rate must be a positive"):
        load_csv(path, signals=["y"], time=None, sample_rate="fast")
    with pytest.raises(sc.ExperimentError, match=r"run.csv: 'p:1': 'p' is an array of shape"):
        load_csv(path, signals={"y": "p:1"}, time=None, sample_rate=10.0)
