"""Sweeps: designs, outputs, resuming a killed sweep, the Dask engine, bad configurations."""

from __future__ import annotations

import copy
import json
import re

import numpy as np
import pytest

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

import softcurve as sc  # noqa: E402
from softcurve.base.status import Status  # noqa: E402
from softcurve.cli import main  # noqa: E402
from softcurve.scenarios.config import ConfigError  # noqa: E402
from softcurve.scenarios.sweep import run_sweep, settling_time, summarize  # noqa: E402
from softcurve.scenarios.sweep_config import load_sweep, sweep_from_dict  # noqa: E402
from softcurve.simulation.batch._batch import simulate_batch  # noqa: E402

BASE = {
    "robot": {"preset": "ifac2020"},
    "simulation": {"t_final": 0.3, "q0": [0.064, 20.0, 0.0], "qd0": [0.0, 0.0, 300.0]},
    "sweep": {
        "design": "grid",
        "chunk_size": 2,
        "output_dt": 0.01,
        "variables": [
            {"name": "q0[1]", "low": -20.0, "high": 20.0, "points": 3},
            {"name": "segments[0].bending_stiffness.a1", "low": 0.42, "high": 0.5, "points": 2},
        ],
    },
}


def config_dict(**sweep_changes) -> dict:
    data = copy.deepcopy(BASE)
    data["sweep"].update(sweep_changes)
    return data


