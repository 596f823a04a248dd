"""``softcurve simulate`` end to end: files, data, exit codes and error messages."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import tomllib

import softcurve as sc
from softcurve.cli import main
from softcurve.scenarios.config import scenario_from_dict

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture(autouse=True)
def _compiled_once(paper_model):
    """Every run here uses the paper's structure, compiled once by the session fixture."""


def test_default_run_writes_data_figures_and_summary(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["simulate", "-o", str(out), "--t-final", "1.0", "--no-progress", "--npz"])
    assert code == 0
    printed = capsys.readouterr().out
    for word in (
        "built-in paper case",
        "status      success",
        "final q",
        "energy",
        "cvodes-adams",
        "real time",
    ):
        assert word in printed, word
    assert sorted(p.name for p in out.iterdir()) == [
        "states.png",
        "tip.png",
        "trajectory.csv",
        "trajectory.npz",
    ]
    for figure in ("states.png", "tip.png"):
        assert (out / figure).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    trajectory = sc.load_trajectory(out / "trajectory.csv")
    assert trajectory.t.size == 1001 and trajectory.t[-1] == 1.0
    np.testing.assert_array_equal(trajectory.q[0], [0.064, 25.0, 0.0])
    np.testing.assert_array_equal(trajectory.qd[0], [0.0, 0.0, 1500.0])
    assert np.all(np.isfinite(trajectory.x)) and abs(trajectory.q[-1, 1]) < 0.1  # decayed
    assert np.all(np.abs(np.linalg.norm(trajectory.tip, axis=1) - 0.064) < 0.01)


def test_config_file_with_animation(tmp_path, capsys):
    out = tmp_path / "hanging"
    code = main(
        [
            "simulate",
            str(EXAMPLES / "hanging.toml"),
            "-o",
            str(out),
            "--t-final",
            "0.2",
            "--animate",
            "--fps",
            "10",
            "--quiet",
        ]
    )
    assert code == 0 and capsys.readouterr().out == ""
    assert (out / "animation.gif").read_bytes()[:6] == b"GIF89a"
    trajectory = sc.load_trajectory(out / "trajectory.csv")
    assert trajectory.tip[-1, 2] > 0.0 and trajectory.q[0, 1] == 15.5  # hangs along +z


def test_solver_failure_exits_1_and_keeps_the_partial_trajectory(tmp_path, capsys):
    out = tmp_path / "failed"
    code = main(
        [
            "simulate",
            "-o",
            str(out),
            "--t-final",
            "0.5",
            "--max-steps",
            "3",
            "--no-figures",
            "--no-progress",
        ]
    )
    assert code == 1
    error = capsys.readouterr().err
    assert "integration failed" in error and "What to try" in error
    partial = sc.load_trajectory(out / "trajectory.csv")
    assert partial.status == "integration_failed" and 0 < partial.t.size < 501


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("[robot]\npreset = 'ifac2020'\nfoo = 1\n", "robot.foo: unknown key"),
        (
            "[robot]\npreset = 'ifac2020'\n[simulation]\nrtol = 'tight'\n",
            "simulation.rtol: must be a finite number",
        ),
        (
            "[robot]\npreset = 'ifac2020'\n[simulation]\nq0 = [0.064, 25.0]\n",
            "simulation.q0: must have 3 entries",
        ),
    ],
)
def test_bad_configuration_exits_2_with_file_and_key(tmp_path, capsys, text, expected):
    config = tmp_path / "bad.toml"
    config.write_text(text)
    code = main(["simulate", str(config), "-o", str(tmp_path / "out")])
    assert code == 2
    error = capsys.readouterr().err
    assert f"{config}: {expected}" in error and "Traceback" not in error
    assert not (tmp_path / "out").exists()  # nothing written


def test_bad_options_exit_2(tmp_path, capsys):
    assert main(["simulate", "-o", str(tmp_path), "--dt", "-1"]) == 2
    assert "dt" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "missing.toml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["simulate", "--method", "euler"])
    assert exit_info.value.code == 2


