"""Deprecated path of :mod:`softcurve.analysis.equilibrium_results`: each name is the same
object, given after a :class:`DeprecationWarning` naming the new module."""

from softcurve.analysis import equilibrium_results
from softcurve.base.deprecation import moved_module

__getattr__ = moved_module(__name__, equilibrium_results)
