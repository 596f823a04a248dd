"""Fault injection (issue 11): bad input and faults through the command line and the API.

Each case asserts the exit code (2: bad input, 1: failure), the key words of the one
line printed, no traceback, and that no output file was left half-written.
"""

from __future__ import annotations

import dataclasses
import io
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import softcurve as sc
from softcurve.base import files
from softcurve.base.validation import ParameterError
from softcurve.cli import build_parser, main
from softcurve.compiled._build import checksum_file
from softcurve.simulation._settings import SimulationSettings

ROOT = Path(__file__).resolve().parents[1]


def run(argv, capsys):
    """``(exit code, stdout, stderr)`` of ``softcurve argv`` in this process."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err, err
    return code, out, err


def leftovers(folder: Path) -> list[str]:
    """Temporary files (half-written outputs) left in ``folder`` and below."""
    return [p.name for p in folder.rglob(".*") if ".pid" in p.name]


@pytest.fixture
def compiled(paper_model):
    """The paper's model, compiled once per session (the CLI reuses the library)."""
    return paper_model


# -- case 5: output locations, sizes, damaged files, long writes ---------------------------
@pytest.fixture
def a_file(tmp_path) -> Path:
    path = tmp_path / "a_file"
    path.write_text("not a folder")
    return path


def counted(monkeypatch, owner, name: str) -> list:
    """Calls of ``owner.name`` (the real one, still called), each appended to the returned
    list: a budget on work done, which a loaded machine cannot make fail."""
    calls, real = [], getattr(owner, name)

    def counting(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(owner, name, counting)
    return calls


def test_simulate_output_under_a_file_is_refused_before_integrating(a_file, capsys, monkeypatch):
    """Refused before any work: no model built, nothing of the 1000 s integrated."""
    import softcurve.simulation

    built = counted(monkeypatch, sc.Model, "__init__")
    simulated = counted(monkeypatch, softcurve.simulation, "simulate")
    code, _, err = run(["simulate", "-o", a_file / "out", "--t-final", "1000"], capsys)
    assert code == 2 and "--output" in err and "not a folder" in err
    assert built == [] and simulated == []
    assert a_file.read_text() == "not a folder"


@pytest.mark.parametrize(
    "argv, option",
    [
        (["equilibria", "--starts", "1", "--plot", "{file}/e.png"], "--plot"),
        (["fit", "{csv}", "--strain", "x", "--force", "f", "--figure", "{file}/f.png"], "--figure"),
    ],
)
def test_figure_under_a_file_is_refused_before_work(a_file, tmp_path, capsys, argv, option):
    csv = tmp_path / "data.csv"
    csv.write_text("x,f\n" + "".join(f"{x},{2 * x}\n" for x in np.linspace(-1, 1, 9)))
    argv = [a.format(file=a_file, csv=csv) for a in argv]
    code, out, err = run(argv, capsys)
    assert code == 2 and option in err and "not a folder" in err and out == ""


def test_sweep_output_under_a_file(a_file, tmp_path, capsys):
    pytest.importorskip("pyarrow")
    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=0.1, points=2))
    code, _, err = run(["sweep", config, "-o", a_file / "out", "--no-progress"], capsys)
    assert code == 2 and "not a folder" in err


def test_read_only_filesystem_is_refused(tmp_path, capsys):
    target = Path("/sys/softcurve-fault-test")  # sysfs refuses new folders, even to root
    try:
        target.mkdir()
    except OSError:
        pass
    else:  # pragma: no cover
        target.rmdir()
        pytest.skip("/sys is writable here")
    code, _, err = run(["simulate", "-o", target, "--t-final", "0.01"], capsys)
    assert code == 2 and "cannot write there" in err and str(target) in err


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_is_refused(tmp_path, capsys):  # pragma: no cover - as root
    folder = tmp_path / "ro"
    folder.mkdir(mode=0o500)
    code, _, err = run(["simulate", "-o", folder, "--t-final", "0.01"], capsys)
    assert code == 2 and "permission denied" in err


