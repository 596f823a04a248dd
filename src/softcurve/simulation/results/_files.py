"""The trajectory file format: CSV (a JSON metadata line, a header, one row per output
time, 17 significant digits) or NPZ; documented in ``docs/configuration.md``. A file is
read only if it agrees with its own metadata (:class:`TrajectoryFileError`)."""

from __future__ import annotations

import io
import json
import re
import zipfile
import zlib
from pathlib import Path

import numpy as np

from softcurve.base.files import InputFileError, atomic_path, atomic_write, input_file
from softcurve.base.progress import ProgressLine
from softcurve.base.status import Status

FORMAT_VERSION = 2
"""Version of the trajectory format written (in the metadata line). Version 1 named the
actuator's inputs ``pressures`` (columns ``p1 ...``) and a failure ``"failed"``; both are
still read. The metadata's ``rows`` (the number of output times) was added within
version 2: a file without it is checked for everything else; so were ``coordinates``
and ``units`` (each coordinate's column and unit, per element kind): a file without them
has constant-curvature segments, ``l1 kx1 ky1 ...``."""

_LEGACY_STATUS = {"failed": "integration_failed"}

ROWS_PER_BLOCK = 100_000
"""Rows formatted at once when a CSV file is written (about 30 MB of text for one
segment, 1 to 2 s): the progress bar moves once per block."""