def test_subprocess_entry_point(tmp_path):
    """The installed ``softcurve`` script (or the same entry point through Python)."""
    env = {**os.environ, "MPLBACKEND": "Agg"}
    script = shutil.which("softcurve")
    launcher = (
        [script]
        if script
        else [sys.executable, "-c", "import sys; from softcurve.cli import main; sys.exit(main())"]
    )
    command = [*launcher, "simulate", "-o", str(tmp_path), "--t-final", "0.1", "--no-figures", "-q"]
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "" and (tmp_path / "trajectory.csv").exists()
    helped = subprocess.run(
        [*launcher, "simulate", "--help"], capture_output=True, text=True, env=env, timeout=60
    )
    assert helped.returncode == 0 and "--output" in helped.stdout
    bad = subprocess.run(
        [*launcher, "simulate", "--rtol", "2"],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
        cwd=tmp_path,
    )
    assert bad.returncode == 2 and "rtol" in bad.stderr and "Traceback" not in bad.stderr


def test_a_rerun_names_the_files_it_replaced_and_those_it_left(tmp_path, capsys):
    """A second run into the same folder says which files of the first it replaced and
    which it left (written by the first only: they do not belong to this run)."""
    out = tmp_path / "out"
    short = ["simulate", "-o", str(out), "--t-final", "0.1", "--no-progress"]
    assert main([*short, "--npz"]) == 0
    assert "replaced" not in capsys.readouterr().out  # a new folder: nothing replaced
    assert main(short) == 0
    printed = capsys.readouterr().out.splitlines()
    assert "  replaced    trajectory.csv, states.png, tip.png of an earlier run" in printed
    assert "  left        trajectory.npz of an earlier run (not written now)" in printed


def test_a_six_strain_robot_with_a_gripper_runs_from_its_file(tmp_path, capsys):
    """examples/twisting_gripper.toml: a constant-strain segment with all six strains
    and a rigid gripper on a moved, turned base, simulated end to end."""
    from tests.test_kinds import six_strain_gripper_robot

    scenario = sc.load_config(EXAMPLES / "twisting_gripper.toml")
    robot = scenario.robot
    assert robot.structure() == six_strain_gripper_robot().structure()
    np.testing.assert_array_equal(robot.base_position, [0.0, 0.0, 0.2])
    segment, gripper = robot.segments
    assert segment.strains == sc.STRAINS and gripper.mass == 0.02
    # from its material and section: E I, G J with G = E / 3, E A, rho A L0
    r, e = 0.01, 1e6
    assert segment.bending_stiffness.k0 == pytest.approx(e * np.pi * r**4 / 4, rel=1e-12)
    assert segment.torsion_stiffness.k0 == pytest.approx(e / 3 * np.pi * r**4 / 2, rel=1e-12)
    assert segment.stretch_stiffness.k0 == pytest.approx(e * np.pi * r**2, rel=1e-12)
    assert segment.mass == pytest.approx(1070.0 * np.pi * r**2 * 0.1, rel=1e-12)
    np.testing.assert_array_equal(gripper.inertia[0], [3e-6, 2e-7, 0.0])
    out = tmp_path / "out"
    code = main(["simulate", str(EXAMPLES / "twisting_gripper.toml"), "-o", str(out),
                 "--no-progress"])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    run = sc.load_trajectory(out / "trajectory.csv")
    assert run.q.shape == (301, 6) and run.status == "success"
    twist = run.q[:, sc.STRAINS.index("twist")]
    assert np.abs(twist).max() > 1e-2  # the gripper's weight off the axis twists it
    model = sc.Model(robot, compile=False)
    np.testing.assert_allclose(run.tip[-1], model.pose(run.q[-1], 1.0).position, atol=1e-9)


STRAIN_SEGMENT = """
[robot]
base_position = [0.0, 0.0, 0.1]
[[robot.segments]]
kind = "constant_strain"
rest_length = 0.1
mass = 0.03
radius = 0.01
strains = STRAINS
bending_stiffness = { law = "linear", k0 = 8e-3 }
LAWS
"""


