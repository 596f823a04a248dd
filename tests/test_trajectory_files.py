"""Trajectory files are read only if they agree with their own metadata: a file cut short,
columns that do not match ``n``, NaN cells and times that do not increase are refused,
naming the file and the line (the row of an NPZ file)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import softcurve as sc
from softcurve.simulation.results import TrajectoryFileError


@pytest.fixture(scope="module")
def run(paper_model):
    """201 output times to t = 0.2 s, as in the report of a cut file."""
    return sc.simulate(paper_model, [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0], t_final=0.2)


def _lines(run, tmp_path) -> list[str]:
    """The lines of ``run`` saved as CSV, with their ends."""
    return run.save(tmp_path / "good.csv").read_text().splitlines(keepends=True)


def _write(tmp_path, lines, name="run.csv"):
    path = tmp_path / name
    path.write_text("".join(lines))
    return path


def _with_meta(lines, **changes):
    """``lines`` with the metadata's fields changed (a value None removes the field)."""
    meta = json.loads(lines[0][2:])
    meta.update(changes)
    meta = {k: v for k, v in meta.items() if v is not None}
    return ["# " + json.dumps(meta) + "\n", *lines[1:]]


UNNAMED = {"coordinates": None, "units": None}
"""Metadata without the coordinates' names: a file written before they were recorded."""


def _refused(path, match):
    """Loading ``path`` raises a ParameterError naming the file and matching ``match``."""
    with pytest.raises(sc.ParameterError, match=match) as info:
        sc.load_trajectory(path)
    assert isinstance(info.value, TrajectoryFileError)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_a_good_trajectory_round_trips_bit_for_bit(run, tmp_path, suffix):
    loaded = sc.load_trajectory(run.save(tmp_path / f"run{suffix}"))
    for name in ("t", "q", "qd", "lam", "tip"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(run, name), err_msg=name)
    assert loaded.t.size == 201 and loaded.t[-1] == 0.2
    assert loaded.status is sc.Status.SUCCESS and loaded.message == run.message
    assert loaded.stats == run.stats


def test_csv_records_its_rows(run, tmp_path):
    lines = _lines(run, tmp_path)
    assert json.loads(lines[0][2:])["rows"] == 201 == len(lines) - 2


def test_csv_cut_at_a_line_boundary_is_refused(run, tmp_path):
    path = _write(tmp_path, _lines(run, tmp_path)[: 2 + 100])
    _refused(path, r"100 rows, ending at line 102, but the metadata says 201: it is cut")


def test_csv_without_rows_cut_at_a_line_boundary_is_refused_by_its_message(run, tmp_path):
    """A file written before ``rows`` was recorded: a successful run's data must reach
    the time its message says."""
    lines = _with_meta(_lines(run, tmp_path), rows=None)
    assert sc.load_trajectory(_write(tmp_path, lines, "whole.csv")).t.size == 201
    path = _write(tmp_path, lines[: 2 + 100])
    _refused(path, r"end at line 102 \(t = 0.099 s\).*'integrated to t = 0.2 s")


def test_csv_cut_inside_a_line_is_refused(run, tmp_path):
    lines = _lines(run, tmp_path)
    path = _write(tmp_path, [*lines[:-1], lines[-1][:20]])  # the last number cut short
    _refused(path, "line 203: the last line has no end: the file is cut inside it")


def test_failed_run_ends_early_and_loads_with_its_status(run, tmp_path):
    """A failed run's data end before t_final: its file loads, with or without ``rows``."""
    failed = dataclasses.replace(
        run,
        **{k: getattr(run, k)[:60] for k in ("t", "q", "qd", "lam", "tau")},
        tip_positions=run.tip[:60],
        status=sc.Status.INTEGRATION_FAILED,
        message="CVODES CV_TOO_MUCH_WORK: the trajectory stops at t = 0.059 s",
    )
    lines = _lines(failed, tmp_path)
    for path in (_write(tmp_path, lines), _write(tmp_path, _with_meta(lines, rows=None))):
        loaded = sc.load_trajectory(path)
        assert loaded.status is sc.Status.INTEGRATION_FAILED and loaded.t.size == 60


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"n": 6, **UNNAMED}, r"line 2: the columns do not match the metadata \(n = 6, "
                              r"n_creep = 3, n_inputs = 0\): column 5 is 'l1_dot', expected 'l2'"),
        ({"n_creep": 0}, r"n_creep = 0.*column 8 is 'lam1', expected 'tip_x'"),
        ({"n_inputs": 2}, r"n_inputs = 2\): 16 columns, expected 18"),
        ({"n": 4, **UNNAMED}, "n must be 3 per segment where it does not name its coordinates"),
        ({"n": 4}, r"coordinates must be 4 distinct names \(n = 4\), got \['l1', 'kx1', 'ky1'\]"),
        ({"n": 3 * 10**9, **UNNAMED}, "16 columns, expected 6000000007"),  # no names built
        ({"coordinates": ["l1", "kx1", "kx1"]}, "coordinates must be 3 distinct names"),
    ],
)  # fmt: skip
def test_csv_whose_n_disagrees_with_its_columns_is_refused(run, tmp_path, changes, match):
    _refused(_write(tmp_path, _with_meta(_lines(run, tmp_path), **changes)), match)


