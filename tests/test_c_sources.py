"""The C shipped as package data: every file compiles as strict C99 with every warning an
error, the ctypes declarations read from the driver's header match the library built
from it, the wheel's package data covers every file, a changed file changes the cache
key, and the CasADi of this environment is one the driver was verified with."""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess
import sys
from pathlib import Path

import casadi as ca
import pytest

import softcurve
from softcurve.compiled._declarations import read_header
from softcurve.compiled._lanes import LANE_WIDTH, lanes_function, lanes_prelude
from softcurve.compiled._source import compile_files
from softcurve.simulation.solvers import _driver as driver_library

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PACKAGE = Path(softcurve.__file__).parent  # the package imported: installed or the source's
SOURCE = Path(__file__).resolve().parents[1]  # the checkout the tests come with
PYPROJECT = SOURCE / "pyproject.toml"
C_FILES = sorted(p for p in PACKAGE.rglob("*") if p.suffix in (".c", ".h"))
SOURCE_C_FILES = sorted(
    p.relative_to(SOURCE / "src" / "softcurve")
    for p in (SOURCE / "src" / "softcurve").rglob("*")
    if p.suffix in (".c", ".h")
)
STRICT = ("-std=c99", "-Wall", "-Wextra", "-Werror")


def _gcc() -> str:
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("no gcc here: the shipped C files are not compiled")
    return gcc


def test_the_package_ships_the_driver_and_its_headers():
    names = {p.name for p in C_FILES}
    assert {"softcurve_driver.h", "sundials2.h", "driver.c", "groups.c"} <= names


@pytest.mark.parametrize("path", C_FILES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_every_shipped_c_file_compiles_as_strict_c99(path, tmp_path):
    """Headers too, as C (``-x c``): each one must stand alone."""
    command = [_gcc(), *STRICT, "-x", "c", "-c", str(path), "-o", str(tmp_path / "out.o")]
    result = subprocess.run(command, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_every_exported_definition_is_declared_in_the_header():
    """Python reads the header only: an entry defined in a C file but not declared there
    would be called undeclared."""
    declared = set(driver_library.DECLARATIONS.functions)
    defined = set()
    for path in driver_library.C_FOLDER.glob("*.c"):
        defined |= set(re.findall(r"^SC_EXPORT\s+[\w\s*]+?\b(\w+)\(", path.read_text(), re.M))
    assert defined == declared


def test_the_declarations_match_the_library_built():
    """Every function of the header is in the library (binding it would raise otherwise)
    and every struct has the library's size, by its ``softcurve_sizeof_`` export."""
    library = driver_library.library()
    if library is None:
        pytest.skip("softcurve's CVODES driver is not available here")
    for name, struct in driver_library.DECLARATIONS.structs.items():
        assert getattr(library, f"softcurve_sizeof_{name}")() == ctypes.sizeof(struct), name
    for name, signature in driver_library.DECLARATIONS.functions.items():
        function = getattr(library, name)
        assert function.argtypes == list(signature.argtypes), name
        assert function.restype == signature.restype, name
    assert driver_library.Options(rtol=1e-6).rtol == 1e-6  # a field by name, not position


def test_the_options_struct_carries_every_setting_the_driver_reads():
    """softcurve_integrate and softcurve_sensitivities take their settings from one
    struct."""
    sensitivities = driver_library.DECLARATIONS.functions["softcurve_sensitivities"].names
    integrate = driver_library.DECLARATIONS.functions["softcurve_integrate"].names
    fields = {name for name, _ in driver_library.Options._fields_}
    assert {"rtol", "atol", "max_steps", "max_order", "settled_ratio", "radau"} <= fields
    assert not fields & (set(integrate) | set(sensitivities))
    assert "options" in integrate and "options" in sensitivities


@pytest.mark.parametrize(
    "text",
    [
        "typedef struct {\n    int a, b;\n} s;",  # two fields on a line
        "typedef struct {\n    unsigned a;\n} s;",  # a type outside the form
        "SC_EXPORT int f(double **x);",  # two stars
        "enum { A };",  # an enumerator without its value
    ],
)
def test_the_header_parser_refuses_what_is_not_of_its_form(text, tmp_path):
    header = tmp_path / "h.h"
    header.write_text(text)
    with pytest.raises(ValueError):
        read_header(header)


def test_the_header_parser_reads_structs_pointers_and_functions(tmp_path):
    header = tmp_path / "h.h"
    header.write_text(
        "/* a comment; int ignored(int); */\n#define X 1\n"
        "typedef int (*fn)(const double *x);\n"
        "typedef struct {\n    fn f;\n    long long n; /* n */\n    const double *x;\n} s;\n"
        "enum { ONE = 1, MINUS = -2 };\n"
        "SC_EXPORT void g(const s *p, fn h, int k,\n            double t);\n"
        "SC_EXPORT long size(void);\n"
    )
    declarations = read_header(header)
    s = declarations.structs["s"]
    assert [name for name, _ in s._fields_] == ["f", "n", "x"]
    assert ctypes.sizeof(s) == 3 * 8
    g = declarations.functions["g"]
    assert g.restype is None and g.names == ("p", "h", "k", "t")
    assert g.argtypes == (ctypes.POINTER(s), ctypes.c_void_p, ctypes.c_int, ctypes.c_double)
    assert declarations.functions["size"].argtypes == ()
    assert dict(declarations.constants) == {"ONE": 1, "MINUS": -2}


def test_a_changed_c_file_changes_the_library(tmp_path, monkeypatch):
    """The cache key holds every file of the folder: after an edit of a header the
    library is built again, not loaded from the cache."""
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "cache"))
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    folder = tmp_path / "c"
    folder.mkdir()
    (folder / "value.c").write_text(
        '#include "value.h"\n__attribute__((visibility("default"))) int value(void) '
        "{ return VALUE; }\n"
    )
    values = []
    for value in (1, 2, 1):
        (folder / "value.h").write_text(f"#define VALUE {value}\n")
        values.append(compile_files("test_value", folder).value())
    assert values == [1, 2, 1]


