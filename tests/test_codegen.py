"""Standalone C export: the generated code agrees with the Python model; the CLI commands."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from softcurve import ParameterError, PneumaticActuator
from softcurve.cli import main
from softcurve.compiled._export import build_and_run_test, export_c

from .conftest import assert_close

COMPILER = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")


def parse(output: str) -> dict[str, np.ndarray]:
    values: dict[str, list[float]] = {}
    for line in output.splitlines():
        parts = line.split()
        if len(parts) == 3:
            values.setdefault(parts[0], []).append(float(parts[2]))
    return {name: np.array(v) for name, v in values.items()}


@pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc, gcc or clang) found")
@pytest.mark.parametrize("embed", [True, False])
def test_generated_c_agrees_with_the_model(paper_model, tmp_path, embed):
    act = PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    exported = export_c(paper_model, tmp_path, actuator=act, prefix="robot", embed_parameters=embed)
    assert exported.success and exported.header.read_text().count("robot_forward_dynamics") >= 1
    output = build_and_run_test(exported, optimization="-O0")  # fast to compile
    assert output.strip().endswith("OK")
    c = parse(output)
    s = exported.sample_inputs
    drop_p = (lambda args: args) if embed else (lambda args: args[:-1])
    expected = {
        "forward_dynamics": paper_model.forward_dynamics(*drop_p(s["forward_dynamics"])),
        "inverse_dynamics": paper_model.inverse_dynamics(*drop_p(s["inverse_dynamics"])),
        "potential_force": paper_model.potential_force(*drop_p(s["potential_force"])),
        "input_matrix": act.input_matrix(*drop_p(s["input_matrix"])).ravel(order="F"),
    }
    for name, value in expected.items():
        value = np.array(value)
        assert_close(c[name], value, rtol=1e-12, scale=np.abs(value).max(), what=name)


def test_export_rejects_bad_prefix(paper_model, tmp_path):
    with pytest.raises(ParameterError, match="prefix must be a C identifier"):
        export_c(paper_model, tmp_path, prefix="my-robot")


def test_cli_codegen_writes_the_files(tmp_path, capsys):
    assert main(["codegen", "--output", str(tmp_path), "--prefix", "arm"]) == 0
    assert {p.name for p in tmp_path.iterdir()} >= {"arm.c", "arm.h", "test_arm.c"}
    assert "arm_input_matrix" in capsys.readouterr().out


@pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc, gcc or clang) found")
@pytest.mark.parametrize("output", [None, "out/c"], ids=["default", "relative"])
def test_cli_codegen_check_with_a_relative_output(tmp_path, monkeypatch, capsys, output):
    """A relative -o (the default softcurve_c too) is resolved once: the test program is
    built and run in it, not at the path doubled (issue 11, case 1)."""
    monkeypatch.chdir(tmp_path)
    argv = ["codegen", "--check", "--no-actuator"] + ([] if output is None else ["-o", output])
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "test program: OK" in captured.out and "No such file" not in captured.err
    folder = tmp_path / (output or "softcurve_c")
    assert {p.name for p in folder.iterdir()} >= {
        "softcurve_model.c",
        "softcurve_model.h",
        "test_softcurve_model.c",
        "test_softcurve_model",
    }
    assert str(folder) in captured.out  # the paths printed are the resolved ones


@pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc, gcc or clang) found")
@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash to paste the line into")
def test_cli_codegen_hint_quotes_the_folder(tmp_path, monkeypatch, capsys):
    """The printed ``cd <folder> && cc ...``, pasted into bash, builds the test program
    in a folder named like a command substitution and runs nothing (before: the line
    ran ``touch pwned``)."""
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "$(touch pwned)"
    assert main(["codegen", "--no-actuator", "-o", str(folder)]) == 0
    (line,) = [x for x in capsys.readouterr().out.splitlines() if "build the test: " in x]
    pasted = tmp_path / "pasted"
    pasted.mkdir()
    command = line.split("build the test: ", 1)[1]
    done = subprocess.run(["bash", "-c", command], cwd=pasted, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert not list(tmp_path.rglob("pwned")), "the folder's name ran as a command"
    assert (folder / "test_softcurve_model").is_file()


@pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc, gcc or clang) found")
def test_the_c_of_a_six_strain_robot_with_a_gripper_agrees_with_the_model(tmp_path):
    """All six strains and a rigid gripper: the exported C, compiled, gives the model's
    forward and inverse dynamics and potential forces at a state with every strain
    away from rest."""
    import softcurve as sc

    from .test_kinds import six_strain_gripper_robot

    model = sc.Model(six_strain_gripper_robot())
    exported = export_c(model, tmp_path, prefix="gripper")
    assert exported.success, exported.message
    output = build_and_run_test(exported, optimization="-O0")
    assert output.strip().endswith("OK")
    c = parse(output)
    s = exported.sample_inputs
    q = s["forward_dynamics"][0]
    assert q.shape == (6,) and np.all(q != model.robot.rest_configuration())
    for name in ("forward_dynamics", "inverse_dynamics", "potential_force"):
        value = np.array(getattr(model, name)(*s[name]))
        assert_close(c[name], value, rtol=1e-12, scale=np.abs(value).max(), what=name)
