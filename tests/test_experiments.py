"""Experiment loading: typed structure, resampling, trimming, and clear errors for bad files."""

import numpy as np
import pytest
import scipy.io

from softcurve.identification.experiments._loading import (
    Experiment,
    ExperimentError,
    load_csv,
    load_mat,
)


def _write_csv(path, text):
    path.write_text(text)
    return path


def test_load_csv_reads_columns_and_units(tmp_path):
    path = _write_csv(tmp_path / "run.csv", "t,beta,p1\n0.0,1.0,10\n0.1,2.0,20\n0.2,4.0,30\n")
    e = load_csv(path, signals=["beta"], inputs=["p1"], units={"beta": "deg", "p1": "Pa"})
    np.testing.assert_array_equal(e.t, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(e.signals["beta"], [1.0, 2.0, 4.0])
    np.testing.assert_array_equal(e.input_matrix(), [[10.0], [20.0], [30.0]])
    assert e.units == {"beta": "deg", "p1": "Pa"}
    assert e.name == "run"


def test_load_mat_row_and_column_vectors_and_matrix_columns(tmp_path):
    t = np.linspace(0.0, 1.0, 11)
    scipy.io.savemat(tmp_path / "a.mat", {"x": t[None, :], "y": (2 * t)[:, None]})
    e = load_mat(tmp_path / "a.mat", time="x", signals={"beta": "y"})
    np.testing.assert_allclose(e.signals["beta"], 2 * t)
    u = np.column_stack([t, 3 * t, 5 * t])
    scipy.io.savemat(tmp_path / "b.mat", {"U_": u, "k": t[:, None]})
    e = load_mat(tmp_path / "b.mat", sample_rate=10.0, signals={"k": "k"}, inputs={"p3": "U_:2"})
    np.testing.assert_allclose(e.t, np.arange(11) / 10.0)
    np.testing.assert_allclose(e.inputs["p3"], 5 * t)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("t,beta\n0,1\n0.1,nan\n", "non-finite"),
        ("t,beta\n0,1\n0,2\n", "strictly increasing"),
        ("t,beta\n0,1\n0.1,abc\n", "'abc' is not a number"),
        ("t,beta\n0,1\n0.1\n", "1 fields, the header has 2"),
        ("t,gamma\n0,1\n0.1,2\n", "no variable or column 'beta'"),
        ("t,beta\n", "header row and at least one data row"),
    ],
)
def test_malformed_csv_is_rejected_with_a_clear_message(tmp_path, text, match):
    path = _write_csv(tmp_path / "bad.csv", text)
    with pytest.raises(ExperimentError, match=match):
        load_csv(path, signals=["beta"])


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("t,beta\n0,1\n0.1,2\n\n0.2,nan\n", r"bad.csv, line 5, column .beta.: non-finite"),
        ("t,beta\n0,1\n0.1,inf\n", r"bad.csv, line 3, column 'beta': non-finite value inf"),
        ("t,beta\n0,1\nnan,2\n", r"bad.csv, line 3, column 't': non-finite value nan"),
        ("t,beta\n0,1\n0.1,2\n0.05,3\n", r"bad.csv, line 4: time must be strictly increasing, "
                                            r"but 't' is 0.05 s, not after 0.1 s on line 3"),
    ],
)  # fmt: skip
def test_csv_nan_and_time_not_increasing_name_the_line(tmp_path, text, match):
    path = _write_csv(tmp_path / "bad.csv", text)
    with pytest.raises(ExperimentError, match=match):
        load_csv(path, signals=["beta"])


def test_csv_nan_in_a_column_not_read_is_no_error(tmp_path):
    path = _write_csv(tmp_path / "run.csv", "t,beta,note\n0,1,nan\n0.1,2,1\n")
    np.testing.assert_array_equal(load_csv(path, signals=["beta"]).signals["beta"], [1.0, 2.0])


