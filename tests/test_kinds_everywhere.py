"""The layers above the models on robots of every element kind: inverse statics and input
sweeps driven by tendons, sweeps, loaded trajectories, the words of the messages, and
the static figures' rigid bodies."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.cli import main
from softcurve.figures import plot_backbones, plot_equilibria
from softcurve.simulation.results import TrajectoryFileError

from .test_kinds import gripper, six_strain_segment

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
LINK = dict(mass=0.01, tip_position=[0.0, 0.0, 0.02], inertia=[1e-6, 1e-6, 5e-7], radius=0.01)
"""A rigid link as wide as the soft segments (tendons run past it)."""


def chains() -> dict:
    """Two six-strain segments, and the same with a rigid link between them."""
    soft = six_strain_segment()
    return {
        "six strains": sc.Robot(segments=(soft, soft), gravity=[0.0, 0.0, 0.0]),
        "with a rigid link": sc.Robot(
            segments=(soft, sc.RigidBody(**LINK), soft), gravity=[0.0, 0.0, 0.0]
        ),
    }


# -- 1. inverse statics and input sweeps -----------------------------------------------------
@pytest.mark.parametrize("name", list(chains()))
def test_inverse_statics_and_input_sweep_with_tendons(name):
    """Tendons on six-strain chains: the inputs inverse statics finds put the tip on a
    target that other inputs reach (checked by a forward equilibrium at them); a target
    beyond the body's length is out of reach; an input sweep follows the equilibria."""
    robot = chains()[name]
    actuator = sc.TendonActuator.three_per_segment(distance=0.008, t_max=5.0, elements=robot)
    model = sc.Model(robot, compile=False)
    rest = robot.rest_configuration()
    pulled = np.zeros(actuator.n_inputs)
    pulled[[0, 4]] = 2.0, 1.0  # segment 1 bends one way, segment 2 another: a 3-D tip
    reached = sc.equilibrium(model, rest, actuator=actuator, inputs=pulled)
    assert reached.success, reached.message

    found = sc.inverse_statics(model, actuator, reached.tip_position, starts=2)
    assert found.status is Status.SUCCESS, found.message
    check = sc.equilibrium(model, rest, actuator=actuator, inputs=found.inputs)
    assert check.success, check.message
    tolerance = 1e-6 * robot.rest_length  # inverse_statics' default reach
    assert np.linalg.norm(check.tip_position - reached.tip_position) <= tolerance
    assert np.all((found.inputs >= actuator.lower) & (found.inputs <= actuator.upper))

    beyond = sc.inverse_statics(model, actuator, [0.0, 0.0, 2.0 * robot.rest_length], starts=1)
    assert beyond.status is Status.INFEASIBLE, beyond.message

    path = np.linspace(0.0, 1.0, 4)[:, None] * pulled
    sweep = sc.input_sweep(model, actuator, path)
    assert sweep.status is Status.SUCCESS, sweep.message
    np.testing.assert_allclose(sweep.tip[-1], reached.tip_position, atol=1e-9)
    assert sweep.curvature.shape == (4, robot.n_segments)
    rigid = [i for i, size in enumerate(robot.sizes) if size == 0]
    assert np.all(sweep.curvature[:, rigid] == 0.0)