@pytest.mark.parametrize(
    ("strains", "laws", "expected"),
    [
        ('["bend_x", "twirl"]', "", "robot.segments[0].strains: unknown strain 'twirl'"),
        ('["bend_x", "twist"]', "", "robot.segments[0].torsion_stiffness: is required"),
        (
            '["bend_x"]',
            'shear_stiffness = { law = "linear", k0 = 90.0 }',
            "robot.segments[0].shear_stiffness: the segment chooses none of shear_x, shear_y",
        ),
        ('"bend_x"', "", "robot.segments[0].strains: must be a non-empty array of strings"),
        (
            '["bend_x"]\ndamping = [1.0, 2.0]',
            "",
            "robot.segments[0]: damping must have shape (1, 1), got (2,)",
        ),
    ],
)
def test_a_bad_strain_segment_exits_2_naming_its_field(tmp_path, capsys, strains, laws, expected):
    config = tmp_path / "bad.toml"
    config.write_text(STRAIN_SEGMENT.replace("STRAINS", strains).replace("LAWS", laws))
    assert main(["simulate", str(config), "-o", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert f"{config}: {expected}" in error, error
    assert error.count("\n") == 1 and "Traceback" not in error
    assert not (tmp_path / "out").exists()


def test_a_strain_segment_of_laws_or_of_a_material_and_a_section():
    laws = STRAIN_SEGMENT.replace("STRAINS", '["bend_x", "twist"]').replace(
        "LAWS", 'torsion_stiffness = { law = "tanh", a1 = 5e-3, a2 = 2e-3, a3 = 4.0 }'
    )
    segment = scenario_from_dict(tomllib.loads(laws)).robot.segments[0]
    assert segment.strains == ("bend_x", "twist") and segment.mass == 0.03
    assert segment.bending_stiffness.k0 == 8e-3 and segment.torsion_stiffness.a3 == 4.0
    tube = """
    [robot]
    [[robot.segments]]
    kind = "constant_strain"
    rest_length = 0.05
    strains = ["bend_x", "bend_y", "twist"]
    material = { youngs_modulus = 2e6, density = 1100.0, shear_modulus = 7e5 }
    section = { outer_radius = 0.02, inner_radius = 0.01 }
    """
    segment = scenario_from_dict(tomllib.loads(textwrap.dedent(tube))).robot.segments[0]
    second = np.pi * (0.02**4 - 0.01**4) / 4
    assert segment.bending_stiffness.k0 == pytest.approx(2e6 * second, rel=1e-12)
    assert segment.torsion_stiffness.k0 == pytest.approx(7e5 * 2 * second, rel=1e-12)
    assert segment.radius == 0.02 and segment.shear_stiffness is None


@pytest.mark.parametrize(
    ("element", "expected"),
    [
        ("section = { radius = 0.01 }", "robot.segments[0].material: is required"),
        (
            "material = { youngs_modulus = 1e6, density = 1070.0 }\nsection = { radius = 0.01 }",
            "robot.segments[0].material: a Material needs shear_modulus [Pa] or poisson_ratio",
        ),
        (
            "material = { youngs_modulus = 1e6, density = 1e3, poisson_ratio = 0.5 }\n"
            "section = { radius = 0.01 }\nmass = 0.03",
            "robot.segments[0].mass: comes from material and section",
        ),
        (
            "material = { youngs_modulus = 1e6, density = 1e3, poisson_ratio = 0.7 }\n"
            "section = { radius = 0.01 }",
            "robot.segments[0].material: ",
        ),
    ],
)
def test_a_bad_material_or_section_exits_2_naming_its_field(tmp_path, capsys, element, expected):
    config = tmp_path / "bad.toml"
    config.write_text(
        '[robot]\n[[robot.segments]]\nkind = "constant_strain"\nrest_length = 0.1\n'
        + element
        + "\n"
    )
    assert main(["simulate", str(config), "-o", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert f"{config}: {expected}" in error, error
    assert error.count("\n") == 1


@pytest.mark.parametrize(
    ("element", "expected"),
    [
        ('kind = "hinge"', "robot.segments[0].kind: must be one of"),
        ('kind = "rigid_body"\nmass = 0.02', "robot.segments[0].tip_position: is required"),
        (
            'kind = "rigid_body"\nmass = 0.02\ntip_position = [0, 0, 0.03]\ninertia = [1, 2]',
            "robot.segments[0].inertia: must be 3 numbers",
        ),
        (
            'kind = "rigid_body"\nmass = -1.0\ntip_position = [0, 0, 0.03]',
            "robot.segments[0]: mass must be >= 0",
        ),
    ],
)
def test_a_bad_rigid_body_exits_2_naming_its_field(tmp_path, capsys, element, expected):
    config = tmp_path / "bad.toml"
    config.write_text(f"[robot]\n[[robot.segments]]\n{element}\n")
    assert main(["simulate", str(config), "-o", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert f"{config}: {expected}" in error, error
    assert error.count("\n") == 1