@pytest.mark.parametrize(
    "option", [["--t-final", "1e7"], ["--t-final", "1e300"], ["--dt", "1e-300"]]
)
def test_huge_outputs_are_refused_with_the_estimate(tmp_path, capsys, option):
    out = tmp_path / "out"
    code, _, err = run(["simulate", "-o", out, *option], capsys)
    assert code == 2
    for word in ("output times", "in memory", "of CSV", "--max-outputs"):
        assert word in err, word
    assert not out.exists()


def test_max_outputs_is_a_setting_the_user_can_raise():
    with pytest.raises(ParameterError, match="max_outputs"):
        SimulationSettings(t_final=1.0, dt=0.25, max_outputs=4)
    assert SimulationSettings(t_final=1.0, dt=0.25, max_outputs=5).output_times().size == 5
    with pytest.raises(ParameterError, match="max_outputs"):
        SimulationSettings(t_final=1e7)


def test_long_csv_writes_show_progress(compiled, tmp_path, capsys, monkeypatch):
    from softcurve.simulation.results import _files as trajectory_files

    monkeypatch.setattr(trajectory_files, "ROWS_PER_BLOCK", 20)
    trajectory = sc.simulate(compiled, [0.064, 5.0, 0.0], np.zeros(3), t_final=0.1, dt=1e-3)
    path = trajectory_files.save_trajectory(trajectory, tmp_path / "t.csv", progress=True)
    err = capsys.readouterr().err
    assert "writing t.csv" in err and "6/6 blocks" in err
    np.testing.assert_array_equal(sc.load_trajectory(path).x, trajectory.x)


SWEEP_TOML = """
[robot]
preset = "ifac2020"

[simulation]
t_final = {t_final}
q0 = [0.064, 20.0, 0.0]
qd0 = [0.0, 0.0, 300.0]

[sweep]
design = "grid"
chunk_size = 1
output_dt = 0.01

[[sweep.variables]]
name = "q0[1]"
low = -20.0
high = 20.0
points = {points}
"""


