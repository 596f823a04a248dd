"""The part files of a sweep folder: one Parquet file per chunk in ``<out>/parts/``,
written whole (:func:`~softcurve.base.files.atomic_path`). A part that cannot be read,
or has the wrong number of rows (a partial copy, a damaged disk), is deleted with a
warning so that its chunk is computed again."""

from __future__ import annotations

import warnings
from pathlib import Path

from softcurve.scenarios.tables import ConfigError


def part_path(parts: Path, c: int) -> Path:
    """The part file of chunk ``c`` in the folder ``parts``.

    Parameters
    ----------
    parts : Path
        The folder ``<out>/parts``.
    c : int
        Index of the chunk.
    """
    return parts / f"chunk-{c:06d}.parquet"


def intact(path: Path, rows: int) -> bool:
    """Whether the part ``path`` exists with ``rows`` rows; a damaged one is deleted, with
    a warning, so that its chunk is computed again.

    Parameters
    ----------
    path : Path
        A part file.
    rows : int
        The rows of its chunk.
    """
    import pyarrow.parquet as pq

    if not path.exists():
        return False
    try:
        found = pq.read_metadata(path).num_rows
        if found == rows:
            return True
        reason = f"{found} rows instead of {rows}"
    except Exception as exc:  # pyarrow raises ArrowInvalid, OSError and others
        reason = " ".join(str(exc).split()) or type(exc).__name__
    path.unlink(missing_ok=True)
    warnings.warn(
        f"{path}: damaged part file ({reason}); deleted, its chunk is computed again",
        RuntimeWarning,
        stacklevel=4,
    )
    return False


def read_part(path: Path):
    """The table of a part file; a damaged one is deleted and :class:`ConfigError` says to
    run the sweep again (it recomputes that chunk).

    Parameters
    ----------
    path : Path
        A part file.
    """
    import pyarrow.parquet as pq

    try:
        return pq.read_table(path)
    except Exception as exc:  # pyarrow raises ArrowInvalid, OSError and others
        path.unlink(missing_ok=True)
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise ConfigError(
            f"{path}: damaged part file ({reason}); deleted: run the same command again to "
            "compute its chunk, or use --restart"
        ) from None
