"""MATLAB files as nested tables, and the selectors that pick a column out of them.

:func:`read_mat` reads a ``.mat`` file (MATLAB v4 to v7; not v7.3, which is HDF5) with
structs as dicts, struct arrays and cell arrays as lists, and vectors as 1-D arrays.
:func:`select` resolves a selector in it (grammar below); every failure is a
:class:`SelectorError` (an :class:`~softcurve.identification.experiments.ExperimentError`)
naming the file and the selector.

Selectors
---------
``name`` then any number of ``.field`` (a struct's field) and ``[k]`` (element ``k``,
from 0, of a struct array or cell array), then optionally ``:j``: column ``j`` of a
matrix, or element ``j`` of a struct array (``"train:0"`` is ``"train[0]"``). Examples:
``"U_:1"`` (column 1 of matrix ``U_``), ``"train[2].y"`` (field ``y`` of trial 2 of the
1xK struct array ``train``), ``"meta.rig.p:0"``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import scipy.io

from softcurve.identification.experiments._errors import ExperimentError

SELECTOR = re.compile(r"^([A-Za-z]\w*)((?:\.[A-Za-z]\w*|\[\d+\])*)(?::(\d+))?$")
STEP = re.compile(r"\.([A-Za-z]\w*)|\[(\d+)\]")


class SelectorError(ExperimentError):
    """A selector does not name a column of the table (or the file is unreadable)."""


def read_mat(path: Path) -> dict:
    """The variables of a MATLAB file by name (``__header__`` and the like dropped).

    Parameters
    ----------
    path : pathlib.Path
        The file.
    """
    try:
        table = scipy.io.loadmat(path, simplify_cells=True)
    except NotImplementedError:
        raise SelectorError(
            f"{path}: MATLAB v7.3 (HDF5) files are not supported; save with "
            "save(..., '-v7') or read it with h5py and build an Experiment"
        ) from None
    except (ValueError, TypeError, OSError, IndexError, EOFError, KeyError) as exc:
        raise SelectorError(f"{path}: not a readable MATLAB file ({exc})") from None
    return {k: v for k, v in table.items() if not k.startswith("__")}


def _kind(value) -> str:
    if isinstance(value, str):
        return f"the text {value!r}"
    if isinstance(value, dict):
        return f"a struct with fields {sorted(value)}"
    if isinstance(value, list):
        return f"a struct or cell array of {len(value)} elements"
    return f"an array of shape {np.shape(value)}"


def _element(source, key, value, k: int, done: str):
    if isinstance(value, dict) and k == 0:  # a 1x1 struct array is read as the struct
        return value
    if isinstance(value, list | tuple) or (
        isinstance(value, np.ndarray) and value.dtype == object and value.ndim == 1
    ):
        if not 0 <= k < len(value):
            raise SelectorError(
                f"{source}: {key!r}: {done!r} has {len(value)} elements, [{k}] does not exist"
            )
        return value[k]
    raise SelectorError(f"{source}: {key!r}: {done!r} is {_kind(value)}, not an array of trials")


def select(source: str, table: dict, key: str):
    """The value a selector names (see the module docstring), or :class:`SelectorError`.

    Parameters
    ----------
    source : str
        The file (or table) name, for messages.
    table : dict
        Variables by name, as :func:`read_mat` returns them.
    key : str
        The selector, e.g. ``"train[0].y"`` or ``"U_:1"``.
    """
    match = SELECTOR.match(str(key).strip())
    if not match:
        raise SelectorError(
            f"{source}: {key!r} is not a selector: write name, then .field or [k] steps, "
            "then optionally :j (e.g. 'U_:1', 'train[0].y', 'train:0')"
        )
    name, steps, column = match.groups()
    if name not in table:
        raise SelectorError(f"{source}: no variable or column {name!r}; available: {sorted(table)}")
    value, done = table[name], name
    for field, index in STEP.findall(steps):
        if field:
            if not isinstance(value, dict):
                raise SelectorError(
                    f"{source}: {key!r}: {done!r} is {_kind(value)}, it has no field {field!r}"
                )
            if field not in value:
                raise SelectorError(
                    f"{source}: {key!r}: {done!r} has no field {field!r}; fields: {sorted(value)}"
                )
            value, done = value[field], f"{done}.{field}"
        else:
            value, done = _element(source, key, value, int(index), done), f"{done}[{index}]"
    if column is None:
        return value
    j = int(column)
    if isinstance(value, dict | list):
        return _element(source, key, value, j, done)
    value = np.asarray(value)
    if value.ndim != 2:
        raise SelectorError(
            f"{source}: {key!r}: {done!r} is {_kind(value)}, not a matrix, cannot take column {j}"
        )
    if not 0 <= j < value.shape[1]:
        raise SelectorError(
            f"{source}: {key!r}: {done!r} has {value.shape[1]} columns, column {j} does not exist"
        )
    return value[:, j]


def numeric(source: str, key: str, value) -> np.ndarray:
    """A selected value as a float64 array, or :class:`SelectorError` saying what it is.

    Parameters
    ----------
    source : str
        The file, for messages.
    key : str
        The selector, for messages.
    value : object
        What :func:`select` returned.
    """
    if isinstance(value, dict | list | str):
        hint = ""
        if isinstance(value, dict | list):
            trial = re.sub(r":(\d+)$", r"[\1]", key)
            first = value if isinstance(value, dict) else (value[0] if value else {})
            field = next(iter(first), "field") if isinstance(first, dict) else "field"
            element = trial if isinstance(value, dict) else f"{trial}[0]"
            hint = f" (select a field, e.g. {element + '.' + field!r})"
        raise SelectorError(f"{source}: {key!r} is {_kind(value)}, not numbers{hint}")
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise SelectorError(f"{source}: {key!r} is {_kind(value)}, not numbers") from None


def count_elements(source: str, table: dict, key: str) -> int:
    """How many trials a struct array (or cell array) holds; 1 for a single struct.

    Parameters
    ----------
    source : str
        The file, for messages.
    table : dict
        Variables by name.
    key : str
        Selector of the struct array, e.g. ``"train"``.
    """
    value = select(source, table, key)
    if isinstance(value, dict):
        return 1
    if isinstance(value, list) or (isinstance(value, np.ndarray) and value.dtype == object):
        return len(value)
    raise SelectorError(f"{source}: {key!r} is {_kind(value)}, not a struct array of trials")
