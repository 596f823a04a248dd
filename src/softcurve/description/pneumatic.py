"""Deprecated path of :mod:`softcurve.description.bellows`: each name is the same object,
given after a :class:`DeprecationWarning` naming the new module."""

from softcurve.base.deprecation import moved_module
from softcurve.description import bellows

__getattr__ = moved_module(__name__, bellows)
