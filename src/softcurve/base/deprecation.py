"""Old names kept for a while: a function renamed, a module moved.

Each warns :class:`DeprecationWarning` naming its replacement where it is used, and
otherwise behaves as the new name: :func:`renamed` wraps a function under its old name,
:func:`moved_module` gives the ``__getattr__`` of a module left at an old path, so that
``from old.path import Name`` returns the new module's ``Name``. Importing the old
module alone does not warn (the package's walkers and doctests import every module).
"""

from __future__ import annotations

import functools
import inspect
import warnings
from collections.abc import Callable
from types import ModuleType

CALLER = 2
"""``stacklevel`` of the warnings: the line that uses the old name."""


def renamed(function: Callable, old: str) -> Callable:
    """``function`` under its old name ``old``: the same arguments and result, after a
    :class:`DeprecationWarning` naming ``function``.

    Parameters
    ----------
    function : callable
        The function under its new name (its ``__name__``).
    old : str
        The old name; the alias's ``__name__``.
    """
    new = function.__name__

    @functools.wraps(function)
    def alias(*args, **kwargs):
        warnings.warn(
            f"{old} is deprecated, use {new} (the same arguments and result)",
            DeprecationWarning,
            stacklevel=CALLER,
        )
        return function(*args, **kwargs)

    alias.__name__ = old
    alias.__qualname__ = function.__qualname__.replace(new, old)
    doc = inspect.cleandoc(function.__doc__ or "")
    parameters = doc[doc.find("Parameters\n---") :] if "Parameters\n---" in doc else ""
    alias.__doc__ = (
        f"Deprecated name of :func:`{new}`: warns :class:`DeprecationWarning`, then "
        f"returns what :func:`{new}` returns.\n\n{parameters}"
    )
    return alias


def moved_module(old: str, new: ModuleType) -> Callable[[str], object]:
    """The module ``__getattr__`` of a module left at the old path ``old``: each public
    name is looked up in ``new``, after a :class:`DeprecationWarning` naming ``new``.

    Parameters
    ----------
    old : str
        The old dotted module path (the shim's ``__name__``).
    new : module
        The module that now holds the names.
    """

    def __getattr__(name: str) -> object:
        if name.startswith("__"):  # dunders (__all__, __test__ ...) are the shim's own
            raise AttributeError(f"module {old!r} has no attribute {name!r}")
        value = getattr(new, name)
        warnings.warn(
            f"{old} is deprecated, import {name} from {new.__name__}",
            DeprecationWarning,
            stacklevel=CALLER,
        )
        return value

    return __getattr__