# -- 2. sweeps -------------------------------------------------------------------------------
@pytest.mark.slow  # compiles its own structures: in the slow study, under the CI budget
def test_sweep_of_a_six_strain_robot_names_its_columns(tmp_path, capsys):
    """``softcurve sweep`` over the twisting gripper's torsion stiffness and initial twist:
    the final state's columns are its strains (before: ``final_l1 final_kx1 ...``, three
    per element, for a robot that has none of them) and the axes are labelled by them."""
    pq = pytest.importorskip("pyarrow.parquet")
    scenario = (EXAMPLES / "twisting_gripper.toml").read_text()
    scenario = scenario[: scenario.index("[simulation]")]
    variables = [
        ("segments[0].torsion_stiffness.k0", 1e-5, 3e-5),
        ("q0[2]", 0.0, 5.0),
    ]
    lines = ["[simulation]", "t_final = 0.05", "[sweep]", 'design = "grid"', "output_dt = 0.01"]
    for name, low, high in variables:
        lines += ["[[sweep.variables]]", f"name = {json.dumps(name)}"]
        lines += [f"low = {low}", f"high = {high}", "points = 2"]
    path = tmp_path / "sweep.toml"
    path.write_text(scenario + "\n".join(lines) + "\n")
    out = tmp_path / "out"
    assert main(["sweep", str(path), "-o", str(out), "--workers", "0"]) == 0
    capsys.readouterr()
    table = pq.read_table(out / "results.parquet")
    strains = [f"{s}1" for s in sc.STRAINS]
    state = [f"final_{c}" for c in strains] + [f"final_{c}_dot" for c in strains]
    names = table.column_names
    assert names[names.index("final_bend_x1") :][: len(state)] == state, names
    assert not any(c.startswith("final_l") for c in names), names
    twist = np.array(table.column("final_twist1"))
    assert table.num_rows == 4 and np.all(np.isfinite(twist))
    assert set(table.column("status").to_pylist()) == {"success"}

    from softcurve.scenarios.sweep_config import load_sweep
    from softcurve.scenarios.sweep_variables import variable_label

    swept = load_sweep(path).scenario
    assert variable_label(swept, "q0[2]") == "initial twist, segment 0 [1/m]"
    assert variable_label(swept, "q0[5]") == "initial stretch, segment 0 [-]"
    assert variable_label(swept, "qd0[3]") == "initial rate of shear_x, segment 0 [1/s]"


@pytest.mark.parametrize(
    "low, high, refused",
    [(-5.0, 5.0, None), (0.0, 1.2, r"q0\[5\] = 0 is outside the model's domain .*0 < stretch")],
)
def test_sweeps_check_initial_strains_by_their_domain(low, high, refused):
    """A swept initial strain is checked against its own domain: a bend may be negative
    (before: ``q0[0]`` was "a length" whatever the element), a stretch must be > 0."""
    from softcurve.scenarios.config import ConfigError
    from softcurve.scenarios.sweep_config import sweep_from_dict
    from softcurve.scenarios.tables import read_toml

    data, _ = read_toml(EXAMPLES / "twisting_gripper.toml")
    name = "q0[0]" if refused is None else "q0[5]"
    variable = {"name": name, "low": low, "high": high, "points": 2}
    data["sweep"] = {"design": "grid", "variables": [variable]}
    if refused is None:
        assert sweep_from_dict(data, "bend.toml").variables[0].name == "q0[0]"
    else:
        with pytest.raises(ConfigError, match=refused):
            sweep_from_dict(data, "stretch.toml")


# -- 3. loaded trajectories ------------------------------------------------------------------
@pytest.fixture(scope="module")
def mixed_run():
    robot = chains()["with a rigid link"]
    model = sc.Model(robot, compile=False)
    return sc.simulate(model, robot.rest_configuration(), np.zeros(robot.n), t_final=0.02)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_a_loaded_trajectory_names_its_coordinates(mixed_run, suffix, tmp_path):
    """A six-strain run saved and loaded: the trajectory has the coordinates' names and
    units of its file, and its states figure has the same panels as the run's (before: the
    loaded one fell back to ``l, kx, ky`` panels of four "segments")."""
    assert mixed_run.success, mixed_run.message
    names = tuple(f"{s}{i}" for i in (1, 3) for s in sc.STRAINS)  # element 2 is rigid
    assert mixed_run.coordinate_names == names
    loaded = sc.load_trajectory(mixed_run.save(tmp_path / f"run{suffix}"))
    assert loaded.model is None and loaded.coordinate_names == names
    assert loaded.coordinate_units == tuple(mixed_run.model.robot.coordinate_units())
    run_axes, loaded_axes = mixed_run.plot().axes, loaded.plot().axes
    labels = [ax.get_ylabel() for ax in loaded_axes]
    assert labels == [ax.get_ylabel() for ax in run_axes]
    assert labels == ["bend_x [1/m]", "bend_y [1/m]", "twist [1/m]", "shear_x [-]",
                      "shear_y [-]", "stretch [-]"]  # fmt: skip
    for ours, theirs in zip(loaded_axes, run_axes, strict=True):
        assert [ln.get_label() for ln in ours.lines] == ["segment 1", "segment 3"]
        for a, b in zip(ours.lines, theirs.lines, strict=True):
            np.testing.assert_array_equal(a.get_ydata(), b.get_ydata())


