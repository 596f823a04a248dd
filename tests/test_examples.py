"""Every example runs in every mode, at a small size, in a process of its own, as a user
runs it: a renamed function fails here, not in a user's hands.

The runs on the measurements (``../shared/data`` relative to the repository, or
``$SOFTCURVE_DATA``) skip with a message without them. Those of validate_joint.py take
minutes even at their smallest (each of its dozens of fits builds its sensitivity
equations): they are marked ``slow`` (``python -m pytest -m slow tests/test_examples.py``);
by default every name the examples read from a module is checked to exist (a rename's
leftover, found without running), and tests/test_validation_goals.py runs a fit of it.
So is tendon_reach.py's plan (half a minute's compile and 12 s of solve), whose planner is
checked on the paper's robot by tests/test_planning.py.
The runs of ``train_reach.py`` skip without Stable-Baselines3 (``pip install ".[rl]"``
and PyTorch).
"""

from __future__ import annotations

import ast
import dataclasses
import importlib.util
import os
import subprocess
import sys
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


@dataclasses.dataclass(frozen=True)
class Run:
    """One run of an example: ``python examples/<script> <args>``, ``{out}`` in the
    arguments standing for a fresh folder."""

    script: str
    args: tuple[str, ...]
    modes: frozenset[str] = frozenset()
    """The choices of the script's options (``choices=``) this run goes through."""
    writes: tuple[str, ...] = ()
    """Files the run writes into ``{out}``."""
    needs: str | None = None
    """``"data"`` (the measurements) or a module that must be importable."""
    slow: bool = False
    """Whether the run takes minutes even at its smallest (marked ``slow``)."""

    @property
    def id(self) -> str:
        return " ".join([self.script, *(a for a in self.args if "{out}" not in a)])


RUNS = (
    Run(
        "contact_finger.py",
        ("all", "--quick", "--output", "{out}"),
        frozenset({"finger", "cylinder", "floor", "all"}),  # "all" runs the three
        ("finger_force.png", "cylinder.png", "floor_force.png", "floor_tip.png"),
    ),
    Run("flick.py", ("--quick", "--output", "{out}"), writes=("flick.png", "flick.html")),
    Run("inverse_statics.py", ("--output", "{out}/statics.png"), writes=("statics.png",)),
    Run(
        "paper_reproduction.py",
        ("--figures", "{out}"),
        writes=("paper-states-first-second.png",),
    ),
    Run(
        "tendon_tracking.py",
        ("--output", "{out}", "--t-final", "0.6"),
        writes=("tendon_tracking_tensions.png", "tendon_tracking_shapes.png"),
    ),
    Run(
        "predictive_circle.py",
        ("--quick", "--output", "{out}"),
        writes=("predictive_circle.png", "predictive_circle.html"),
    ),
    # its first plan compiles a two-segment robot's second derivatives (about half a
    # minute in an empty cache) and solves in 12 s; a plan in the virtual machine takes more
    Run(
        "tendon_reach.py",
        ("--output", "{out}"),
        writes=("tendon_reach.png", "tendon_reach.html"),
        slow=True,
    ),
    Run("tip_circle.py", ("--output", "{out}/tip.png", "--t-final", "1.1"), writes=("tip.png",)),
    *(
        Run(
            "train_reach.py",
            ("--algo", algo, "--steps", "512", "--envs", "2", "--output", "{out}"),
            frozenset({algo}),
            ("policy.zip", "learning_curve.csv", "learning_curve.png", "rollout.png"),
            needs="stable_baselines3",
        )
        for algo in ("ppo", "sac")
    ),
    Run(
        "validate_caasenbrood2021.py",
        ("--smoke", "--figures", "{out}"),
        writes=("validation_oscillation.png", "validation_openloop.png", "validation_static.png"),
        needs="data",
    ),
    Run(
        "validate_joint.py",
        ("--smoke", "--figure", "{out}/swings.png"),
        frozenset({"oscillation", "openloop", "creep"}),  # without --only: these three
        ("swings.png",),
        needs="data",
        slow=True,
    ),
    Run(
        "validate_joint.py",
        ("--smoke", "--only", "rate"),
        frozenset({"rate"}),
        needs="data",
        slow=True,
    ),
)
"""The runs: together, every example in every mode."""