def test_fit_command_refuses_a_nan_cell_naming_the_line(tmp_path, capsys):
    from softcurve.cli import main

    path = _write_csv(tmp_path / "data.csv", "x,f\n0.1,0.2\n0.2,0.4\n0.3,nan\n0.4,0.8\n")
    code = main(["fit", str(path), "--strain", "x", "--force", "f", "--law", "linear"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert f"{path}, line 4, column 'f': non-finite value nan" in err


def test_malformed_mat_is_rejected(tmp_path):
    scipy.io.savemat(tmp_path / "m.mat", {"x": np.arange(5.0), "y": np.arange(4.0)})
    with pytest.raises(ExperimentError, match="4 samples but the time vector has 5"):
        load_mat(tmp_path / "m.mat", time="x", signals={"beta": "y"})
    with pytest.raises(ExperimentError, match=r"available: \['x', 'y'\]"):
        load_mat(tmp_path / "m.mat", time="x", signals={"beta": "z"})
    with pytest.raises(ExperimentError, match="exactly one of time"):
        load_mat(tmp_path / "m.mat", signals={"beta": "x"})
    (tmp_path / "junk.mat").write_bytes(b"not a mat file at all")
    with pytest.raises(ExperimentError, match="not a readable MATLAB file"):
        load_mat(tmp_path / "junk.mat", time="x", signals={"beta": "y"})
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_mat(tmp_path / "missing.mat", time="x", signals={"beta": "y"})


def test_resample_is_linear_interpolation_and_trim_keeps_the_window():
    t = np.linspace(0.0, 2.0, 201)
    e = Experiment(t, {"y": 3.0 * t + 1.0}, {"u": t**2}, {"y": "m"}, "ramp")
    r = e.resample(0.25)
    np.testing.assert_allclose(r.t, np.arange(9) * 0.25, atol=1e-15)
    np.testing.assert_allclose(r.signals["y"], 3.0 * r.t + 1.0, rtol=1e-12)
    np.testing.assert_allclose(r.inputs["u"], r.t**2, atol=1e-4)
    w = e.trim(0.5, 1.0, rezero=True)
    assert w.t[0] == 0.0 and w.duration == pytest.approx(0.5)
    np.testing.assert_allclose(w.signals["y"], 3.0 * (w.t + 0.5) + 1.0, rtol=1e-12)
    assert w.units["y"] == "m"
    with pytest.raises(ExperimentError, match="leaves 0 samples"):
        e.trim(5.0, 6.0)
    with pytest.raises(ExperimentError, match="dt must be a positive"):
        e.resample(-1.0)


def test_experiment_is_read_only_and_validates_names():
    e = Experiment([0.0, 1.0], {"y": [1.0, 2.0]})
    with pytest.raises(ValueError):
        e.signals["y"][0] = 5.0
    with pytest.raises(ExperimentError, match="both as signal and input"):
        Experiment([0.0, 1.0], {"y": [1.0, 2.0]}, {"y": [0.0, 0.0]})
    with pytest.raises(ExperimentError, match="no signal"):
        e.signal_matrix(["z"])
    with pytest.raises(ExperimentError, match="at least one measured signal"):
        Experiment([0.0, 1.0], {})


def test_thin_keeps_every_kth_sample_and_bin_averages_blocks():
    t = np.arange(10) * 0.1
    e = Experiment(t, {"x": t**2}, {"p": 2 * t}, {"x": "mm", "p": "kPa"}, name="trial")
    thin = e.thin(3)
    np.testing.assert_array_equal(thin.t, t[::3])
    np.testing.assert_array_equal(thin.signals["x"], e.signals["x"][::3])
    assert thin.units == e.units and thin.source_units == e.source_units
    binned = e.bin(4)  # two whole blocks of four; the last two samples are dropped
    np.testing.assert_allclose(binned.t, [0.15, 0.55], rtol=1e-14)
    np.testing.assert_allclose(binned.signals["x"], 1e-3 * np.array([0.035, 0.315]), rtol=1e-13)
    np.testing.assert_allclose(binned.inputs["p"], 2e3 * binned.t, rtol=1e-14)
    assert e.thin(1).t.size == 10 and e.bin(1).t.size == 10
    for method, bad in [(e.thin, 6), (e.bin, 0), (e.bin, 2.5), (e.thin, True)]:
        with pytest.raises(ValueError):
            method(bad)


def test_binning_keeps_the_intervals_and_thinning_widens_them():
    """Independent noise: a bin's mean has 1/k of the variance, so the standard error of a
    fitted level is the whole record's; thinning keeps 1/k of the samples of the same
    noise, so it is sqrt(k) times larger (the closed forms of a mean)."""
    from softcurve.identification.fits._report import covariance

    rng = np.random.default_rng(3)
    t = np.arange(40_000) * 0.01
    e = Experiment(t, {"y": 1.0 + 0.1 * rng.standard_normal(t.size)})

    def standard_error(experiment):
        y = experiment.signals["y"]
        cov, _ = covariance(np.ones((y.size, 1)), y - y.mean())
        return float(np.sqrt(cov[0, 0]))

    whole = standard_error(e)
    assert whole == pytest.approx(0.1 / np.sqrt(t.size), rel=0.02)
    assert standard_error(e.bin(10)) == pytest.approx(whole, rel=0.05)
    assert standard_error(e.thin(10)) == pytest.approx(np.sqrt(10) * whole, rel=0.05)
