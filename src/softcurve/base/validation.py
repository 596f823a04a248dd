"""Validation of user input, shared by the parameter objects and the file readers."""

from __future__ import annotations

import numpy as np


class ParameterError(ValueError):
    """A parameter is missing, malformed or outside its allowed range.

    The message names the field, the value received and the allowed range.
    """


FLOAT_MAX = float(np.finfo(np.float64).max)
"""The largest finite float64 (about 1.8e308): a Python int beyond it has no float."""


def beyond_float(value) -> str:
    """Why ``value``, whose conversion to float overflowed (a Python int, or a sequence
    holding one, beyond :data:`FLOAT_MAX`), is refused: the reason, after the field's name.

    Parameters
    ----------
    value : object
        What the user gave.

    Examples
    --------
    >>> beyond_float(10**400)
    'must be finite (at most 1.8e+308 in magnitude), got an integer of 401 digits'
    """
    if isinstance(value, int | np.integer):
        given = f"an integer of {len(str(abs(int(value))))} digits"
    else:
        given = "an integer entry too large for a float"
    return f"must be finite (at most {FLOAT_MAX:.2g} in magnitude), got {given}"


def whole_count(name: str, value, minimum: int = 1) -> int:
    """Return ``value`` as an int of at least ``minimum``, or raise :class:`ParameterError`
    (a bool is not a count; NumPy integers are).

    Parameters
    ----------
    name : str
        The field's name, for the message.
    value : int
        The count to check.
    minimum : int
        Its smallest allowed value.
    """
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ParameterError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def random_seed(name: str, value):
    """Return ``value`` as a seed of NumPy's and SciPy's generators: an integer >= 0 (a
    bool is not one) or a :class:`numpy.random.Generator`; :class:`ParameterError`
    otherwise.

    Parameters
    ----------
    name : str
        The field's name, for the message.
    value : int or numpy.random.Generator
        The seed to check.
    """
    if isinstance(value, np.random.Generator):
        return value
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
        raise ParameterError(
            f"{name} must be an integer >= 0 (or a numpy.random.Generator), got {value!r}"
        )
    return int(value)


def real_scalar(name: str, value, *, positive: bool = False, nonzero: bool = False) -> float:
    """Return ``value`` as a finite float, or raise :class:`ParameterError`.

    Parameters
    ----------
    name : str
        The field's name, for the message.
    value : object
        What the user gave; a real number (not a bool or string) passes.
    positive : bool
        Require ``value > 0``.
    nonzero : bool
        Require ``value != 0``.

    Examples
    --------
    >>> real_scalar("mass", 0.05, positive=True)
    0.05
    >>> real_scalar("mass", -1, positive=True)
    Traceback (most recent call last):
    ...
    softcurve.base.validation.ParameterError: mass must be > 0, got -1.0
    """
    if isinstance(value, bool | str | bytes) or not np.isscalar(value) or not np.isrealobj(value):
        raise ParameterError(f"{name} must be a real number, got {value!r}")
    try:
        x = float(value)
    except OverflowError:
        raise ParameterError(f"{name} {beyond_float(value)}") from None
    if not np.isfinite(x):
        raise ParameterError(f"{name} must be finite, got {x!r}")
    if positive and not x > 0:
        raise ParameterError(f"{name} must be > 0, got {x!r}")
    if nonzero and x == 0:
        raise ParameterError(f"{name} must be nonzero, got {x!r}")
    return x


def float_array(name: str, value, expected: str) -> np.ndarray:
    """``value`` as a new float64 array of any shape, or :class:`ParameterError` (for
    what is not numbers, and for a Python int beyond the float range).

    Parameters
    ----------
    name : str
        The field's name, for the message.
    value : array_like, any shape
        What the user gave, in any unit.
    expected : str
        What the field must be, for the message (e.g. "a real array of shape (3,)").
    """
    try:
        return np.array(value, dtype=np.float64)
    except OverflowError:
        raise ParameterError(f"{name} {beyond_float(value)}") from None
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be {expected}: {exc}") from None


def real_array(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """Return ``value`` as a read-only finite float64 array of ``shape``.

    Parameters
    ----------
    name : str
        The field's name, for the message.
    value : array_like, shape ``shape``
        What the user gave, in any unit.
    shape : tuple of int
        The required shape.
    """
    a = float_array(name, value, f"a real array of shape {shape}")
    if a.shape != shape:
        raise ParameterError(f"{name} must have shape {shape}, got {a.shape}")
    if not np.isfinite(a).all():
        raise ParameterError(f"{name} must be finite, got {a.tolist()}")
    a.setflags(write=False)
    return a


def positive_definite(name: str, value, size: int) -> np.ndarray:
    """A symmetric positive-definite ``size x size`` matrix; a vector means a diagonal.

    Parameters
    ----------
    name : str
        The field's name, for the message.
    value : array_like, shape (size, size) or (size,)
        The matrix, or its diagonal.
    size : int
        Number of rows and columns.
    """
    if not np.isscalar(value) and np.shape(value) == (size,):
        value = np.diag(real_array(name, value, (size,)))
    m = real_array(name, value, (size, size))
    if not np.allclose(m, m.T, rtol=1e-12, atol=0.0):
        raise ParameterError(f"{name} must be symmetric, got {m.tolist()}")
    eigenvalues = np.linalg.eigvalsh(m)
    if not eigenvalues.min() > 0:
        raise ParameterError(
            f"{name} must be positive definite (all eigenvalues > 0), "
            f"got eigenvalues {eigenvalues.tolist()}"
        )
    return m