def _casadi_requirement() -> str:
    dependencies = tomllib.loads(PYPROJECT.read_text())["project"]["dependencies"]
    (casadi,) = [d for d in dependencies if re.match(r"casadi\b", d)]
    return casadi.removeprefix("casadi").replace(" ", "")


def test_the_runtime_pin_of_casadi_is_pyprojects():
    assert _casadi_requirement() == driver_library.CASADI_VERIFIED


def test_the_installed_casadi_is_one_the_driver_was_verified_with():
    """Fails where the environment holds a CasADi outside the pin: the driver then
    refuses to load (and its tests would all skip)."""
    assert driver_library.version_verified(ca.__version__), (
        ca.__version__,
        driver_library.CASADI_VERIFIED,
    )


@pytest.mark.parametrize(
    ("version", "verified"),
    [("3.8.0", True), ("3.8.2", True), ("3.8.10", True), ("3.9.0", False), ("3.7.2", False),
     ("4.0", False), ("3.8.2rc1", True), ("3.8", True)],
)  # fmt: skip
def test_the_pin_reads_release_numbers(version, verified):
    assert driver_library.version_verified(version) is verified


def test_package_data_covers_every_c_file():
    """A non-editable install ships what pyproject's package-data names: every C file of
    the source."""
    patterns = tomllib.loads(PYPROJECT.read_text())["tool"]["setuptools"]["package-data"]
    source = SOURCE / "src" / "softcurve"
    covered = {p.relative_to(source) for pattern in patterns["softcurve"]
               for p in source.glob(pattern)}  # fmt: skip
    assert SOURCE_C_FILES and set(SOURCE_C_FILES) <= covered


def test_the_package_imported_has_every_c_file_of_the_source():
    """What the install put beside the imported package (a wheel's, in CI) holds every C
    file of the source: the driver builds from the files shipped."""
    missing = [str(p) for p in SOURCE_C_FILES if not (PACKAGE / p).is_file()]
    assert not missing, missing


def test_the_lanes_prelude_has_every_function_the_lanes_code_calls(tmp_path):
    """A lanes function of every elementary operation compiles on the shipped prelude:
    Python names the functions (CasADi's operations), the prelude defines them."""
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    unary = ["exp", "log", "sqrt", "sin", "cos", "tan", "asin", "acos", "atan", "floor",
             "ceil", "fabs", "erf", "sinh", "cosh", "tanh", "asinh", "acosh", "atanh",
             "log1p", "expm1"]  # fmt: skip
    binary = ["fmod", "copysign", "fmin", "fmax", "atan2", "hypot"]
    outputs = [getattr(ca, name)(x) for name in unary if hasattr(ca, name)]
    outputs += [getattr(ca, name)(x, y) for name in binary if hasattr(ca, name)]
    outputs += [x**y, x**2.5]
    function = ca.Function("every", [x, y], [ca.vertcat(*outputs)])
    for vector_math in (False, True):
        source = tmp_path / "every.c"
        source.write_text(
            lanes_prelude(LANE_WIDTH, vector_math) + lanes_function(function, "f", (False, True))
        )
        command = [_gcc(), *STRICT, "-Wno-unused-function", "-c", str(source), "-o",
                   str(tmp_path / "every.o")]  # fmt: skip
        result = subprocess.run(command, capture_output=True, text=True)
        assert result.returncode == 0, result.stderr