def choices(script: Path) -> set[str]:
    """The choices of every option of ``script`` (its ``add_argument(..., choices=...)``
    calls, read from the source)."""
    found = set()
    for node in ast.walk(ast.parse(script.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument":
            for keyword in node.keywords:
                if keyword.arg == "choices":
                    found |= set(ast.literal_eval(keyword.value))
    return found


def uncovered(runs, scripts) -> list[str]:
    """The examples of ``scripts`` (paths) without a run, and the modes no run goes
    through."""
    problems = []
    for script in scripts:
        mine = [run for run in runs if run.script == script.name]
        if not mine:
            problems.append(f"{script.name}: no run")
            continue
        missing = choices(script) - set().union(*(run.modes for run in mine))
        problems += [f"{script.name}: no run of {mode!r}" for mode in sorted(missing)]
    return problems


SCRIPTS = sorted(p for p in EXAMPLES.glob("*.py") if not p.name.startswith("_"))


def test_every_example_has_a_run_of_every_mode():
    assert uncovered(RUNS, SCRIPTS) == []
    assert {run.script for run in RUNS} == {p.name for p in SCRIPTS}
    # the check fails where it should: a mode left out, an example left out
    without_rate = [r for r in RUNS if not (r.script == "validate_joint.py" and "rate" in r.modes)]
    assert uncovered(without_rate, SCRIPTS) == ["validate_joint.py: no run of 'rate'"]
    without_finger = [r for r in RUNS if r.script != "contact_finger.py"]
    assert uncovered(without_finger, SCRIPTS) == ["contact_finger.py: no run"]


def _load(script: Path):
    """``script`` imported as a module (its ``main`` not run), its folder on the path as
    when it runs (an example may import another's robot)."""
    spec = importlib.util.spec_from_file_location(f"example_{script.stem}", script)
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(script.parent))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(script.parent))
    return module


def missing_names(namespace: dict, source: str) -> list[str]:
    """The dotted names ``module.name`` in ``source`` whose module (a module in
    ``namespace``, as the script's imports bind them) has no such name: what a rename
    leaves behind in a caller, found without running it."""
    missing = set()
    for node in ast.walk(ast.parse(source)):
        chain = []
        while isinstance(node, ast.Attribute):
            chain.insert(0, node.attr)
            node = node.value
        if not (chain and isinstance(node, ast.Name)):
            continue
        owner = namespace.get(node.id)
        for depth, name in enumerate(chain):
            if not isinstance(owner, types.ModuleType):
                break
            if not hasattr(owner, name):
                missing.add(".".join([node.id, *chain[: depth + 1]]))
                break
            owner = getattr(owner, name)
    return sorted(missing)


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_the_names_an_example_reads_from_modules_exist(script):
    """Every ``module.name`` an example reads exists, in every branch, run or not (before,
    ``vc.curvatures`` of validate_joint.py's open loop was gone)."""
    assert missing_names(vars(_load(script)), script.read_text(encoding="utf-8")) == []


def test_a_name_a_rename_left_behind_is_found():
    joint = vars(_load(EXAMPLES / "validate_joint.py"))
    old = "output = vc.curvatures(offsets=vc.OFFSETS)\nq = sc.presets.gone()\n"
    assert missing_names(joint, old) == ["sc.presets.gone", "vc.curvatures"]


def _data_directory():
    """The measurements, where validate_caasenbrood2021.py finds them (None: absent)."""
    return _load(EXAMPLES / "validate_caasenbrood2021.py").data_directory()


@pytest.mark.parametrize(
    "run",
    [
        pytest.param(
            run,
            id=run.id,
            marks=[
                *([pytest.mark.data] if run.needs == "data" else []),
                *([pytest.mark.slow] if run.slow else []),
            ],
        )
        for run in RUNS
    ],
)
def test_the_example_runs(run, tmp_path):
    if run.needs == "data" and _data_directory() is None:
        pytest.skip(
            "real data absent: put caasenbrood2021 under ../shared/data (relative to the "
            "repository) or set SOFTCURVE_DATA"
        )
    if run.needs not in (None, "data") and importlib.util.find_spec(run.needs) is None:
        pytest.skip(f"{run.script} needs {run.needs}: pip install '.[rl]' (and PyTorch)")
    out = tmp_path / "out"
    out.mkdir()
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / run.script), *(a.format(out=out) for a in run.args)],
        capture_output=True,
        text=True,
        cwd=tmp_path,  # what a run writes by default lands here, not in the repository
        env={**os.environ, "MPLBACKEND": "Agg"},
        timeout=1800,  # a hung run fails; a loaded machine takes minutes for the data runs
        check=False,
    )
    assert done.returncode == 0, f"{run.id}:\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    assert [name for name in run.writes if not (out / name).is_file()] == []