def _write_rows(out, table: np.ndarray, name: str, progress: bool) -> None:
    """Write ``table`` (rows, columns) as CSV lines into the open file ``out``, block by
    block, with a progress bar when ``progress`` and the table has more than one block."""
    blocks = max(1, -(-table.shape[0] // ROWS_PER_BLOCK))
    bar = ProgressLine(blocks, 0, progress and blocks > 1, "blocks", f"writing {name}")
    try:
        for b in range(blocks):
            part = table[b * ROWS_PER_BLOCK : (b + 1) * ROWS_PER_BLOCK]
            np.savetxt(out, part, delimiter=",", fmt="%.17g")
            bar.update(b + 1)
    finally:
        bar.close()


def coordinate_columns(robot) -> list[str]:
    """The columns of a robot's coordinates: each element's coordinate names numbered by
    the element from 1 (``l1 kx1 ky1`` for a constant-curvature segment, ``bend_x2 ...
    stretch2`` for a constant-strain one; a rigid body has none).

    Parameters
    ----------
    robot : Robot
        The robot.
    """
    return [f"{name}{i + 1}" for i, s in enumerate(robot.segments) for name in s.coordinate_names]


def column_names(
    n: int, n_creep: int, with_tau: bool, n_inputs: int = 0, coordinates=None
) -> list[str]:
    """CSV columns: t, the coordinates (``l1 kx1 ky1 ...``), their rates (``l1_dot
    ...``), lam1 ..., tip_x tip_y tip_z, tau1 ..., u1 ... (the actuator's inputs, when an
    actuator drove the robot).

    Parameters
    ----------
    n : int
        Number of coordinates.
    n_creep : int
        Number of creep states.
    with_tau : bool
        Whether the input forces are columns.
    n_inputs : int
        Number of actuator inputs.
    coordinates : sequence of str, optional
        The coordinates' columns, :func:`coordinate_columns`; default those of ``n / 3``
        constant-curvature segments (a file whose metadata does not name them).
    """
    if coordinates is None:  # files before the element kinds: constant curvature
        coordinates = [f"{c}{i + 1}" for i in range(n // 3) for c in ("l", "kx", "ky")]
    q = list(coordinates)
    names = ["t", *q, *(f"{c}_dot" for c in q), *(f"lam{i + 1}" for i in range(n_creep))]
    names += ["tip_x", "tip_y", "tip_z"]
    names += [f"tau{i + 1}" for i in range(n)] if with_tau else []
    return names + [f"u{i + 1}" for i in range(n_inputs)]


def _meta(trajectory) -> dict:
    model = trajectory.model
    named = {}
    if model is not None:
        named = {
            "coordinates": coordinate_columns(model.robot),
            "units": model.robot.coordinate_units(),
        }
    return {
        "format": "softcurve-trajectory",
        "version": FORMAT_VERSION,
        "n": trajectory.n,
        **named,
        "n_creep": trajectory.lam.shape[1],
        "n_inputs": 0 if trajectory.inputs is None else trajectory.inputs.shape[1],
        "rows": int(trajectory.t.size),
        "status": trajectory.status.value,
        "message": trajectory.message,
        "stats": trajectory.stats,
    }


def save_trajectory(trajectory, path, *, progress: bool = False) -> Path:
    """Write a trajectory to ``path``: ``.csv`` (one JSON comment line of metadata, a
    header, one row per output time, 17 significant digits) or ``.npz``.

    Parameters
    ----------
    trajectory : Trajectory
        What to write.
    path : str or Path
        Target file, ``.csv`` or ``.npz``.
    progress : bool
        A progress bar on stderr while a long CSV file is written (more than
        :data:`ROWS_PER_BLOCK` rows).
    """
    path = Path(path)
    tau, inputs = trajectory.tau, trajectory.inputs
    if inputs is not None and tau is None:
        raise ValueError("a trajectory with actuator inputs must carry tau (the force H(q) u)")
    meta = _meta(trajectory)
    if path.suffix == ".csv":
        blocks = [
            trajectory.t[:, None],
            trajectory.q,
            trajectory.qd,
            trajectory.lam,
            trajectory.tip,
        ] + [a for a in (tau, inputs) if a is not None]
        table = np.hstack(blocks)
        names = column_names(
            trajectory.n,
            meta["n_creep"],
            tau is not None,
            meta["n_inputs"],
            meta.get("coordinates"),
        )
        with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as out:
            out.write("# " + json.dumps(meta) + "\n")
            out.write(",".join(names) + "\n")
            _write_rows(out, table, path.name, progress)
        return path
    if path.suffix == ".npz":
        arrays = {
            "t": trajectory.t,
            "q": trajectory.q,
            "qd": trajectory.qd,
            "lam": trajectory.lam,
            "tip": trajectory.tip,
            "meta": np.array(json.dumps(meta)),
        }
        if tau is not None:
            arrays["tau"] = tau
        if inputs is not None:
            arrays["inputs"] = inputs
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **arrays)
        return atomic_write(path, buffer.getvalue())
    raise ValueError(f"path must end in .csv or .npz, got {path.name!r}")


class TrajectoryFileError(InputFileError):
    """A trajectory file disagrees with its own metadata or is not a trajectory: cut short,
    columns that do not match ``n``, a cell that is not a finite number, times that do
    not increase. The message names the file, the line (the row of an NPZ file) and what
    is wrong."""


_INTEGRATED_TO = re.compile(r"^integrated to t = (\S+) s\b")
"""The message of a successful run (``solvers._policy``): the time it reached, to six
significant digits; a file without ``rows`` is checked against it."""


def _count(path, meta: dict, key: str, minimum: int, default=None) -> int:
    """The whole number ``meta[key]`` (>= ``minimum``), or a :class:`TrajectoryFileError`."""
    value = meta.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise TrajectoryFileError(
            f"{path}: the metadata's {key} must be a whole number >= {minimum}, got {value!r}"
        )
    return value


def _metadata(path, text: str) -> dict:
    """The metadata JSON ``text`` of ``path``, its fields checked: ``format``, the counts
    ``n`` (with its ``coordinates`` named, or three per segment), ``n_creep``,
    ``n_inputs``, ``rows`` (absent in files written before it was recorded) and
    ``status``."""
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:
        raise TrajectoryFileError(f"{path}: its metadata is not JSON ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != "softcurve-trajectory":
        raise TrajectoryFileError(f"{path}: not a softcurve trajectory")
    missing = [k for k in ("n", "n_creep", "status", "message", "stats") if k not in meta]
    if missing:
        raise TrajectoryFileError(f"{path}: the metadata lacks {missing}")
    if not isinstance(meta["message"], str) or not isinstance(meta["stats"], dict):
        raise TrajectoryFileError(
            f"{path}: the metadata's message must be text and its stats a table, got "
            f"{type(meta['message']).__name__} and {type(meta['stats']).__name__}"
        )
    n = _count(path, meta, "n", 1)
    names = meta.get("coordinates")
    if names is not None:
        if not (isinstance(names, list) and len(names) == n and len(set(names)) == n
                and all(isinstance(c, str) and c for c in names)):  # fmt: skip
            raise TrajectoryFileError(
                f"{path}: the metadata's coordinates must be {n} distinct names (n = {n}), "
                f"got {names!r}"
            )
        units = meta.get("units")
        if not (isinstance(units, list) and len(units) == n
                and all(isinstance(u, str) for u in units)):  # fmt: skip
            raise TrajectoryFileError(
                f"{path}: the metadata's units must be {n} texts, one per coordinate "
                f"(n = {n}), got {units!r}"
            )
    elif n % 3:
        raise TrajectoryFileError(
            f"{path}: the metadata's n must be 3 per segment where it does not name its "
            f"coordinates, got {meta['n']!r}"
        )
    _count(path, meta, "n_creep", 0)
    meta["n_inputs"] = _count(path, meta, "n_inputs", 0, meta.get("n_pressures", 0))
    if "rows" in meta:
        _count(path, meta, "rows", 0)
    status = _LEGACY_STATUS.get(meta["status"], meta["status"])
    try:
        meta["status"] = Status.parse(status)
    except ValueError:
        known = [s.value for s in Status]
        raise TrajectoryFileError(
            f"{path}: the metadata's status {status!r} is none of {known}"
        ) from None
    return meta


def _columns(meta: dict, with_tau: bool) -> list[str]:
    """The column names of a file with ``meta``; version 1 named the inputs ``p1 ...``."""
    names = column_names(
        meta["n"], meta["n_creep"], with_tau, meta["n_inputs"], meta.get("coordinates")
    )
    if meta.get("version") == 1:
        names = [f"p{c[1:]}" if c.startswith("u") else c for c in names]
    return names


def _check_header(path, meta: dict, header: list[str]) -> bool:
    """Whether the CSV ``header`` (line 2) holds ``tau``; a
    :class:`TrajectoryFileError` if it is not the columns the metadata gives."""
    n, m = meta["n"], meta["n_inputs"]
    states = 2 * n + meta["n_creep"] + 4  # t, q, qd, lam, tip
    sizes = {True: states + n + m} if m else {False: states, True: states + n}  # u needs tau
    with_tau = min(sizes, key=lambda w: abs(sizes[w] - len(header)))
    what = f"{len(header)} columns, expected {sizes[with_tau]}"
    if max(n, meta["n_creep"], m) <= len(header):  # else no names could match: none built
        expected = _columns(meta, with_tau)
        differ = [k for k, (a, b) in enumerate(zip(header, expected, strict=False)) if a != b]
        if not differ and len(header) == len(expected):
            return with_tau
        if differ:
            k = differ[0]
            what = f"column {k + 1} is {header[k]!r}, expected {expected[k]!r}"
    counts = ", ".join(f"{k} = {meta[k]}" for k in ("n", "n_creep", "n_inputs"))
    raise TrajectoryFileError(
        f"{path}, line 2: the columns do not match the metadata ({counts}): {what}"
    )


def _bad_line(path, rows: list[str], lines: list[int], header: list[str]) -> TrajectoryFileError:
    """The error for the first of ``rows`` (on ``lines``) that is not one number per
    column of ``header``."""
    for row, number in zip(rows, lines, strict=True):
        cells = row.strip().split(",")
        if len(cells) != len(header):
            return TrajectoryFileError(
                f"{path}, line {number}: {len(cells)} fields, the header has {len(header)}"
            )
        for name, cell in zip(header, cells, strict=True):
            try:
                float(cell)
            except ValueError:
                return TrajectoryFileError(
                    f"{path}, line {number}, column {name!r}: {cell!r} is not a number"
                )
    return TrajectoryFileError(f"{path}: the rows cannot be read as numbers")


def _read_csv(path) -> tuple[dict, np.ndarray, bool, list]:
    """``(metadata, table, with_tau, where)`` of a CSV file; ``where[k]`` names row ``k``."""
    try:
        with open(path, encoding="utf-8") as f:
            first = f.readline()
            if not first.startswith("# "):
                raise TrajectoryFileError(
                    f"{path}, line 1: not a softcurve trajectory (no metadata)"
                )
            meta = _metadata(path, first[2:])
            header = f.readline().strip().split(",")
            rows, lines = [], []
            for number, line in enumerate(f, start=3):
                if line.strip():
                    rows.append(line)
                    lines.append(number)
    except UnicodeDecodeError as exc:
        raise TrajectoryFileError(
            f"{path}: not a UTF-8 text file (byte {exc.start}): not a softcurve trajectory"
        ) from None
    with_tau = _check_header(path, meta, header)
    if rows and not rows[-1].endswith("\n"):  # every line written ends in one
        raise TrajectoryFileError(
            f"{path}, line {lines[-1]}: the last line has no end: the file is cut inside it"
        )
    try:
        table = np.loadtxt(rows, delimiter=",", ndmin=2) if rows else np.empty((0, len(header)))
    except ValueError:
        raise _bad_line(path, rows, lines, header) from None
    if table.shape[1] != len(header):
        raise _bad_line(path, rows, lines, header)
    return meta, table, with_tau, [f"line {k}" for k in lines]


def _read_npz(path) -> tuple[dict, np.ndarray, bool, list]:
    """``(metadata, table, with_tau, where)`` of an NPZ file, its arrays side by side in
    the CSV's columns; ``where[k]`` names row ``k``."""
    try:
        # opened here: np.load leaves its own file open when the archive is damaged
        with open(path, "rb") as f, np.load(f, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise TrajectoryFileError(
            f"{path}: not a readable NPZ file, cut or damaged ({exc})"
        ) from None
    if "meta" not in arrays:
        raise TrajectoryFileError(f"{path}: not a softcurve trajectory (no array 'meta')")
    meta = _metadata(path, str(arrays["meta"]))
    if "pressures" in arrays:  # version 1
        arrays["inputs"] = arrays.pop("pressures")
    n, m = meta["n"], meta["n_inputs"]
    t = arrays.get("t")
    size = t.shape[0] if t is not None and t.ndim == 1 else -1
    shapes = {"t": (size,), "q": (size, n), "qd": (size, n), "lam": (size, meta["n_creep"])}
    shapes.update(tip=(size, 3))
    with_tau = "tau" in arrays
    if with_tau:
        shapes["tau"] = (size, n)
    if m or "inputs" in arrays:
        shapes["inputs"] = (size, m)
    for key, shape in shapes.items():
        got = arrays[key].shape if key in arrays else None
        if got != shape:
            raise TrajectoryFileError(
                f"{path}: array {key!r} has shape {got}, the metadata (n = {n}, n_creep = "
                f"{meta['n_creep']}, n_inputs = {m}) and 't' give {shape}"
            )
    if m and not with_tau:
        raise TrajectoryFileError(f"{path}: inputs without the array 'tau' (the force H(q) u)")
    table = np.hstack([arrays["t"][:, None], *(arrays[k] for k in shapes if k != "t")])
    return meta, table, with_tau, [f"row {k + 1}" for k in range(size)]


def _check_table(path, meta: dict, table: np.ndarray, names: list[str], where: list) -> None:
    """A :class:`TrajectoryFileError` naming the row ``where[k]`` if ``table`` has fewer
    or more rows than the metadata says (or, without ``rows``, ends before the time a
    successful run's message says it reached), a cell that is not finite, or times
    that do not increase."""
    size = table.shape[0]
    end = where[-1] if size else "the header"
    if "rows" in meta and size != meta["rows"]:
        cut = "it is cut" if size < meta["rows"] else "rows were added"
        raise TrajectoryFileError(
            f"{path}: {size} rows, ending at {end}, but the metadata says {meta['rows']}: {cut}"
        )
    claim = _INTEGRATED_TO.match(meta["message"]) if meta["status"] is Status.SUCCESS else None
    if "rows" not in meta and claim is not None:
        reached = float(f"{table[-1, 0]:.6g}") if size else None
        if reached != float(claim.group(1)):
            raise TrajectoryFileError(
                f"{path}: the data end at {end} (t = {reached} s), but the metadata says "
                f"{meta['message']!r}: it is cut"
            )
    bad = ~np.isfinite(table)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise TrajectoryFileError(
            f"{path}, {where[k]}, column {names[j]!r}: {table[k, j]} is not a finite number"
        )
    back = np.flatnonzero(np.diff(table[:, 0]) <= 0)
    if back.size:
        k = back[0] + 1
        raise TrajectoryFileError(
            f"{path}, {where[k]}: t = {float(table[k, 0])!r} s does not come after the row "
            f"before (t = {float(table[k - 1, 0])!r} s); the times of a trajectory increase"
        )


def read_trajectory(path) -> dict:
    """The fields of a trajectory written by :func:`save_trajectory`, as keyword
    arguments of :class:`~softcurve.simulation.results.Trajectory`, checked against the
    file's own metadata.

    Parameters
    ----------
    path : str or Path
        A ``.csv`` or ``.npz`` file (format version 1 or 2).

    Raises
    ------
    TrajectoryFileError
        Naming the file, the line (CSV) or row (NPZ) and what is wrong: fewer or more
        rows than the metadata's ``rows`` (without ``rows``, a successful run's data
        ending before the time its message says it reached), columns that do not match
        ``n``, ``n_creep`` and ``n_inputs``, a NaN or infinite cell, a time not after
        the one before. A failed run's file may end early: it loads, with its status.
    """
    path = Path(path)
    if path.suffix not in (".csv", ".npz"):
        raise TrajectoryFileError(f"path must end in .csv or .npz, got {path.name!r}")
    path = input_file(path, "trajectory file")
    meta, table, with_tau, where = (_read_csv if path.suffix == ".csv" else _read_npz)(path)
    _check_table(path, meta, table, _columns(meta, with_tau), where)
    n, n_creep, m = meta["n"], meta["n_creep"], meta["n_inputs"]
    cuts = np.cumsum([1, n, n, n_creep, 3, n if with_tau else 0, m])
    parts = np.split(table, cuts, axis=1)
    states = ("q", "qd", "lam", "tip_positions")
    return {
        "t": np.array(parts[0][:, 0]),
        **{k: np.array(a) for k, a in zip(states, parts[1:5], strict=True)},
        "tau": np.array(parts[5]) if with_tau else None,
        "inputs": np.array(parts[6]) if m else None,
        "stats": meta["stats"],
        "status": meta["status"],
        "message": meta["message"],
        "coordinates": meta.get("coordinates"),
        "units": meta.get("units"),
    }
