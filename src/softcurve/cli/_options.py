"""The checks of the commands' options, one per kind of option, all run before any work.

Every error is a :class:`~softcurve.ParameterError` that names the option as the user
typed it (exit code 2); the rules themselves are the library's (a seed is what
:func:`~softcurve.base.validation.random_seed` accepts, a figure's suffix what
:func:`~softcurve.figures.drawing.figure_format` accepts), so the command line and the
Python API refuse the same values.
"""

from __future__ import annotations

from pathlib import Path

from softcurve.base.docs import parameters_from
from softcurve.base.files import writable_file
from softcurve.base.validation import ParameterError, random_seed, whole_count


def as_option(option: str, check, *args):
    """``check(*args)``, its :class:`~softcurve.ParameterError` prefixed with ``option``.

    Parameters
    ----------
    option : str
        The option, e.g. ``"--inputs"``.
    check : callable
        A check of the library that raises :class:`~softcurve.ParameterError`.
    *args
        Its arguments.
    """
    try:
        return check(*args)
    except ParameterError as exc:
        raise ParameterError(f"{option}: {exc}") from None


def figure_file(path, option: str) -> Path:
    """A figure to be written: a format Matplotlib writes (from the suffix) and a
    folder where files can be written.

    Parameters
    ----------
    path : str or Path
        The file.
    option : str
        The option that gave it, e.g. ``"--plot"``.
    """
    from softcurve.figures.drawing import figure_format

    figure_format(path, f"{option} {path}")
    return writable_file(path, option)


_number_parameters = parameters_from(
    {"value": ("int", "As parsed."), "option": ("str", "The option.")}
)


def _number(option: str, check, value, *args) -> int:
    """``check(name, value, *args)`` of the library, the name the option's without its
    dashes, its error prefixed with ``option``."""
    return as_option(option, check, option.lstrip("-"), value, *args)


@_number_parameters
def seed(value, option: str = "--seed") -> int:
    """A seed of the random starts: an integer >= 0.

    Parameters
    ----------
    %(value)s
    %(option)s
    """
    return _number(option, random_seed, value)


@_number_parameters
def count(value, option: str, minimum: int = 1) -> int:
    """A number of things (starts, workers): an integer >= ``minimum``.

    Parameters
    ----------
    %(value)s
    %(option)s
    minimum : int
        Its smallest allowed value.
    """
    return _number(option, whole_count, value, minimum)


def _installed(module: str) -> bool:
    """Whether ``module`` can be imported (found, not imported: cheap)."""
    import importlib.util

    return importlib.util.find_spec(module) is not None


def viewer(option: str = "--html") -> None:
    """An option that writes the 3-D viewer: Plotly, of the extra ``viewer``, is there
    (else the run would fail at its end, after the work).

    Parameters
    ----------
    option : str
        The option.
    """
    if not _installed("plotly"):
        raise ParameterError(
            f"{option} needs Plotly, of the extra viewer: pip install 'softcurve[viewer]' "
            "(or leave out the option)"
        )
