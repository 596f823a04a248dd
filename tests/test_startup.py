"""Ctrl-C at the edges of a command: while Python imports softcurve and the command, and
just after a sweep has written its table. Each is one line on stderr and exit code 130,
never a traceback.

A real SIGINT is sent at a chosen point: a finder on ``sys.meta_path`` sends it to its
own process when a given module is first imported, so that the interrupt lands inside
that import, as a Ctrl-C in the first second of a command does.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from tests.conftest import sigint_default
from tests.test_faults import SWEEP_TOML

INTERRUPT_AT = """\
import os, signal, sys

class InterruptAt:
    \"\"\"Sends SIGINT to this process when {target!r} is first imported.\"\"\"

    def find_spec(self, name, path=None, target=None):
        if name == {target!r}:
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, InterruptAt())
sys.argv = ["softcurve", *{argv!r}]
"""

PYTHON_M = "import runpy\nrunpy.run_module('softcurve', run_name='__main__', alter_sys=True)\n"
"""``python -m softcurve``: imports the facade, then runs ``softcurve/__main__.py``."""

ENTRY = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())["project"][
    "scripts"
]["softcurve"]
"""``module:function`` that the ``softcurve`` console script calls."""

SCRIPT = "from {} import {} as main\nsys.exit(main())\n".format(*ENTRY.split(":"))
"""What the ``softcurve`` console script runs (pip writes it from ``ENTRY``)."""

STARTING = "softcurve: interrupted before starting: nothing was done"


def _interrupted(entry: str, target: str, argv: list[str]) -> subprocess.CompletedProcess:
    code = INTERRUPT_AT.format(target=target, argv=[str(a) for a in argv]) + entry
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
        preexec_fn=sigint_default,
    )  # fmt: skip


def _one_line_130(done: subprocess.CompletedProcess) -> str:
    assert done.returncode == 128 + signal.SIGINT, (done.returncode, done.stderr)
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    return lines[0]


@pytest.mark.parametrize(
    ("entry", "target"),
    [
        (PYTHON_M, "softcurve.cli"),  # the command line's face
        (PYTHON_M, "argparse"),  # what the face imports
        (PYTHON_M, "numpy"),  # the commands' modules
        (SCRIPT, "softcurve.cli"),
        (SCRIPT, "argparse"),
        (SCRIPT, "numpy"),
        (SCRIPT, "softcurve.cli.simulate"),
    ],
    ids=[
        "m-cli",
        "m-argparse",
        "m-numpy",
        "script-cli",
        "script-argparse",
        "script-numpy",
        "script-command",
    ],
)
def test_ctrl_c_while_softcurve_imports_is_one_line_and_130(entry, target, tmp_path):
    done = _interrupted(entry, target, ["simulate", "-o", tmp_path / "out", "--no-figures"])
    assert _one_line_130(done) == STARTING
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("target", ["casadi", "softcurve.simulation"])
def test_ctrl_c_while_the_command_imports_the_library_is_one_line_and_130(target, tmp_path):
    """The library is imported by the command as it runs: its own interrupt line."""
    out = tmp_path / "out"
    done = _interrupted(SCRIPT, target, ["simulate", "-o", out, "--no-figures"])
    assert _one_line_130(done).startswith("softcurve simulate: interrupted: ")


def test_ctrl_c_right_after_start_is_no_traceback(tmp_path):
    """A real Ctrl-C at once: Python may not have installed its handler yet (then the
    signal ends the process, which a shell reports as 130) or it is in the imports."""
    process = subprocess.Popen(
        [sys.executable, "-m", "softcurve", "simulate", "-o", tmp_path, "--no-figures"],
        preexec_fn=sigint_default,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=600)
    assert process.returncode in (128 + signal.SIGINT, -signal.SIGINT), err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err


SWEEP_THEN_LOOK = """\
import json, multiprocessing, sys, threading

from softcurve.cli import main

if __name__ == "__main__":
    code = main(sys.argv[1:])
    waited = [t.name for t in threading.enumerate()
              if not t.daemon and t is not threading.main_thread()]
    children = [p.pid for p in multiprocessing.active_children()]
    print(json.dumps({"code": code, "waited": waited, "children": children}))
"""


def test_a_sweep_leaves_nothing_for_the_interpreters_exit_to_wait_for(paper_model, tmp_path):
    """The worker pool is closed inside the command, where a Ctrl-C is one line; a pool
    left to the interpreter's exit was joined there, and a Ctrl-C then was a threading
    traceback and exit code 0."""
    pytest.importorskip("pyarrow")
    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=0.05, points=2))
    script = tmp_path / "look.py"
    script.write_text(SWEEP_THEN_LOOK)
    argv = ["sweep", config, "-o", tmp_path / "out", "--workers", "2", "--no-progress", "-q"]
    done = subprocess.run(
        [sys.executable, script, *map(str, argv)], capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout.splitlines()[-1])
    assert seen == {"code": 0, "waited": [], "children": []}


def test_ctrl_c_just_after_a_sweep_wrote_its_table_is_no_traceback(paper_model, tmp_path):
    """A real Ctrl-C once the summary is printed: the command is done or ending."""
    pytest.importorskip("pyarrow")
    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=0.05, points=2))
    argv = ["sweep", config, "-o", tmp_path / "out", "--workers", "2", "--no-progress"]
    process = subprocess.Popen(
        [sys.executable, "-m", "softcurve", *map(str, argv)],
        preexec_fn=sigint_default,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    printed = b""
    while b"wrote" not in printed and (chunk := os.read(process.stdout.fileno(), 4096)):
        printed += chunk
    assert b"wrote" in printed
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=600)
    err = err.decode()
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    if process.returncode == -signal.SIGINT:
        # in the last steps of Python's finalization, which restores SIGINT's default
        # action: the signal ends the process (a shell reports 130), nothing printed
        assert err.strip() == "", err
        return
    # in the command or in Python's teardown: one line and 130
    assert process.returncode == 128 + signal.SIGINT, (process.returncode, err)
    assert len(err.strip().splitlines()) == 1, err


def _python(code: str) -> subprocess.CompletedProcess:
    """``python -c code``, its SIGINT at Python's default."""
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
        preexec_fn=sigint_default,
    )  # fmt: skip


def test_a_ctrl_c_in_a_weakref_callback_ends_the_command_in_one_line():
    """The garbage collector runs weakref callbacks anywhere; a Ctrl-C inside one cannot
    be raised, and Python would print it as ignored (a traceback) and carry on."""
    done = _python(
        "import signal, sys, weakref\n"
        "import softcurve.__main__ as entry\n"
        "sys.unraisablehook = entry._interrupted_in_a_callback\n"
        "class Held: pass\n"
        "def callback(reference):\n"
        "    signal.raise_signal(signal.SIGINT)\n"
        "    sum(range(1000))  # the handler runs here, inside the callback\n"
        "held = Held()\n"
        "watch = weakref.ref(held, callback)\n"
        "print('before', flush=True)\n"
        "del held\n"
        "print('carried on')\n"
    )
    assert _one_line_130(done) == "softcurve: interrupted"
    assert done.stderr == "softcurve: interrupted\n", done.stderr
    assert done.stdout == "before\n"


def test_the_command_line_installs_the_callbacks_hook():
    done = _python(
        "import sys\n"
        "import softcurve.__main__ as entry\n"
        "sys.argv = ['softcurve', '--version']\n"
        "try:\n"
        "    code = entry.main()\n"
        "except SystemExit as done:  # argparse's --version\n"
        "    code = done.code\n"
        "print(code, sys.unraisablehook is entry._interrupted_in_a_callback)\n"
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "0 True", done.stdout
