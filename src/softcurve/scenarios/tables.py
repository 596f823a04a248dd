"""Typed access to the tables of a TOML file, for scenario and sweep files: every key
read is type-checked, unknown keys are refused, and every error names the file and the
key path (:class:`ConfigError`)."""

from __future__ import annotations

import difflib
import sys

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.files import InputFileError, read_input
from softcurve.base.validation import ParameterError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


CLOSE = 0.75
"""Similarity (difflib ratio, 0 to 1) above which an unknown key is taken for a typo of a
known one: one or two letters swapped, missing or extra in a word of ten."""


toml_parameters = parameters_from(
    {
        "path": ("str or Path", "The TOML file."),
        "data": ("dict", "The parsed TOML."),
        "file": ("str", "Its name, for messages."),
    }
)
"""Documents the parameters the readers of TOML files share."""


class ConfigError(ParameterError):
    """A configuration file is malformed; the message names the file and the key."""


def read_toml(path) -> tuple[dict, str]:
    """``(parsed TOML, file name)`` of ``path``; :class:`ConfigError` if it cannot be read
    or parsed.

    Parameters
    ----------
    path : str or Path
        The TOML file.
    """
    file = str(path)
    try:
        text = read_input(path)
    except InputFileError as exc:
        raise ConfigError(str(exc)) from None
    try:
        return tomllib.loads(text), file
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{file}: not valid TOML: {exc}") from None


class Reader:
    """Typed access to one TOML table, recording which keys were used.

    Parameters
    ----------
    file : str
        The file's name, for messages.
    path : str
        The table's key path, e.g. ``"simulation"``.
    table : dict
        The table as TOML gives it.
    """

    def __init__(self, file: str, path: str, table):
        self.file, self.path = file, path
        if not isinstance(table, dict):
            self.fail("", f"must be a table, got {_kind(table)}")
        self.table = table
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def fail(self, name: str, reason: str):
        where = self.key(name) if name else self.path or "(top level)"
        raise ConfigError(f"{self.file}: {where}: {reason}")

    def has(self, name: str) -> bool:
        return name in self.table

    def get(self, name, kind, default=None, *, required=False):
        self.used.add(name)
        if name not in self.table:
            if required:
                typo = difflib.get_close_matches(name, [str(k) for k in self.table], 1, CLOSE)
                if typo:  # rest_lenght for rest_length: name the key that is there
                    self.fail(typo[0], f"unknown key; did you mean {name!r}? ({name} is required)")
                self.fail(name, "is required")
            return default
        value = self.table[name]
        checker = {
            "number": _number,
            "string": _string,
            "strings": _strings,
            "bool": _bool,
            "vector": _vector,
            "integer": _integer,
            "table": _table,
            "tables": _tables,
        }[kind]
        ok, result = checker(value)
        if not ok:
            self.fail(name, f"must be {result}, got {_kind(value)} {value!r}")
        return result

    def positive(self, name, default=None, *, required=False):
        value = self.get(name, "number", default, required=required)
        if value is not None and not value > 0:
            self.fail(name, f"must be > 0, got {value!r}")
        return value

    def vector(self, name, length=None, default=None):
        value = self.get(name, "vector", default)
        if value is not None and length is not None and len(value) not in _as_tuple(length):
            self.fail(
                name,
                f"must have {' or '.join(map(str, _as_tuple(length)))} entries, got {len(value)}",
            )
        return value

    def sub(self, name) -> Reader:
        self.used.add(name)
        return Reader(self.file, self.key(name), self.table[name])

    def done(self) -> None:
        unknown = sorted(set(self.table) - self.used)
        if unknown:
            known = ", ".join(sorted(self.used)) or "none"
            close = difflib.get_close_matches(str(unknown[0]), sorted(self.used), 1, CLOSE)
            hint = f"did you mean {close[0]!r}? " if close else ""
            self.fail(unknown[0], f"unknown key; {hint}(allowed here: {known})")


def _as_tuple(x):
    return x if isinstance(x, tuple) else (x,)


def _kind(value) -> str:
    return {
        bool: "a boolean",
        str: "a string",
        int: "an integer",
        float: "a number",
        list: "an array",
        dict: "a table",
    }.get(type(value), type(value).__name__)


def _number(v):
    if isinstance(v, int | float) and not isinstance(v, bool):
        if np.isfinite(v):
            return True, float(v)
    return False, "a finite number"


def _integer(v):
    return (True, v) if isinstance(v, int) and not isinstance(v, bool) else (False, "an integer")


def _string(v):
    return (True, v) if isinstance(v, str) else (False, "a string")


def _strings(v):
    if isinstance(v, list) and v and all(isinstance(x, str) for x in v):
        return True, tuple(v)
    return False, "a non-empty array of strings"


def _bool(v):
    return (True, v) if isinstance(v, bool) else (False, "true or false")


def _vector(v):
    if isinstance(v, list) and v and all(_number(x)[0] for x in v):
        return True, tuple(float(x) for x in v)
    if isinstance(v, list) and v and all(isinstance(r, list) for r in v):
        rows = [_vector(r) for r in v]
        if all(ok for ok, _ in rows) and len({len(r) for _, r in rows}) == 1:
            return True, tuple(r for _, r in rows)
    return False, "a non-empty array of finite numbers (or of equal rows)"


def _table(v):
    return (True, v) if isinstance(v, dict) else (False, "a table")


def _tables(v):
    ok = isinstance(v, list) and v and all(isinstance(x, dict) for x in v)
    return (True, v) if ok else (False, "an array of tables ([[...]])")