def test_constant_curvature_files_and_files_without_units(tmp_path):
    """A file that names no coordinates is constant curvature's (``l1 kx1 ky1``); one
    that names them without their units is refused, naming the field."""
    paper = sc.Model(sc.presets.ifac2020(), compile=False)
    run = sc.simulate(paper, paper.robot.rest_configuration(), np.zeros(3), t_final=0.01)
    path = run.save(tmp_path / "paper.csv")
    loaded = sc.load_trajectory(path)
    assert loaded.coordinate_names == ("l1", "kx1", "ky1")
    assert loaded.coordinate_units == ("m", "1/m", "1/m")
    first, rest = path.read_text().split("\n", 1)
    meta = json.loads(first[2:])
    del meta["coordinates"], meta["units"]
    (tmp_path / "old.csv").write_text("# " + json.dumps(meta) + "\n" + rest)
    old = sc.load_trajectory(tmp_path / "old.csv")
    assert old.coordinate_names == ("l1", "kx1", "ky1")
    assert [ax.get_ylabel() for ax in old.plot().axes][0] == "length l [m]"
    meta = json.loads(first[2:])
    del meta["units"]
    (tmp_path / "bad.csv").write_text("# " + json.dumps(meta) + "\n" + rest)
    with pytest.raises(TrajectoryFileError, match="the metadata's units must be 3 texts"):
        sc.load_trajectory(tmp_path / "bad.csv")


# -- 4. words --------------------------------------------------------------------------------
def test_messages_count_elements_where_the_chain_has_other_kinds(tmp_path, capsys):
    """Constant-curvature robots keep their segments; other chains count elements
    (before: "the model of 3 segments" for two segments and a rigid body)."""
    assert sc.presets.ifac2020().with_segments(2).counted() == "2 segments"
    assert sc.presets.ifac2020().counted() == "1 segment"
    assert chains()["with a rigid link"].counted() == "3 elements"
    assert chains()["six strains"].element_word == "element"
    scenario = EXAMPLES / "twisting_gripper.toml"
    assert main(["simulate", str(scenario), "-o", str(tmp_path / "run")]) == 0
    assert f"softcurve simulate: {scenario}, 2 element(s), " in capsys.readouterr().out


# -- 5. figures ------------------------------------------------------------------------------
def test_static_figures_draw_rigid_bodies_as_bars(mixed_run):
    """The equilibria and backbones figures draw each rigid body as a dark grey bar and
    the soft elements' line broken there (before: one line through them)."""
    robot = sc.Robot(segments=(*chains()["with a rigid link"].segments, gripper()))
    model = sc.Model(robot, compile=False)
    table = sc.equilibria(model, starts=1, seed=0, gravity=[9.81, 0.0, 0.0])
    assert table.status is Status.SUCCESS, table.message
    (ax,) = plot_equilibria(table).axes
    assert len(ax.patches) == 2 * len(table.equilibria)  # the link and the gripper
    grey = [p for p in ax.patches if p.get_facecolor()[:3] == pytest.approx((0.35,) * 3)]
    assert len(grey) == len(ax.patches) and ax.patches[0].get_label() == "rigid body"
    (line,) = ax.lines
    assert np.isnan(line.get_xdata()).sum() == 2  # broken at the link and the gripper

    figure = plot_backbones(mixed_run, [0.0, 0.02])
    side, top = figure.axes
    assert len(side.patches) == len(top.patches) == 2  # one link, two times
    backbone = side.lines[0]
    assert np.isnan(backbone.get_xdata()).sum() == 1
    tip = mixed_run.tip[0] * 1e3
    assert side.lines[1].get_xdata()[0] == pytest.approx(tip[0])
