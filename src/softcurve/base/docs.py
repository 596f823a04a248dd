"""One text for each parameter that many functions take: its type, meaning, unit and shape.

The units of the generalized coordinates and forces, say, are then written once, and a
docstring cannot drift from the others. A docstring names a shared parameter by a line
``%(name)s`` in its Parameters section; :func:`shared_parameters` replaces that line by
the numpy-style entry, indented like the marker::

    @shared_parameters
    def gravity_force(self, q):
        '''``dV_g/dq``, shape (n,).

        Parameters
        ----------
        %(q)s
        '''

Tools that read ``__doc__`` (``help()``, numpydoc, Sphinx autodoc, the documentation
test) see the complete entry.
"""

from __future__ import annotations

import re
import types

PARAMETERS: dict[str, tuple[str, str]] = {
    "q": (
        "array_like, shape (n,)",
        "Generalized coordinates: ``(l, kx, ky)`` of each constant-curvature segment [m, "
        "1/m, 1/m], the chosen strains of each constant-strain segment [1/m or -].",
    ),
    "qd": (
        "array_like, shape (n,)",
        "Their rates (e.g. [m/s, 1/(m s), 1/(m s)]).",
    ),
    "lam": (
        "array_like, shape (n_creep,), optional",
        "Creep states, three per segment with creep (default zero).",
    ),
    "tau": (
        "array_like, shape (n,)",
        "Generalized forces [N, N m^2, N m^2] per segment (power is ``tau . qd``).",
    ),
    "model": ("Model", "The compiled model."),
    "actuator": ("Actuator or None", "The actuator whose inputs ``u`` enter (None: none)."),
    "q_i": (
        "casadi.SX, shape (3,)",
        "The segment's coordinates ``(l, kx, ky)`` [m, 1/m, 1/m].",
    ),
    "s": (
        "casadi.SX or float",
        "Material coordinate along the segment, in [0, 1] (dimensionless).",
    ),
    "threads": ("int", "Threads of the mapped evaluation."),
    "steps": ("ChainSteps", "The steps of the algorithms over the chain."),
    "terms": (
        "list of SegmentTerms",
        "Each element's terms and steps (``chain.segment_motions``).",
    ),
    "qdd": ("casadi.SX, shape (n,)", "Accelerations."),
    "base_acceleration": (
        "casadi.SX, shape (6,)",
        "``(alpha, a)`` of the base frame; ``(0, -g)`` in base coordinates for gravity.",
    ),
    "parameters": (
        "ndarray, shape (B, n_p)",
        "One robot parameter vector per member (``Robot.layout``).",
    ),
}
"""Shared parameter: ``(type line, description)``."""

_MARKER = re.compile(r"^(?P<indent>[ \t]*)%\((?P<name>\w+)\)s[ \t]*$", re.MULTILINE)
_RETURNS = re.compile(r"^[ \t]*Returns\n[ \t]*-+[ \t]*$", re.MULTILINE)
_INDENT = re.compile(r"^(?P<indent>[ \t]*)\S", re.MULTILINE)
"""The indentation of a line that holds text; a docstring's body is indented by the least
of its lines after the first (which follows the quotes), as :func:`inspect.cleandoc` reads it."""


def parameters_from(table: dict[str, tuple[str, str]], returns: tuple[str, str] | None = None):
    """A decorator like :func:`shared_parameters` that reads its entries from ``table``
    (for parameters shared within one layer, e.g. the options of the fits).

    Parameters
    ----------
    table : dict
        Parameter name -> ``(type line, description)``.
    returns : tuple of str, optional
        ``(type line, description)`` of what every function it decorates returns: their
        docstrings leave out the ``Returns`` section, and the decorator writes it as
        their last (a ValueError at import names a docstring that has one already, a
        TypeError a class decorated).
    """

    def entry(match: re.Match) -> str:
        kind, description = table[match["name"]]
        indent = match["indent"]
        return f"{indent}{match['name']} : {kind}\n{indent}    {description}"

    def returns_section(function, doc: str) -> str:
        if _RETURNS.search(doc):
            raise ValueError(
                f"{function.__qualname__}: its Returns section is written by the decorator"
            )
        kind, description = returns
        indent = min((m["indent"] for m in _INDENT.finditer(doc.partition("\n")[2])), default="")
        lines = ("Returns", "-------", kind, f"    {description}")
        return doc.rstrip() + "\n\n" + "".join(f"{indent}{line}\n" for line in lines) + indent

    def substitute(function):
        if getattr(function, "__doc__", None):
            function.__doc__ = _MARKER.sub(entry, function.__doc__)
            if returns is not None:
                function.__doc__ = returns_section(function, function.__doc__)

    def decorate(function):
        """Substitute the shared entries into ``function.__doc__``; for a class, into the
        docstrings of the class and of every function defined in it.

        Parameters
        ----------
        function : callable or type
            A function, method or class whose docstrings name shared parameters.
        """
        if returns is not None and isinstance(function, type):
            raise TypeError(f"{function.__qualname__}: a class returns nothing to document")
        substitute(function)
        if isinstance(function, type):
            for attribute in vars(function).values():
                method = getattr(attribute, "__func__", attribute)  # class and static methods
                if isinstance(method, types.FunctionType):
                    substitute(method)
        return function

    return decorate


shared_parameters = parameters_from(PARAMETERS)
"""Decorator: replace each line ``%(name)s`` of the docstring by the entry of the shared
parameter ``name`` of :data:`PARAMETERS` (a KeyError names an unknown one at import)."""