def write_toml(path, data) -> None:
    """A minimal TOML writer for the tables used here (JSON scalars and arrays are TOML)."""
    lines = []
    for table in ("robot", "simulation", "sweep"):
        lines.append(f"[{table}]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in data[table].items() if k != "variables"]
    for variable in data["sweep"]["variables"]:
        lines.append("[[sweep.variables]]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in variable.items()]
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def config():
    return sweep_from_dict(config_dict(), "test.toml")


@pytest.fixture(scope="module")
def uninterrupted(config, tmp_path_factory):
    return run_sweep(config, tmp_path_factory.mktemp("full"), workers=0)


# -- designs and outputs ---------------------------------------------------------------------
def test_designs():
    grid = sweep_from_dict(config_dict(), "t").design_points()
    assert grid.shape == (6, 2)
    assert sorted(set(grid[:, 0])) == [-20.0, 0.0, 20.0] and sorted(set(grid[:, 1])) == [0.42, 0.5]
    assert len({tuple(row) for row in grid}) == 6
    log_grid = [{"name": "qd0[2]", "low": 1.0, "high": 100.0, "points": 3, "scale": "log"}]
    values = sweep_from_dict(config_dict(variables=log_grid), "t").design_points()[:, 0]
    assert values[0] == 1.0 and values[2] == 100.0  # the ends exactly
    assert values[1] == pytest.approx(10.0, rel=1e-15)  # geometric spacing
    variables = [
        {"name": "qd0[2]", "low": 1.0, "high": 100.0, "scale": "log"},
        {"name": "tau[0]", "low": -0.1, "high": 0.1},
    ]
    for design, samples in (("random", 50), ("sobol", 64)):
        data = config_dict(design=design, samples=samples, seed=3, variables=variables)
        points = sweep_from_dict(data, "t").design_points()
        assert points.shape == (samples, 2)
        assert np.all((points >= [1.0, -0.1]) & (points <= [100.0, 0.1]))
        np.testing.assert_array_equal(points, sweep_from_dict(data, "t").design_points())
    # a Sobol design is balanced: on the log scale, half of the points in each half range
    assert np.sum(np.log10(points[:, 0]) < 1.0) == 32


def test_settling_time_definition():
    t = np.linspace(0.0, 1.0, 101)
    tip = np.zeros((2, t.size, 3))
    tip[0, :, 0] = np.exp(-5.0 * t)
    distance = np.abs(tip[0, :, 0] - tip[0, -1, 0])
    expected = t[np.flatnonzero(distance > 0.02 * distance.max())[-1] + 1]
    result = settling_time(t, tip, 0.02)
    assert result[0] == pytest.approx(expected) and 0.7 < expected < 0.8  # about ln(50)/5
    assert result[1] == 0.0  # a tip that never moves has settled at once


def test_summaries_match_the_batch(paper_model):
    q0s = np.array([[0.064, 20.0, 0.0], [0.064, -5.0, 3.0]])
    batch = simulate_batch(paper_model, q0s, np.zeros(3), t_final=0.3, dt=0.01)
    columns = summarize(batch, ("final_state", "tip_range", "peak_energy"), 0.02)
    assert columns["final_kx1"][1] == batch.q[1, -1, 1]
    assert columns["final_lam3"][0] == batch.lam[0, -1, 2]
    np.testing.assert_array_equal(columns["tip_range_y"], np.ptp(batch.tip[:, :, 1], axis=1))
    assert columns["peak_energy"][0] == pytest.approx(batch.member(0).energy().max(), rel=1e-12)
    assert "settling_time" not in columns


# -- running, resuming, Dask -----------------------------------------------------------------
def test_sweep_table(config, uninterrupted):
    table = uninterrupted.table.to_pydict()
    assert uninterrupted.failed == 0 and table["index"] == list(range(6))
    assert uninterrupted.status is Status.SUCCESS and uninterrupted.success
    np.testing.assert_array_equal(
        np.column_stack([table["q0[1]"], table["segments[0].bending_stiffness.a1"]]),
        config.design_points(),
    )
    assert set(table["status"]) == {"success"}
    # mirror symmetry x -> -x: an initial bend of -20 and +20 1/m swing the tip as far;
    # the bending stiffness changes the swing
    swing = np.array(table["tip_range_x"]).reshape(3, 2)  # rows: q0[1]; columns: a1
    np.testing.assert_allclose(swing[0], swing[2], rtol=1e-6)
    assert np.all(np.abs(swing[[0, 2], 1] - swing[[0, 2], 0]) > 1e-3 * swing[[0, 2], 0])


def test_interrupted_sweep_resumes_to_the_same_table(config, uninterrupted, tmp_path):
    def kill_after_one(chunk, done, total):
        if done == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(config, tmp_path, workers=0, on_chunk=kill_after_one)
    assert len(list((tmp_path / "parts").glob("chunk-*.parquet"))) == 1
    assert not (tmp_path / "results.parquet").exists()
    resumed = run_sweep(config, tmp_path, workers=0)
    assert (resumed.chunks_run, resumed.chunks_skipped) == (2, 1)
    assert resumed.table.equals(uninterrupted.table)
    assert pq.read_table(tmp_path / "results.parquet").equals(uninterrupted.table)


def test_another_configuration_in_the_same_folder_is_refused(uninterrupted):
    other = sweep_from_dict(config_dict(output_dt=0.02), "other.toml")
    with pytest.raises(ConfigError, match="another sweep"):
        run_sweep(other, uninterrupted.path.parent, workers=0)


def test_dask_cluster_gives_the_local_table(config, uninterrupted, tmp_path):
    """A LocalCluster on loopback, addressed as ``--scheduler tcp://127.0.0.1:PORT`` is."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=1,
        processes=False,
        protocol="tcp",
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        result = run_sweep(config, tmp_path, scheduler=cluster.scheduler_address)
    assert result.table.equals(uninterrupted.table)


def test_process_pool_gives_the_local_table(config, uninterrupted, tmp_path):
    result = run_sweep(config, tmp_path, workers=2)
    assert result.table.equals(uninterrupted.table)


# -- bad configurations ----------------------------------------------------------------------
def one(name, low, high, **more):
    return {"variables": [{"name": name, "low": low, "high": high, **more}]}


BAD = [
    ({"design": "latin"}, r"sweep\.design: must be one of grid, random, sobol"),
    ({"design": "sobol", "samples": 100}, r"sweep\.samples: must be a power of 2"),
    ({"design": "random"}, r"sweep\.samples: is required"),
    ({"outputs": ["final_state", "overshoot"]}, r"sweep\.outputs: unknown output 'overshoot'"),
    ({"chunk_size": 0}, r"sweep\.chunk_size: must be >= 1"),
    ({"quadrature_nodes": 0}, r"sweep\.quadrature_nodes: must be in \[1, 64\]"),
    ({"seed": -1}, r"sweep\.seed: must be >= 0"),
    ({"output_dt": 1.0}, r"sweep\.output_dt: must be <= simulation\.t_final"),
    ({"color": "red"}, r"sweep\.color: unknown key"),
    (one("segments[0].stiffness", 0, 1, points=2), r"variables\[0\]\.name: .* is neither"),
    (one("q0[3]", 0, 1, points=2), r"index out of range"),
    (one("q0[1]", 1, 1, points=2), r"variables\[0\]\.high: must be > low"),
    (one("q0[1]", 1, 2), r"variables\[0\]\.points: is required for a grid"),
    (one("q0[1]", -1, 2, points=2, scale="log"), r"variables\[0\]\.low: must be > 0 on a log"),
    (one("q0[0]", -0.01, 0.07, points=2), r"q0\[0\] = -0.01 is outside the model's domain .*0 < l"),
    (
        one("segments[0].bending_stiffness.a1", 0.3, 0.5, points=2),
        r"corner segments\[0\]\.bending_stiffness\.a1 = 0\.3 of the design is invalid",
    ),
    (
        {"variables": [{"name": "q0[1]", "low": 0, "high": 1, "points": 2}] * 2},
        r"'q0\[1\]' appears more than once",
    ),
]


@pytest.mark.parametrize("change, message", BAD)
def test_bad_configurations_fail_before_any_work(change, message):
    with pytest.raises(ConfigError, match=message):
        sweep_from_dict(config_dict(**change), "bad.toml")


def test_cli_sweep_and_bad_file(tmp_path, capsys):
    good, bad = tmp_path / "good.toml", tmp_path / "bad.toml"
    write_toml(good, config_dict())
    out = tmp_path / "out"
    assert main(["sweep", str(good), "-o", str(out), "--workers", "0", "--figure"]) == 0
    printed = capsys.readouterr().out
    assert "6 simulations" in printed and f"figure      {out / 'sweep.png'}" in printed
    rate = re.search(r"\((\S+) simulated s per s\)", printed)
    assert rate is not None and float(rate.group(1)) > 0  # significant digits, never "0"
    assert pq.read_table(out / "results.parquet").num_rows == 6
    assert (out / "sweep.png").read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    never = str(tmp_path / "never")
    assert main(["sweep", str(good), "-o", never, "--figure", "summary.xyz"]) == 2
    assert "--figure summary.xyz: the suffix must be one of" in capsys.readouterr().err
    write_toml(bad, config_dict(design="sobol", samples=12))
    assert main(["sweep", str(bad), "-o", str(tmp_path / "never")]) == 2
    assert "sweep.samples: must be a power of 2" in capsys.readouterr().err
    assert not (tmp_path / "never").exists()


def test_sweep_killed_with_sigkill_resumes_losing_nothing(tmp_path):
    """``kill -9`` of a running ``softcurve sweep``, then the same command again: the table
    equals that of an uninterrupted run."""
    import os
    import signal
    import subprocess
    import sys
    import time

    data = config_dict(chunk_size=1)
    data["simulation"]["t_final"] = 2.0
    path = tmp_path / "sweep.toml"
    write_toml(path, data)
    out = tmp_path / "killed"
    cli = "import sys; from softcurve.cli import main; sys.exit(main())"
    command = [sys.executable, "-c", cli, "sweep", str(path), "-o", str(out), "--workers", "0",
               "--no-progress"]  # fmt: skip
    log = tmp_path / "stderr.txt"
    with open(log, "wb") as stderr:
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=stderr)
        deadline = time.monotonic() + 60
        while not list(out.glob("parts/chunk-*.parquet")) and time.monotonic() < deadline:
            if process.poll() is not None:
                pytest.fail(f"the sweep ended before it was killed: {log.read_text()}")
            time.sleep(0.005)
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
    written = len(list(out.glob("parts/chunk-*.parquet")))
    assert 1 <= written < 6 and not (out / "results.parquet").exists()
    resumed = subprocess.run(command, capture_output=True, text=True, check=False)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{6 - written} run, {written} already done" in resumed.stdout
    reference = run_sweep(load_sweep(path), tmp_path / "reference", workers=0)
    assert pq.read_table(out / "results.parquet").equals(reference.table)


def test_failed_simulations_are_rows_with_status_and_nan_outputs(tmp_path, capsys):
    """Few integrator steps allowed: the robot at rest succeeds, the violently launched one
    fails; its row says so, its outputs are NaN and the command exits with code 1."""
    data = config_dict(output_dt=0.1, variables=[
        {"name": "qd0[2]", "low": 0.0, "high": 1e4, "points": 2}])  # fmt: skip
    data["simulation"].update(q0=[0.0644, 0.0, 0.0], qd0=[0.0, 0.0, 0.0], max_steps=150)
    result = run_sweep(sweep_from_dict(data, "t"), tmp_path / "api", workers=0)
    table = result.table.to_pydict()
    assert result.failed == 1 and table["status"] == ["success", "integration_failed"]
    assert result.status is Status.PARTIAL and "1 of 2 simulations failed" in result.message
    assert "CV_TOO_MUCH_WORK" in table["message"][1]
    assert np.isnan(table["settling_time"][1]) and np.isnan(table["final_l1"][1])
    assert np.isfinite(table["settling_time"][0]) and np.isfinite(table["peak_energy"][0])
    path = tmp_path / "failing.toml"
    write_toml(path, data)
    assert main(["sweep", str(path), "-o", str(tmp_path / "cli"), "--workers", "0"]) == 1
    assert "1 simulation(s) failed" in capsys.readouterr().err


@pytest.mark.parametrize("name, size", [("sweep_bending.toml", 256), ("sweep_grid.toml", 20)])
def test_example_files_are_valid(name, size):
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / name
    config = load_sweep(path)
    assert config.size == size and config.design_points().shape == (size, len(config.variables))


# -- the figure of the table -----------------------------------------------------------------
def test_sweep_figure_draws_each_output_against_each_variable(uninterrupted):
    import matplotlib.pyplot as plt

    from softcurve.figures import plot_sweep

    variables = ["q0[1]", "segments[0].bending_stiffness.a1"]
    table = uninterrupted.table.to_pydict()
    pd = pytest.importorskip("pandas")
    rows = ["final tip x [mm]", "final tip y [mm]", "final tip z [mm]"]
    rows += ["tip range x [mm]", "tip range y [mm]", "tip range z [mm]"]
    rows += ["settling time [s]", "peak energy [J]"]
    labels = ["initial curvature kx, segment 0 [1/m]", "segment 0: bending stiffness a1 [N m/rad]"]
    for source in (uninterrupted.table, pd.read_parquet(uninterrupted.path), table):
        figure = uninterrupted.plot() if source is table else plot_sweep(source)
        axes = figure.axes
        assert len(axes) == len(rows) * 2  # one output per row, each on its own scale
        assert [a.get_ylabel() for a in axes[::2]] == rows
        # the result knows the variables' units; a bare table gives their names
        assert [a.get_xlabel() for a in axes[-2:]] == (labels if source is table else variables)
        for v, variable in enumerate(variables):  # the points are the table's values
            x, y = axes[12 + v].lines[0].get_data()
            np.testing.assert_array_equal(x, table[variable])
            np.testing.assert_array_equal(y, table["settling_time"])
        x_tip, z_tip = (axes[k].lines[0].get_data()[1] for k in (0, 4))
        np.testing.assert_allclose(z_tip, 1e3 * np.array(table["final_tip_z"]))  # [mm]
        np.testing.assert_allclose(x_tip, 1e3 * np.array(table["final_tip_x"]))
        plt.close(figure)
    figure = plot_sweep(uninterrupted.table, variables="q0[1]", labels={"q0[1]": "kx [1/m]"})
    assert len(figure.axes) == len(rows) and figure.axes[-1].get_xlabel() == "kx [1/m]"
    plt.close(figure)


def test_sweep_figure_of_failed_rows_and_bad_arguments():
    import matplotlib.pyplot as plt

    from softcurve.base.validation import ParameterError
    from softcurve.figures import plot_sweep

    table = {
        "index": np.arange(3),
        "tensions[0]": np.array([0.0, 1.0, 2.0]),
        "peak_energy": np.array([0.1, np.nan, 0.3]),
        "status": np.array(["success", "integration_failed", "success"]),
        "message": np.array(["", "CVODES failed", ""]),
    }
    figure = plot_sweep(table)
    assert figure.get_suptitle() == "sweep of 3 simulations, 1 failed (not drawn)"
    assert [a.get_ylabel() for a in figure.axes] == ["peak energy [J]"]
    _, given = plt.subplots(1, 1)
    assert plot_sweep(table, given) is given.figure  # the caller's Axes
    with pytest.raises(ParameterError, match="variables: 'peak_energy' is not a swept"):
        plot_sweep(table, variables=["peak_energy"])
    with pytest.raises(ParameterError, match="needs at least one swept variable"):
        plot_sweep({"index": [0], "status": ["success"], "peak_energy": [1.0]})
    with pytest.raises(ParameterError, match="table must be a sweep table"):
        plot_sweep(42)
    plt.close("all")


def test_reading_the_table_as_docs_sweeps_shows(uninterrupted):
    pd = pytest.importorskip("pandas")
    table = pd.read_parquet(uninterrupted.path)
    ok = table[table.status == "success"]
    mean = ok.groupby("q0[1]")["settling_time"].mean()
    assert list(mean.index) == [-20.0, 0.0, 20.0] and np.isfinite(mean).all()


def test_swept_variables_are_labelled_in_words_with_their_units():
    """The sweep figure's x axes: what each swept name sets, with its unit (before: the
    raw name, ``segments[0].elongation_stiffness.a1``, without one)."""
    from pathlib import Path

    from softcurve.scenarios.sweep_variables import variable_label

    examples = Path(__file__).resolve().parents[1] / "examples"
    scenario = load_sweep(examples / "sweep_tendons.toml").scenario
    assert variable_label(scenario, "q0[1]") == "initial curvature kx, segment 0 [1/m]"
    assert variable_label(scenario, "qd0[0]") == "initial rate of length l, segment 0 [m/s]"
    assert variable_label(scenario, "tensions[0]") == "tensions[0] [N]"
    assert variable_label(scenario, "inputs[2]") == "tensions[2] [N]"
    assert variable_label(scenario, "tendons[0].distance") == "tendons[0].distance"
    layout = scenario.robot.layout
    expected = {
        "segments[0].elongation_stiffness.a1": "segment 0: elongation stiffness a1 [N/m]",
        "segments[0].elongation_stiffness.a3": "segment 0: elongation stiffness a3 [1/m]",
        "segments[0].bending_stiffness.a1": "segment 0: bending stiffness a1 [N m/rad]",
        "segments[0].damping[1,1]": "segment 0: damping[1,1] [N m^3 s]",
        "segments[0].damping[0,1]": "segment 0: damping[0,1] [N m s]",
        "gravity[2]": "gravity[2] [m/s^2]",
    }
    for name, label in expected.items():
        assert variable_label(scenario, name) == label == layout.label(name)
    assert len(layout.units) == len(layout.names) == layout.size
    linear = sc.presets.rao2021().layout  # linear laws: one parameter each
    assert linear.unit("segments[1].bending_stiffness.k0") == "N m/rad"
    assert linear.unit("segments[1].elongation_stiffness.k0") == "N/m"
