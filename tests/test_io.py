"""Scenario files (valid and invalid) and trajectory files (round trips)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import softcurve as sc
from softcurve.base.files import atomic_write
from softcurve.base.status import Status
from softcurve.scenarios.config import ConfigError, load_config, paper_scenario
from softcurve.simulation._settings import SimulationSettings

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture(scope="module")
def short_run(paper_model):
    tau = np.tile([0.01, 1e-3, -2e-3], (51, 1))
    return sc.simulate(paper_model, [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0], t_final=0.05, tau=tau)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_trajectory_round_trip_is_exact(short_run, tmp_path, suffix):
    path = short_run.save(tmp_path / f"run{suffix}")
    loaded = sc.load_trajectory(path)
    for name in ("t", "q", "qd", "lam", "tip", "tau"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(short_run, name), err_msg=name)
    assert loaded.status == "success" and loaded.message == short_run.message
    assert loaded.stats["steps"] == short_run.stats["steps"]
    assert loaded.model is None and loaded.t.size == 51


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_pressures_round_trip(paper_model, tmp_path, suffix):
    actuator = sc.PneumaticActuator.three_bellows(
        distance=0.012, area=2e-4, p_max=6e4, time_constant=0.02
    )
    run = sc.simulate(
        paper_model,
        [0.064, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        t_final=0.05,
        inputs=[2e4, 0.0, 1e4],
        actuator=actuator,
    )  # fmt: skip
    loaded = sc.load_trajectory(run.save(tmp_path / f"run{suffix}"))
    for name in ("q", "tau", "inputs"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(run, name), err_msg=name)
    if suffix == ".csv":
        header = (tmp_path / "run.csv").read_text().splitlines()[1].split(",")
        assert header[-6:] == ["tau1", "tau2", "tau3", "u1", "u2", "u3"]


def test_csv_has_named_columns_and_metadata(short_run, tmp_path):
    path = short_run.save(tmp_path / "run.csv")
    lines = path.read_text().splitlines()
    assert lines[0].startswith("# {") and '"status": "success"' in lines[0]
    assert lines[1].split(",")[:4] == ["t", "l1", "kx1", "ky1"]
    assert "tip_z" in lines[1] and lines[1].endswith("tau3")
    assert len(lines) == 2 + 51


def test_failed_trajectory_round_trips_with_its_status(paper_model, tmp_path):
    failed = sc.simulate(
        paper_model, [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0], t_final=0.5, max_steps=3
    )
    loaded = sc.load_trajectory(failed.save(tmp_path / "failed.csv"))
    assert loaded.status is Status.INTEGRATION_FAILED and not loaded.success
    assert loaded.t.size == failed.t.size


def test_unknown_suffix_is_refused(short_run, tmp_path):
    with pytest.raises(ValueError, match=r"\.csv or \.npz"):
        short_run.save(tmp_path / "run.txt")


def test_atomic_write_keeps_the_old_file_on_failure(tmp_path):
    target = atomic_write(tmp_path / "data.bin", b"old")
    from softcurve.base.files import atomic_path

    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_bytes(b"half")
        raise RuntimeError("interrupted")
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["data.bin"]  # no temporary left


def test_examples_load_and_the_paper_example_is_the_preset():
    names = ("ifac2020", "hanging", "two-segment")  # the scenario examples (others are sweeps)
    scenarios = {name: load_config(EXAMPLES / f"{name}.toml") for name in names}
    paper = scenarios["ifac2020"]
    np.testing.assert_array_equal(
        paper.robot.parameter_vector(), sc.presets.ifac2020().parameter_vector()
    )
    builtin = paper_scenario()
    assert paper.settings == builtin.settings
    for name in ("q0", "qd0"):
        assert getattr(paper, name) == getattr(builtin, name), name
    assert scenarios["hanging"].robot.gravity[2] == 9.81
    two = scenarios["two-segment"].robot
    assert two.n_segments == 2 and two.n_creep == 3
    assert isinstance(two.segments[1].bending_stiffness, sc.LinearStiffness)


SEGMENT = """
[[robot.segments]]
rest_length = 0.06
mass = 0.05
radius = 0.02
elongation_stiffness = { law = "linear", k0 = 500.0 }
bending_stiffness = { law = "linear", k0 = 0.05 }
"""


PNEUMATIC = """[robot]
preset = "ifac2020"
[actuation]
distance = 0.012
area = 2e-4
p_max = 6e4
"""


def test_the_pneumatic_example_drives_the_robot_by_pressures():
    scenario = load_config(EXAMPLES / "pneumatic_step.toml")
    assert scenario.inputs == (2.0e4, 0.0, 0.0)
    actuator = scenario.actuator()
    assert actuator.n_inputs == 3 and actuator.time_constant == 0.02


def test_a_minimal_file_gets_the_defaults(tmp_path):
    path = tmp_path / "minimal.toml"
    path.write_text("[robot]\n" + SEGMENT)
    scenario = load_config(path)
    q0, qd0, lam0 = scenario.initial_state()
    np.testing.assert_array_equal(q0, [0.06, 0.0, 0.0])
    assert scenario.settings == SimulationSettings() and lam0.size == 0


BAD = [
    ("[robot]\npreset = 'ifac2020'\ncolor = 'red'\n", "robot.color: unknown key"),
    ("[robot]\npreset = 'ifac2020'\n[simulaton]\nt_final = 1.0\n", "simulaton: unknown key"),
    ("[robot]\npreset = 'ifac2021'\n", "robot.preset: unknown preset"),
    (
        "[robot]\npreset = 'ifac2020'\n[simulation]\nt_final = 'long'\n",
        "simulation.t_final: must be a finite number",
    ),
    (
        "[robot]\npreset = 'ifac2020'\n[simulation]\nt_final = -1.0\n",
        "simulation.t_final: must be > 0",
    ),
    (
        "[robot]\npreset = 'ifac2020'\n[simulation]\nq0 = [0.064, 25.0]\n",
        "simulation.q0: must have 3 entries",
    ),
    (
        "[robot]\npreset = 'ifac2020'\n[simulation]\nq0 = [-0.064, 25.0, 0.0]\n",
        "simulation.q0: lengths",
    ),
    (
        "[robot]\npreset = 'ifac2020'\n[simulation]\nmethod = 'euler'\n",
        "simulation.method: must be one of",
    ),
    (
        "[robot]\npreset = 'ifac2020'\n[simulation]\nt_final = 1.0\ndt = 2.0\n",
        "simulation.dt: must be <= t_final",
    ),
    (
        "[robot]\npreset = 'ifac2020'\n[simulation]\nmax_steps = 1.5\n",
        "simulation.max_steps: must be an integer",
    ),
    ("[robot]\npreset = 'ifac2020'\ngravity = [0, 0]\n", "robot.gravity: must have 3 entries"),
    ("[robot]\npreset = 'ifac2020'\ncreep = 1\n", "robot.creep: must be true or false"),
    ("[simulation]\nt_final = 1.0\n", "robot: is required"),
    (
        "[robot]\n" + SEGMENT.replace("mass = 0.05", "mass = -0.05"),
        "robot.segments[0].mass: must be > 0",
    ),
    ("[robot]\n" + SEGMENT.replace("radius = 0.02\n", ""), "robot.segments[0].radius: is required"),
    (
        "[robot]\n" + SEGMENT.replace("k0 = 500.0", "k0 = 500.0, k1 = 2.0"),
        "robot.segments[0].elongation_stiffness.k1: unknown key",
    ),
    (
        "[robot]\n" + SEGMENT.replace('law = "linear", k0 = 0.05', 'law = "cubic", k0 = 0.05'),
        "robot.segments[0].bending_stiffness.law: must be 'tanh' or 'linear'",
    ),
    (
        "[robot]\n"
        + SEGMENT.replace(
            'law = "linear", k0 = 500.0', 'law = "tanh", a1 = 1.0, a2 = 2.0, a3 = 1.0'
        ),
        "robot.segments[0].elongation_stiffness: a2 must be < a1",
    ),
    (
        "[robot]\n" + SEGMENT + "damping = [1.0, -1.0, 1.0]\n",
        "robot.segments[0]: damping must be positive definite",
    ),
    (
        "[robot]\n" + SEGMENT + "creep = { gamma = [1.0, 2.0], compliance = [1.0, 1.0, 1.0] }\n",
        "robot.segments[0].creep.gamma: must have 6 entries",
    ),
    (
        "[robot]\n"
        + SEGMENT
        + "creep = { rate = [1.0, 1.0, 1.0], compliance = [1.0, 1.0, 1.0] }\n",
        "robot.segments[0].creep: needs gamma",
    ),
    ("[robot\npreset = 1\n", "not valid TOML"),
    (
        '[robot]\npreset = "ifac2020"\n[simulation]\ninputs = [1.0, 0.0, 0.0]\n',
        "simulation.inputs: needs an [actuation] table",
    ),
    (
        PNEUMATIC + "[simulation]\ninputs = [7e4, 0.0, 0.0]\n",
        "simulation.inputs: inputs[0] = 70000.0 Pa is outside its bounds",
    ),
    (
        PNEUMATIC + "[simulation]\ninputs = [1e4, 0.0]\n",
        "inputs must have shape (3,)",
    ),
    (
        PNEUMATIC + "[simulation]\ninputs = [1e4, 0.0, 0.0]\ntau = [0.0, 0.0, 0.0]\n",
        "simulation.inputs: give tau or inputs, not both",
    ),
]


@pytest.mark.parametrize(("text", "expected"), BAD, ids=[b[1][:40] for b in BAD])
def test_bad_files_name_file_key_and_reason(tmp_path, text, expected):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    message = str(info.value)
    assert message.startswith(f"{path}: "), message
    assert expected in message, message


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_config(tmp_path / "nothing.toml")


def test_a_scenario_checks_itself_also_when_replaced():
    """dataclasses.replace re-runs the checks: no route around them."""
    import dataclasses

    scenario = paper_scenario()
    with pytest.raises(sc.ParameterError, match="dt must be <= t_final"):
        dataclasses.replace(scenario, settings=scenario.settings.replace(t_final=1e-4))
    with pytest.raises(sc.ParameterError, match="q0 must have 3 entries"):
        dataclasses.replace(scenario, q0=(0.064, 25.0))
    with pytest.raises(sc.ParameterError, match="q0 lengths"):
        dataclasses.replace(scenario, q0=(-0.064, 25.0, 0.0))
    with pytest.raises(sc.ParameterError, match="inputs needs an"):
        dataclasses.replace(scenario, inputs=(1.0, 0.0, 0.0))


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_version_1_files_with_pressures_are_read(paper_model, tmp_path, suffix):
    """Files of format version 1 named the actuator's inputs pressures (columns p1 ...)
    and a failure "failed"; they load into inputs and INTEGRATION_FAILED."""
    import json

    actuator = sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    run = sc.simulate(paper_model, [0.064, 0.0, 0.0], np.zeros(3), t_final=0.02,
                      inputs=[2e4, 0.0, 1e4], actuator=actuator)  # fmt: skip
    path = run.save(tmp_path / f"new{suffix}")
    old = tmp_path / f"old{suffix}"
    if suffix == ".csv":
        meta, header, *rows = path.read_text().splitlines()
        fields = json.loads(meta[2:])
        fields.update(version=1, status="failed", n_pressures=fields.pop("n_inputs"))
        header = header.replace("u1,u2,u3", "p1,p2,p3")
        old.write_text("\n".join(["# " + json.dumps(fields), header, *rows]) + "\n")
    else:
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
        fields = json.loads(str(arrays["meta"]))
        fields.update(version=1, status="failed", n_pressures=fields.pop("n_inputs"))
        arrays["meta"] = np.array(json.dumps(fields))
        arrays["pressures"] = arrays.pop("inputs")
        np.savez(old, **arrays)
    loaded = sc.load_trajectory(old)
    np.testing.assert_array_equal(loaded.inputs, run.inputs)
    assert loaded.status is Status.INTEGRATION_FAILED