@pytest.mark.filterwarnings("default:.*damaged part file:RuntimeWarning")
def test_damaged_sweep_part_is_recomputed(compiled, tmp_path, capsys):
    pytest.importorskip("pyarrow")
    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=0.1, points=3))
    out = tmp_path / "out"
    argv = ["sweep", config, "-o", out, "--workers", "0", "--no-progress", "-q"]
    code, _, err = run(argv, capsys)
    assert code == 0, err
    first = (out / "results.parquet").read_bytes()
    part = out / "parts" / "chunk-000001.parquet"
    part.write_bytes(part.read_bytes()[: part.stat().st_size // 2])  # a partial copy
    code, _, err = run(argv, capsys)
    assert code == 0 and "warning: " in err and "chunk-000001.parquet: damaged part file" in err
    assert "computed again" in err
    import pyarrow.parquet as pq

    assert pq.read_table(out / "results.parquet").equals(pq.read_table(io.BytesIO(first)))
    assert leftovers(out) == []


# -- case 6: workers die with the sweep; one sweep per folder -------------------------------
def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (children, their children...), read from /proc."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parent = int(stat.rpartition(")")[2].split()[1])
            children.setdefault(parent, []).append(int(entry.name))
    found, todo = set(), [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.add(child)
            todo.append(child)
    return found


def working(pid: int) -> bool:
    """Whether the sweep ``pid`` has two workers past their start-up (each runs more
    than one thread: the pool's and the one that watches the parent)."""
    workers = 0
    for child in descendants(pid):
        try:
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
            status = Path(f"/proc/{child}/status").read_text()
        except OSError:
            continue
        threads = int(status.split("Threads:")[1].split()[0])
        workers += b"spawn_main" in cmdline and threads > 1
    return workers >= 2


def alive(pids) -> set[int]:
    left = set()
    for pid in pids:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
        except OSError:
            continue
        if state != "Z":
            left.add(pid)
    return left


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGTERM])
def test_killed_sweep_leaves_no_process_and_holds_its_folder(compiled, tmp_path, capsys, signum):
    pytest.importorskip("pyarrow")
    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=1000.0, points=8))  # runs for minutes
    out = tmp_path / "out"
    workers: set[int] = set()
    sweep = subprocess.Popen(
        [sys.executable, "-m", "softcurve", "sweep", config, "-o", out, "--workers", "2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120  # the workers start, import, then simulate
        while not working(sweep.pid) and time.monotonic() < deadline:
            assert sweep.poll() is None, "the sweep ended early"
            time.sleep(0.2)
        workers = descendants(sweep.pid)
        assert len(workers) >= 3  # two workers and multiprocessing's resource tracker
        # a second sweep on the same folder is refused while the first runs
        code, _, err = run(["sweep", config, "-o", out, "--workers", "0"], capsys)
        assert code == 2 and "another sweep" in err and f"pid {sweep.pid}" in err
        assert str(out) in err
        sweep.send_signal(signum)
        sweep.wait(timeout=30)
        # A worker's watcher thread acts within PARENT_POLL, or once the compiled call the
        # worker is in returns (it needs the interpreter): building a worker's integrator
        # right after start-up takes seconds on a loaded machine.
        deadline = time.monotonic() + 60
        while alive(workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = {pid: Path(f"/proc/{pid}/cmdline").read_bytes()[:80] for pid in alive(workers)}
        assert left == {}, "worker processes outlived the killed sweep"
    finally:
        if sweep.poll() is None:
            sweep.kill()
            sweep.wait()
        for pid in alive(descendants(sweep.pid) | workers):  # else they hold stderr open
            os.kill(pid, signal.SIGKILL)
        err = sweep.communicate()[1]
    if signum == signal.SIGTERM:
        assert "stopped" in err and sweep.returncode == 128 + signum
    assert leftovers(out) == []


def test_folder_lock_names_the_holder(tmp_path):
    with files.folder_lock(tmp_path, "sweep"):
        holder = subprocess.run(
            [
                sys.executable,
                "-c",
                "import sys; from softcurve.base.files import folder_lock\n"
                f"with folder_lock({str(tmp_path)!r}, 'sweep'): pass",
            ],
            capture_output=True,
            text=True,
        )
    assert holder.returncode != 0 and f"pid {os.getpid()}" in holder.stderr
    with files.folder_lock(tmp_path, "sweep"):  # released: taken again
        pass


# -- case 7: fits --------------------------------------------------------------------------
@pytest.fixture
def two_points(tmp_path) -> Path:
    path = tmp_path / "two.csv"
    path.write_text("x,f\n0.1,1\n0.2,2\n")
    return path


@pytest.mark.parametrize("level", ["1.5", "-1", "0", "1"])
def test_fit_confidence_outside_zero_one(two_points, capsys, level):
    argv = ["fit", two_points, "--strain", "x", "--force", "f", "--law", "linear"]
    code, out, err = run([*argv, f"--confidence={level}"], capsys)
    assert code == 2 and "--confidence" in err and "(0, 1)" in err and out == ""
    with pytest.raises(ParameterError, match="confidence"):
        sc.fit_stiffness([0.1, 0.2, 0.3], [1.0, 2.0, 3.0], "linear", confidence=float(level))


def test_fit_with_fewer_points_than_parameters(two_points, capsys):
    code, out, err = run(["fit", two_points, "--strain", "x", "--force", "f"], capsys)
    assert code == 2 and "3 parameter(s)" in err and "at least 4" in err and "got 2" in err
    with pytest.raises(ParameterError, match="at least 4 data points"):
        sc.fit_stiffness([0.1, 0.2, 0.3], [1.0, 2.0, 3.0], "tanh")


# -- case 8: stale temporary files ---------------------------------------------------------
def dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_stale_temporary_files_are_removed_live_ones_kept(tmp_path):
    target = tmp_path / "trajectory.csv"
    here = files.temporary_tag().partition("@")[2]
    stale = tmp_path / f".trajectory.csv.pid{dead_pid()}@{here}.0123abcd.csv"
    live = tmp_path / f".trajectory.csv.pid{os.getppid()}@{here}.0123abcd.csv"
    elsewhere = tmp_path / f".trajectory.csv.pid{dead_pid()}@another-host.0123abcd.csv"
    other = tmp_path / f".tip.png.pid{dead_pid()}@{here}.0123abcd.png"
    for path in (stale, live, elsewhere, other):
        path.write_text("partial")
    files.atomic_write(target, b"whole")
    assert not stale.exists() and live.exists() and elsewhere.exists() and other.exists()
    assert target.read_bytes() == b"whole"


def test_simulate_cleans_a_killed_run(compiled, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    here = files.temporary_tag().partition("@")[2]
    stale = out / f".trajectory.csv.pid{dead_pid()}@{here}.0123abcd.csv"
    stale.write_text("# half a trajectory")
    code, _, _ = run(["simulate", "-o", out, "--t-final", "0.01", "--no-figures"], capsys)
    assert code == 0 and not stale.exists() and leftovers(out) == []


def test_temporary_file_carries_the_writers_pid(tmp_path):
    with files.atomic_path(tmp_path / "a.csv") as tmp:
        assert f".pid{os.getpid()}@" in tmp.name and tmp.suffix == ".csv"


# -- case 9: messages ----------------------------------------------------------------------
def test_negative_numbers_in_scientific_notation():
    parser = build_parser()
    args = parser.parse_args(["equilibria", "--gravity", "0", "0", "-1e6"])
    assert args.gravity == [0.0, 0.0, -1e6]
    args = parser.parse_args(["equilibria", "--pressures", "-2e4", "0", "-.5E+1", "-inf"])
    assert args.inputs[:3] == [-2e4, 0.0, -5.0] and args.inputs[3] == -np.inf


def test_negative_pressure_reaches_validation(capsys):
    code, _, err = run(["equilibria", "--pressures", "-2e4", "0", "0"], capsys)
    assert code == 2 and "pressures[0]" in err and "expected" not in err


def test_key_typo_names_the_unknown_key(tmp_path, capsys):
    config = tmp_path / "typo.toml"
    config.write_text("[robot]\n[[robot.segments]]\nrest_lenght = 0.064\n")
    code, _, err = run(["simulate", config, "-o", tmp_path / "out"], capsys)
    assert code == 2 and "rest_lenght: unknown key" in err and "'rest_length'" in err
    config.write_text('[robot]\npreset = "ifac2020"\n[simulation]\nt_finall = 1.0\n')
    code, _, err = run(["simulate", config, "-o", tmp_path / "out"], capsys)
    assert code == 2 and "t_finall: unknown key; did you mean 't_final'?" in err


def test_integrator_advice_names_the_options(compiled, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["simulate", "-o", out, "--t-final", "0.05", "--max-steps", "1", "--no-figures"]
    code, _, err = run(argv, capsys)
    assert code == 1 and "--max-steps" in err and "--method bdf" in err
    assert "max_steps" not in err and "method='bdf'" not in err
    assert sc.load_trajectory(out / "trajectory.csv").status is sc.Status.INTEGRATION_FAILED


# -- never a traceback ---------------------------------------------------------------------
def test_unexpected_error_is_one_line_and_debug_shows_it(monkeypatch, capsys):
    from softcurve.cli import info

    def boom(args):
        raise RuntimeError("something broke\ninside")

    monkeypatch.setattr(info, "COMMAND", dataclasses.replace(info.COMMAND, run=boom))
    code, _, err = run(["info"], capsys)
    assert code == 1 and err.count("\n") == 1
    assert "RuntimeError: something broke inside" in err and "--debug" in err
    assert main(["--debug", "info"]) == 1
    assert "Traceback" in capsys.readouterr().err
    assert main(["info", "--debug"]) == 1
    assert "Traceback" in capsys.readouterr().err


# -- H1's and H2's cases, through the command line and the API -----------------------------
def test_codegen_check_with_relative_output(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(["codegen", "--check", "-o", "c_out"], capsys)
    assert code == 0, err
    assert "test program" in out and (tmp_path / "c_out" / "softcurve_model.c").exists()


def softcurve_process(*argv, **env):
    """``softcurve argv`` in a new process: ``(exit code, stdout, stderr)``."""
    done = subprocess.run(
        [sys.executable, "-m", "softcurve", *map(str, argv)],
        capture_output=True,
        text=True,
        env={**os.environ, **env},
        timeout=600,
    )
    assert "Traceback" not in done.stderr, done.stderr
    return done.returncode, done.stdout, done.stderr


def test_damaged_cache_is_rebuilt(paper_model, tmp_path):
    """A damaged library in the command line's cache is replaced with one warning line and
    the run's numbers are unchanged. The three kinds of damage (empty, random, truncated)
    are each covered in process by tests/test_cache_integrity.py; here the truncated one,
    end to end, in a cache seeded with the session's intact library (one rebuild, not
    four compiles)."""
    cache = tmp_path / "cache"
    cache.mkdir()
    library = paper_model.compiled_library
    if library is None:
        pytest.skip("no C compiler: nothing is cached")
    for source in (library, checksum_file(library)):
        shutil.copyfile(source, cache / source.name)
    argv = ["simulate", "--t-final", "0.01", "--no-figures", "--no-progress"]
    code, _, err = softcurve_process(*argv, "-o", tmp_path / "good", SOFTCURVE_CACHE_DIR=cache)
    assert code == 0 and "warning" not in err, err  # the seeded library was used as is
    expected = (tmp_path / "good" / "trajectory.csv").read_text().splitlines()[2:]
    seeded = cache / library.name
    content = seeded.read_bytes()
    seeded.write_bytes(content[: len(content) // 2])  # no process has it loaded
    code, _, err = softcurve_process(*argv, "-o", tmp_path / "run", SOFTCURVE_CACHE_DIR=cache)
    assert code == 0 and "warning: " in err and "replac" in err, err
    lines = err.splitlines()  # one warning line, the rebuild's two (and the driver's, if built)
    assert err.count("warning: ") == 1 and len(lines) - 1 == 2 * err.count(": compiled "), err
    assert "compiling the model of" in err and "compiled the model of" in err  # the rebuild's
    assert (tmp_path / "run" / "trajectory.csv").read_text().splitlines()[2:] == expected
    assert seeded.read_bytes() != content[: len(content) // 2]


def test_length_crossing_zero_fails_with_left_domain(compiled, tmp_path, capsys):
    config = tmp_path / "soft.toml"
    config.write_text(
        textwrap.dedent(
            """
            [robot]
            preset = "ifac2020"
            [simulation]
            t_final = 1.0
            dt = 0.001
            q0 = [0.064, 0.0, 0.0]
            qd0 = [-50.0, 0.0, 0.0]
            """
        )
    )
    out = tmp_path / "out"
    code, _, err = run(["simulate", config, "-o", out, "--no-figures"], capsys)
    assert code == 1 and "left_domain" in err.lower()
    trajectory = sc.load_trajectory(out / "trajectory.csv")
    assert trajectory.status is sc.Status.LEFT_DOMAIN and trajectory.t.size > 1
    assert np.all(trajectory.q[:, 0] > 0)
    assert leftovers(out) == []


def test_negative_creep_compliance_in_a_file(tmp_path, capsys):
    config = tmp_path / "active.toml"
    config.write_text(
        textwrap.dedent(
            """
            [robot]
            [[robot.segments]]
            rest_length = 0.064
            mass = 0.05
            radius = 0.01
            elongation_stiffness = { law = "linear", k0 = 2000.0 }
            bending_stiffness = { law = "linear", k0 = 0.4 }
            [robot.segments.creep]
            compliance = [-1e-3, 1e-3, 1e-3]
            rate = [1.0, 1.0, 1.0]
            gain = [1.0, 1.0, 1.0]
            """
        )
    )
    out = tmp_path / "out"
    code, _, err = run(["simulate", config, "-o", out], capsys)
    assert code == 2 and "compliance" in err
    assert not (out / "trajectory.csv").exists()


def test_worker_pool_survives_the_end_of_the_thread_that_started_it(tmp_path):
    """Workers die with the thread that spawned them (the kernel's parent-death signal
    follows threads): a pool started from a finished thread must not serve the next call."""
    script = tmp_path / "pool_from_thread.py"
    script.write_text(
        "import threading\n"
        "from softcurve.simulation.batch._workers import run_in_processes\n"
        "def square(x):\n    return x * x\n"
        "def run():\n    return dict(run_in_processes(square, {i: (i,) for i in range(4)}, 2))\n"
        "if __name__ == '__main__':\n"
        "    out = {}\n"
        "    t = threading.Thread(target=lambda: out.update(run()))\n"
        "    t.start(); t.join()\n"
        "    print(sorted(out.values()), sorted(run().values()))\n"
    )
    done = subprocess.run(
        [sys.executable, "-W", "ignore", str(script)],
        capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[0, 1, 4, 9] [0, 1, 4, 9]"
