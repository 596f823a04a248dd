"""The errors of experiment data: :class:`ExperimentError` and :class:`UnitError`."""

from __future__ import annotations

from softcurve.base.validation import ParameterError


class ExperimentError(ParameterError):
    """An experiment file or array is malformed (missing column, bad time, NaN, unknown
    unit...); the message names the file or experiment and the field."""


class ExperimentFileNotFound(ExperimentError, FileNotFoundError):
    """An experiment file does not exist (also a :class:`FileNotFoundError`)."""


class UnitError(ExperimentError):
    """A unit is unknown, or not the one a map expects."""
