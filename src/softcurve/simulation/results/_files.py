"""The trajectory file format: CSV (a JSON metadata line, a header, one row per output
time, 17 significant digits) or NPZ; documented in ``docs/configuration.md``."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from softcurve.base.files import atomic_path, atomic_write
from softcurve.base.progress import ProgressLine

FORMAT_VERSION = 2
"""Version of the trajectory format written (in the metadata line). Version 1 named the
actuator's inputs ``pressures`` (columns ``p1 ...``) and a failure ``"failed"``; both are
still read."""

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


def column_names(n: int, n_creep: int, with_tau: bool, n_inputs: int = 0) -> list[str]:
    """CSV columns: t, l1 kx1 ky1 ..., l1_dot ..., lam1 ..., tip_x tip_y tip_z, tau1 ...,
    u1 ... (the actuator's inputs, when an actuator drove the robot).

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
    """
    q = [f"{c}{i + 1}" for i in range(n // 3) for c in ("l", "kx", "ky")]
    names = ["t", *q, *(f"{c}_dot" for c in q), *(f"lam{i + 1}" for i in range(n_creep))]
    names += ["tip_x", "tip_y", "tip_z"]
    names += [f"tau{i + 1}" for i in range(n)] if with_tau else []
    return names + [f"u{i + 1}" for i in range(n_inputs)]


def _meta(trajectory) -> dict:
    return {
        "format": "softcurve-trajectory",
        "version": FORMAT_VERSION,
        "n": trajectory.n,
        "n_creep": trajectory.lam.shape[1],
        "n_inputs": 0 if trajectory.inputs is None else trajectory.inputs.shape[1],
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
        names = column_names(trajectory.n, meta["n_creep"], tau is not None, meta["n_inputs"])
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


def read_trajectory(path) -> dict:
    """The fields of a trajectory written by :func:`save_trajectory`, as keyword
    arguments of :class:`~softcurve.simulation.results.Trajectory`.

    Parameters
    ----------
    path : str or Path
        A ``.csv`` or ``.npz`` file (format version 1 or 2).
    """
    path = Path(path)
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            arrays = {k: data[k] for k in ("t", "q", "qd", "lam")}
            arrays["tip_positions"] = data["tip"]
            tau = data["tau"] if "tau" in data else None
            key = "inputs" if "inputs" in data else "pressures"  # version 1: pressures
            inputs = data[key] if key in data else None
    elif path.suffix == ".csv":
        with open(path, encoding="utf-8") as f:
            first = f.readline()
            header = f.readline().strip().split(",")
            if not first.startswith("# "):
                raise ValueError(f"{path}: not a softcurve trajectory (no metadata line)")
            meta = json.loads(first[2:])
            rows = [line for line in f if line.strip()]
        table = np.loadtxt(rows, delimiter=",", ndmin=2) if rows else np.empty((0, len(header)))
        n, n_creep = meta["n"], meta["n_creep"]
        if table.shape[1] != len(header):
            raise ValueError(f"{path}: {table.shape[1]} columns, header names {len(header)}")
        cuts = np.cumsum([1, n, n, n_creep, 3])
        arrays = {
            "t": table[:, 0],
            "q": table[:, cuts[0] : cuts[1]],
            "qd": table[:, cuts[1] : cuts[2]],
            "lam": table[:, cuts[2] : cuts[3]],
            "tip_positions": table[:, cuts[3] : cuts[4]],
        }
        tau = table[:, cuts[4] : cuts[4] + n] if table.shape[1] > cuts[4] else None
        m = meta.get("n_inputs", meta.get("n_pressures", 0))  # version 1: n_pressures
        inputs = table[:, cuts[4] + n : cuts[4] + n + m] if m else None
    else:
        raise ValueError(f"path must end in .csv or .npz, got {path.name!r}")
    if meta.get("format") != "softcurve-trajectory":
        raise ValueError(f"{path}: not a softcurve trajectory")
    return {
        **{k: np.array(v) for k, v in arrays.items()},
        "tau": tau,
        "inputs": inputs,
        "stats": meta["stats"],
        "status": _LEGACY_STATUS.get(meta["status"], meta["status"]),
        "message": meta["message"],
    }