def test_csv_header_renamed_is_refused(run, tmp_path):
    lines = _lines(run, tmp_path)
    lines[1] = lines[1].replace("kx1,ky1", "ky1,kx1", 1)
    _refused(_write(tmp_path, lines), "line 2: .*column 3 is 'ky1', expected 'kx1'")


@pytest.mark.parametrize("cell", ["nan", "inf", "-inf"])
def test_csv_with_a_nan_cell_is_refused(run, tmp_path, cell):
    lines = _lines(run, tmp_path)
    fields = lines[9].split(",")  # line 10
    fields[2] = cell  # kx1
    lines[9] = ",".join(fields)
    _refused(_write(tmp_path, lines), rf"line 10, column 'kx1': {cell} is not a finite number")


def test_csv_with_a_time_not_increasing_is_refused(run, tmp_path):
    lines = _lines(run, tmp_path)
    fields = lines[19].split(",")  # line 20: its time set to that of line 19
    fields[0] = lines[18].split(",")[0]
    lines[19] = ",".join(fields)
    _refused(
        _write(tmp_path, lines),
        r"line 20: t = 0.016 s does not come after the row before \(t = 0.016 s\)",
    )


def test_csv_with_a_short_row_is_refused(run, tmp_path):
    lines = _lines(run, tmp_path)
    lines[30] = ",".join(lines[30].split(",")[:5]) + "\n"
    _refused(_write(tmp_path, lines), "line 31: 5 fields, the header has 16")


def _npz(run, tmp_path, **changes):
    """``run`` saved as NPZ with arrays replaced (``meta`` a dict of field changes)."""
    with np.load(run.save(tmp_path / "good.npz")) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays["meta"]))
    meta.update(changes.pop("meta", {}))
    arrays.update(changes, meta=np.array(json.dumps(meta)))
    path = tmp_path / "run.npz"
    np.savez(path, **arrays)
    return path


def test_npz_faults_are_refused_naming_the_row(run, tmp_path):
    cut = {k: getattr(run, k)[:100] for k in ("t", "q", "qd", "lam", "tip", "tau")}
    _refused(_npz(run, tmp_path, **cut), "100 rows, ending at row 100, but the metadata says 201")
    six = {"n": 6, "coordinates": ["l1", "kx1", "ky1", "l2", "kx2", "ky2"]}
    six["units"] = ["m", "1/m", "1/m"] * 2
    _refused(_npz(run, tmp_path, meta=six), r"array 'q' has shape \(201, 3\).* \(201, 6\)")
    q = run.q.copy()
    q[5, 1] = np.nan
    _refused(_npz(run, tmp_path, q=q), "row 6, column 'kx1': nan is not a finite number")
    t = run.t.copy()
    t[7] = t[6]
    _refused(_npz(run, tmp_path, t=t), "row 8: t = .* does not come after the row before")
    whole = run.save(tmp_path / "whole.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(whole[: len(whole) // 2])
    _refused(tmp_path / "cut.npz", "not a readable NPZ file, cut or damaged")


def test_an_npz_without_times_and_metadata_of_other_types_are_refused(run, tmp_path):
    """Before: KeyError 't' and a TypeError from the message's pattern."""
    path = _npz(run, tmp_path)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k != "t"}
    np.savez(path, **arrays)
    _refused(path, r"array 't' has shape None")
    _refused(_npz(run, tmp_path, meta={"message": 5}), "message must be text and its stats")
    lines = _with_meta(_lines(run, tmp_path), stats=[1, 2])
    _refused(_write(tmp_path, lines), "message must be text and its stats a table")
