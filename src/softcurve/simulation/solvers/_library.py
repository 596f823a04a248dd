"""The build of softcurve's CVODES driver: its C files (package data), the ctypes
declarations read from its header, the CasADi versions it was verified with, and its
library, built and loaded once per process (:func:`library`).

The C is in ``softcurve/simulation/solvers/c``: ``softcurve_driver.h`` declares what
Python calls (the structs ``sc_function`` and ``sc_options`` and the exported functions,
in the restricted form of ``softcurve.compiled._declarations``), ``sundials2.h`` the
SUNDIALS 2.x of CasADi's private CVODES plugin, which ships no headers.
``softcurve.simulation.solvers._driver`` calls the library.
"""

from __future__ import annotations

import os
import re
import threading
from pathlib import Path

import casadi as ca

from softcurve.compiled import compile_files, load_library, read_header

PLUGIN = "libcasadi_integrator_cvodes.so"
"""CasADi's CVODES plugin, which holds SUNDIALS CVODES (the 2.x interface: ``CVSpgmr``)."""

C_FOLDER = Path(__file__).resolve().parent / "c"
"""The driver's C files (package data): every ``.c`` there is compiled into its library."""

HEADER = C_FOLDER / "softcurve_driver.h"
"""The header that declares the driver's structs and exported functions."""

DECLARATIONS = read_header(HEADER)
"""The ctypes declarations of :data:`HEADER`
(``softcurve.compiled._declarations.Declarations``)."""

ProblemStruct = DECLARATIONS.structs["sc_function"]
"""The header's ``sc_function``: a model described to the driver."""

Options = DECLARATIONS.structs["sc_options"]
"""The header's ``sc_options``: the settings of a call
(:func:`softcurve.simulation.solvers.driver_options`)."""

CASADI_VERIFIED = ">=3.8,<3.9"
"""The CasADi versions whose private CVODES plugin the driver was verified with (the
requirement of ``pyproject.toml``, which a test checks equal): the driver declares the
plugin's SUNDIALS by hand (``sundials2.h``) and refuses to load with another CasADi
(:func:`version_verified`)."""


def _release(version: str) -> tuple[int, ...]:
    """The numeric release of a version string: ``"3.8.2"`` -> ``(3, 8, 2)``."""
    numbers = []
    for part in version.split("."):
        digits = re.match(r"\d*", part).group()
        if digits:
            numbers.append(int(digits))
        if not digits or digits != part:  # "3.8.2rc1" -> (3, 8, 2)
            break
    return tuple(numbers)


def version_verified(version: str, requirement: str = CASADI_VERIFIED) -> bool:
    """Whether the CasADi ``version`` meets ``requirement`` (comma-separated ``>=``,
    ``>``, ``<=``, ``<``, ``==``, ``!=`` clauses on release numbers).

    Parameters
    ----------
    version : str
        A CasADi version, e.g. ``casadi.__version__``.
    requirement : str
        The versions allowed (default :data:`CASADI_VERIFIED`).

    Returns
    -------
    bool

    Examples
    --------
    >>> version_verified("3.8.2"), version_verified("3.9.0"), version_verified("3.7.1")
    (True, False, False)
    """
    have = _release(version)
    compare = {
        ">=": lambda a, b: a >= b, "<=": lambda a, b: a <= b, "==": lambda a, b: a == b,
        "!=": lambda a, b: a != b, ">": lambda a, b: a > b, "<": lambda a, b: a < b,
    }  # fmt: skip
    for clause in requirement.split(","):
        clause = clause.strip()
        operator = clause[:2] if clause[:2] in compare else clause[:1]
        wanted = _release(clause[len(operator) :].strip())
        width = max(len(have), len(wanted))
        padded = [v + (0,) * (width - len(v)) for v in (have, wanted)]
        if not compare[operator](*padded):
            return False
    return True


_LIBRARIES: dict = {}  # the driver's library by its defines (or why not, a str), per process
_LOCK = threading.Lock()


def library(defines: tuple[str, ...] = ()):
    """The driver's library built from :data:`C_FOLDER` with the macros ``defines``, its
    functions declared from :data:`HEADER`; built and loaded once per process and
    ``defines``; None where it cannot be: no C compiler, a CasADi outside
    :data:`CASADI_VERIFIED` or whose SUNDIALS has another interface, or
    ``SOFTCURVE_NATIVE_CVODES=0``.

    Parameters
    ----------
    defines : tuple of str
        Macros defined for the build (tests build variants; the product defines none).

    Returns
    -------
    ctypes.CDLL or None
    """
    loaded = _loaded(defines)
    return None if isinstance(loaded, str) else loaded


def unavailable(defines: tuple[str, ...] = ()) -> str | None:
    """Why :func:`library` is None, in a phrase (None where it loads).

    Parameters
    ----------
    defines : tuple of str
        Macros defined for the build, as :func:`library` takes them.
    """
    loaded = _loaded(defines)
    return loaded if isinstance(loaded, str) else None


SWITCHED_OFF = "SOFTCURVE_NATIVE_CVODES=0 is set"
"""Why the driver is unused under ``SOFTCURVE_NATIVE_CVODES=0`` (the user's choice)."""


def _loaded(defines: tuple[str, ...]):
    """The library of ``defines`` or why not (a str), loaded once per process."""
    with _LOCK:
        if defines not in _LIBRARIES:
            _LIBRARIES[defines] = _load(defines)
        return _LIBRARIES[defines]


def _load(defines: tuple[str, ...]):
    """The loaded library, or why it cannot be loaded (a str)."""
    if os.environ.get("SOFTCURVE_NATIVE_CVODES", "1") in ("0", ""):
        return SWITCHED_OFF
    if not version_verified(ca.__version__):
        return f"CasADi {ca.__version__} is outside the verified {CASADI_VERIFIED}"
    directory = Path(ca.__file__).parent
    try:
        if not hasattr(load_library(directory / PLUGIN), "CVSpgmr"):  # SUNDIALS >= 3: other API
            return f"CasADi's {PLUGIN} lacks the SUNDIALS 2.x interface (CVSpgmr)"
    except OSError as exc:
        return f"CasADi's {PLUGIN} cannot be loaded ({exc})"
    link = (f"-L{directory}", f"-l:{PLUGIN}", f"-Wl,-rpath,{directory}", "-pthread")
    loaded = compile_files("cvodes_driver", C_FOLDER, link, defines)
    if loaded is None:
        return "the driver's C source did not compile (no C compiler, or the build failed)"
    return DECLARATIONS.bind(loaded)
