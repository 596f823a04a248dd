"""ctypes declarations read from a C header: the structs and exported functions of a
library, declared once, in C.

A hand-kept ctypes list that is one argument short still calls (x86-64 passes late
integers and pointers alike) and is silently wrong; here the header is the one owner and
Python derives from it the ``Structure`` of every struct and the ``argtypes`` and
``restype`` of every exported function (:func:`read_header`, :meth:`Declarations.bind`).

The header is written in a restricted form (what :func:`read_header` accepts, documented
at the top of ``softcurve/simulation/solvers/c/softcurve_driver.h``): block comments;
preprocessor lines ignored; ``enum { NAME = INTEGER, ... };`` declares constants;
``typedef RET (*NAME)(...);`` declares a
function-pointer type; ``typedef struct { ... } NAME;`` a struct of one ``TYPE NAME;``
field per line; ``SC_EXPORT RET NAME(TYPE NAME, ...);`` an exported function. A
``TYPE`` is ``int``, ``long``, ``long long``, ``double`` or ``void`` (``const`` ignored),
a struct or function-pointer type of the header, followed by at most one ``*``.
Anything else is refused (:class:`ValueError`), so the parser never guesses.
"""

from __future__ import annotations

import ctypes
import re
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

SCALARS = MappingProxyType(
    {
        "int": ctypes.c_int,
        "long": ctypes.c_long,
        "long long": ctypes.c_longlong,
        "double": ctypes.c_double,
    }
)
"""The C scalar types a header may use, with their ctypes."""

_COMMENT = re.compile(r"/\*.*?\*/", re.S)
_FUNCTION_TYPE = re.compile(r"typedef\s+[\w\s]+?\(\s*\*\s*(\w+)\s*\)\s*\([^;]*\)\s*;")
_STRUCT = re.compile(r"typedef\s+struct\s*\{([^}]*)\}\s*(\w+)\s*;")
_ENUM = re.compile(r"enum\s*\{([^}]*)\}\s*;")
_EXPORT = re.compile(r"SC_EXPORT\s+([\w\s\*]+?)\s*\b(\w+)\s*\(([^)]*)\)\s*;")
_DECLARATION = re.compile(r"^(const\s+)?([A-Za-z_][\w\s]*?)\s*(\*?)\s*(\w+)$")


@dataclass(frozen=True)
class Signature:
    """An exported function's ctypes types.

    Attributes
    ----------
    restype : type or None
        Its result type (None: ``void``).
    argtypes : tuple of type
        Its arguments' types, in order.
    names : tuple of str
        Its arguments' names, in order.
    """

    restype: object
    argtypes: tuple
    names: tuple


@dataclass(frozen=True)
class Declarations:
    """What a header declares.

    Attributes
    ----------
    structs : Mapping of str to type
        Each struct's ``ctypes.Structure``, by its C name.
    functions : Mapping of str to Signature
        Each exported function's signature, by its C name.
    constants : Mapping of str to int
        Each enumerator's value, by its C name.
    """

    structs: MappingProxyType
    functions: MappingProxyType
    constants: MappingProxyType

    def bind(self, library: ctypes.CDLL) -> ctypes.CDLL:
        """Set ``argtypes`` and ``restype`` of every exported function on ``library``.

        Parameters
        ----------
        library : ctypes.CDLL
            A library built from C that includes the header.

        Returns
        -------
        ctypes.CDLL
            ``library``.

        Raises
        ------
        AttributeError
            If the library lacks an exported function of the header.
        """
        for name, signature in self.functions.items():
            function = getattr(library, name)
            function.argtypes = list(signature.argtypes)
            function.restype = signature.restype
        return library


def _declared(declaration: str, structs: dict, pointers: set, where: str) -> tuple:
    """``(NAME, ctypes type of TYPE)`` of ``declaration``, ``TYPE NAME``."""
    match = _DECLARATION.match(" ".join(declaration.split()))
    if match is None:
        raise ValueError(f"{where}: cannot read {declaration!r}")
    base, star, name = " ".join(match.group(2).split()), match.group(3), match.group(4)
    if star:
        if base in structs:
            return name, ctypes.POINTER(structs[base])
        if base in SCALARS or base in pointers or base == "void":
            return name, ctypes.c_void_p
    elif base in SCALARS:
        return name, SCALARS[base]
    elif base in pointers:
        return name, ctypes.c_void_p
    raise ValueError(f"{where}: type {declaration!r} is not of the restricted form")


def _returned(text: str, structs: dict, pointers: set, where: str):
    text = " ".join(text.split())
    if text == "void":
        return None
    return _declared(text + " result", structs, pointers, where)[1]


def read_header(path) -> Declarations:
    """The declarations of a header in the restricted form (module notes).

    Parameters
    ----------
    path : str or pathlib.Path
        The header.

    Returns
    -------
    Declarations

    Raises
    ------
    ValueError
        If a struct field or an argument is not of the restricted form.
    """
    text = _COMMENT.sub(" ", Path(path).read_text(encoding="utf-8"))
    text = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))
    pointers = set(_FUNCTION_TYPE.findall(text))
    structs: dict = {}
    for body, name in _STRUCT.findall(text):
        fields = []
        for line in body.splitlines():
            line = line.strip()
            if not line:
                continue
            if not line.endswith(";") or "," in line:
                raise ValueError(f"{path}: {name}: one `TYPE NAME;` per line, got {line!r}")
            fields.append(_declared(line[:-1], structs, pointers, f"{path}: {name}"))
        structs[name] = type(name, (ctypes.Structure,), {"_fields_": fields})
    functions = {}
    for result, name, arguments in _EXPORT.findall(text):
        where = f"{path}: {name}"
        parameters = [a.strip() for a in arguments.split(",")]
        if parameters == ["void"]:
            parameters = []
        declared = [_declared(p, structs, pointers, where) for p in parameters]
        functions[name] = Signature(
            _returned(result, structs, pointers, where),
            tuple(t for _, t in declared),
            tuple(n for n, _ in declared),
        )
    constants = {}
    for body in _ENUM.findall(text):
        for item in filter(None, (i.strip() for i in body.split(","))):
            name, equals, value = (part.strip() for part in item.partition("="))
            if not equals or not value.lstrip("-").isdigit():
                raise ValueError(f"{path}: enumerators need `NAME = INTEGER`, got {item!r}")
            constants[name] = int(value)
    return Declarations(*(MappingProxyType(d) for d in (structs, functions, constants)))
