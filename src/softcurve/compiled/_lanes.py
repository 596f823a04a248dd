"""SX functions generated as C that evaluates :data:`LANE_WIDTH` members at once.

CasADi generates scalar C: one member per call. A batch of members that run the same
code in lock-step (the fixed-step stepper's members) can instead keep every scalar of
the function as a short vector, one lane per member, and let the C compiler's vector
extensions (GCC and Clang: ``__attribute__((vector_size))``) turn each instruction into
one vector instruction. :func:`lanes_function` writes such a function from the
instruction list of a CasADi SX function, so it is generated from the same expressions
as the scalar code and computes the same arithmetic lane by lane.

Sine, cosine and hyperbolic tangent come from glibc's vector math library (libmvec,
accurate to 4 ulp) where the code is built for x86-64 with AVX2; elsewhere, and for
the other elementary functions, each lane calls the C library's scalar function. That
fixed C (the vector type and the elementary functions) is ``c/lanes_prelude.h`` beside
this module (:data:`PRELUDE`); Python writes what it computes from the expressions.
"""

from __future__ import annotations

import ctypes
import math
import platform
import re
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import casadi as ca

from softcurve.compiled._source import compile_source

LANE_WIDTH = 4
"""Members per vector. Per member, one right-hand side of the paper's robot took 2.13 us
as CasADi's C, and 2.43, 1.25, 0.90 and 1.14 us as lanes of 1, 2, 4 and 8 with the C
library's elementary functions, 0.64 us as lanes of 4 with libmvec's
(``python benchmarks/bench_lanes.py``, best of 7 alternating rounds,
on this project's AVX2 machine). Four doubles fill one AVX2 register; eight take
two and spill."""

STACK_WORK = 2048
"""Work vectors kept in local variables (on the stack, 64 KB at most), beyond which a
lanes function works in its caller's array (on the heap). Locals are faster: the RK4
period of the paper robot (963 vectors) took 14.5 us per member against 16.5 us with
the array (best of 9 alternating rounds); a robot of three segments needs
about 110 KB, more than some threads' stacks (musl's default is 128 KB)."""

C_FOLDER = Path(__file__).parent / "c"
"""The fixed C of the generators (package data): the lanes prelude, the templates that
generated sources fill in (:func:`c_template`)."""

PRELUDE = C_FOLDER / "lanes_prelude.h"
"""The C of :func:`lanes_prelude` (package data): the vector type and every elementary
function lane by lane, with glibc's AVX2 vector functions of four doubles (``sin``,
``cos``, ``tanh``; ``tanh`` since glibc 2.35), used where the source is compiled with
``__AVX2__`` on x86-64 and ``vector_math`` was asked for."""

VECTOR_MATH_LIBRARY = ("-lmvec",)
"""The link arguments of the vector math library (:data:`PRELUDE`)."""


def vector_math_available() -> bool:
    """Whether the vector math library (:data:`PRELUDE`) can link here: x86-64 Linux with
    glibc 2.35 or later
    (the first with the vector ``tanh``). The code still uses them only where compiled
    for AVX2.

    Returns
    -------
    bool
    """
    library, version = platform.libc_ver()
    if platform.machine() not in ("x86_64", "AMD64") or library != "glibc":
        return False
    return tuple(int(part) for part in version.split(".")[:2]) >= (2, 35)


_OPERATORS = {getattr(ca, name): name[3:] for name in dir(ca) if name.startswith("OP_")}
_BINARY = {"ADD": "({0}+{1})", "SUB": "({0}-{1})", "MUL": "({0}*{1})", "DIV": "({0}/{1})"}
_UNARY = {"ASSIGN": "{0}", "NEG": "(-{0})", "SQ": "({0}*{0})", "TWICE": "({0}+{0})"}
_UNARY["INV"] = "(sc_broadcast(1.0)/{0})"
_COMPARISONS = {"LT": "<", "LE": "<=", "EQ": "==", "NE": "!="}
_ELEMENTARY = {
    "EXP": "exp", "LOG": "log", "SQRT": "sqrt", "SIN": "sin", "COS": "cos", "TAN": "tan",
    "ASIN": "asin", "ACOS": "acos", "ATAN": "atan", "FLOOR": "floor", "CEIL": "ceil",
    "FABS": "fabs", "ERF": "erf", "SINH": "sinh", "COSH": "cosh", "TANH": "tanh",
    "ASINH": "asinh", "ACOSH": "acosh", "ATANH": "atanh", "LOG1P": "log1p",
    "EXPM1": "expm1",
}  # fmt: skip
_ELEMENTARY2 = {
    "POW": "pow", "CONSTPOW": "pow", "FMOD": "fmod", "COPYSIGN": "copysign",
    "FMIN": "fmin", "FMAX": "fmax", "ATAN2": "atan2", "HYPOT": "hypot",
}  # fmt: skip


def lanes_prelude(width: int = LANE_WIDTH, vector_math: bool = False) -> str:
    """The C that every lanes function needs, once per source: :data:`PRELUDE` for
    vectors of ``width`` doubles (the vector type ``sc_v`` and its mask type, broadcast,
    select, and every elementary function lane by lane, ``sc_sin``, ...).

    Parameters
    ----------
    width : int
        Lanes per vector.
    vector_math : bool
        Take glibc's vector functions where compiled for AVX2 on x86-64 (link with
        :data:`VECTOR_MATH_LIBRARY`); requires ``width == 4``.

    Returns
    -------
    str
        C declarations and inline functions.
    """
    if vector_math and width != 4:
        raise ValueError(f"vector_math needs width 4, got {width}")
    defines = [f"#define SC_W {width}", *(["#define SC_VECTOR_MATH 1"] if vector_math else [])]
    return "\n".join(defines) + "\n" + PRELUDE.read_text(encoding="utf-8")


def c_template(name: str, defines: dict) -> str:
    """The C file ``name`` of :data:`C_FOLDER` after ``#define`` lines of ``defines`` and
    ``SC_GENERATED``: a template whose macros the generator fills in with what it computes
    (each template says which; a template compiles alone on stand-ins without them).

    Parameters
    ----------
    name : str
        The file's name, e.g. ``"stepper_period.c"``.
    defines : dict of str to object
        Macro name to its value; a list or tuple of strings is a block of statements
        (one macro over several lines).

    Returns
    -------
    str
        C source.
    """
    lines = ["#define SC_GENERATED 1"]
    for macro, value in defines.items():
        if isinstance(value, (list, tuple)):
            value = " \\\n  ".join(value)
        lines.append(f"#define {macro} {value}")
    return "\n".join(lines) + "\n" + (C_FOLDER / name).read_text(encoding="utf-8")


def _constant(value: float) -> str:
    if math.isnan(value):
        return "sc_broadcast(NAN)"
    if math.isinf(value):
        return f"sc_broadcast({'-' if value < 0 else ''}INFINITY)"
    return f"sc_broadcast({value!r})"


class _Signature(NamedTuple):
    """How a lanes function reads its inputs and writes its outputs: one array per
    input and output (``in<i>``, ``out<i>``; ``shared`` inputs as doubles), or, for a
    called function, every nonzero of its inputs in one array ``in`` and of its outputs
    in ``out`` (``offsets``: where each input's and output's nonzeros begin)."""

    shared: Sequence[bool]
    offsets: tuple[list[int], list[int]] | None = None

    def input(self, i: int, nz: int) -> str:
        if self.offsets is not None:
            return f"in[{self.offsets[0][i] + nz}]"
        return f"sc_broadcast(in{i}[{nz}])" if self.shared[i] else f"in{i}[{nz}]"

    def output(self, i: int, nz: int) -> str:
        if self.offsets is not None:
            return f"out[{self.offsets[1][i] + nz}]"
        return f"out{i}[{nz}]"


def _offsets(function: ca.Function) -> tuple[list[int], list[int]]:
    def starts(count, sparsity):
        sizes = [sparsity(i).nnz() for i in range(count)]
        return [sum(sizes[:i]) for i in range(count)]

    return (
        starts(function.n_in(), function.sparsity_in),
        starts(function.n_out(), function.sparsity_out),
    )


def _call(function: ca.Function, k: int, name: str) -> str:
    """C of call instruction ``k``: the callee's lanes function ``name`` on copies of
    the arguments' work variables (results no one uses are left in the copy)."""
    args, results = function.instruction_input(k), function.instruction_output(k)
    copy_in = " ".join(f"ci[{j}] = w[{i}];" for j, i in enumerate(args))
    copy_out = " ".join(f"w[{i}] = co[{j}];" for j, i in enumerate(results) if i >= 0)
    return (
        f"{{ sc_v ci[{max(len(args), 1)}], co[{max(len(results), 1)}]; {copy_in} "
        f"{name}(ci, co, w_call); {copy_out} }}"
    )


def _statement(function: ca.Function, k: int, signature: _Signature, calls: dict) -> str:
    """C for instruction ``k`` of ``function`` on the work variables ``w<i>``."""
    op = _OPERATORS[function.instruction_id(k)]
    args, results = function.instruction_input(k), function.instruction_output(k)
    w = [f"w[{i}]" for i in args]
    if op == "OUTPUT":
        return f"{signature.output(*results)} = {w[0]};"
    if op == "CALL":
        return _call(function, k, calls[k])
    target = f"w[{results[0]}] = "
    if op == "INPUT":
        return target + signature.input(*args) + ";"
    if op == "CONST":
        return target + _constant(function.instruction_constant(k)) + ";"
    if op in _BINARY:
        return target + _BINARY[op].format(*w) + ";"
    if op in _UNARY:
        return target + _UNARY[op].format(*w) + ";"
    if op in _ELEMENTARY:
        return target + f"sc_{_ELEMENTARY[op]}({w[0]});"
    if op in _ELEMENTARY2:
        return target + f"sc_{_ELEMENTARY2[op]}({w[0]}, {w[1]});"
    one, zero = "sc_broadcast(1.0)", "sc_broadcast(0.0)"
    if op in _COMPARISONS:
        return target + f"sc_select({w[0]} {_COMPARISONS[op]} {w[1]}, {one}, {zero});"
    if op == "NOT":
        return target + f"sc_select({w[0]} == {zero}, {one}, {zero});"
    if op in ("AND", "OR"):
        joined = " & " if op == "AND" else " | "
        mask = joined.join(f"({x} != {zero})" for x in w)
        return target + f"sc_select({mask}, {one}, {zero});"
    if op == "IF_ELSE_ZERO":
        return target + f"sc_select({w[0]} != {zero}, {w[1]}, {zero});"
    if op == "SIGN":
        positive = f"sc_select({w[0]} > {zero}, {one}, {w[0]})"
        return target + f"sc_select({w[0]} < {zero}, -{one}, {positive});"
    raise NotImplementedError(f"{function.name()}: no lanes code for CasADi's OP_{op}")


def lanes_function(function: ca.Function, name: str, shared: Sequence[bool]) -> str:
    """C of ``static void name(in0, ..., out0, ..., w)``: ``function`` on
    :data:`LANE_WIDTH` members at once (the source needs :func:`lanes_prelude` first).

    Each input is ``const sc_v*`` (one vector per entry, a lane per member) or, where
    ``shared``, ``const double*`` read by every lane; each output is ``sc_v*``; ``w``
    is the caller's work array of :func:`lanes_work` vectors, used where the function
    needs more than :data:`STACK_WORK` of them (else the work is in local variables).

    Parameters
    ----------
    function : casadi.Function
        An SX function (``expand()`` an MX one of SX parts) with dense column inputs and
        outputs.
    name : str
        The C function's name.
    shared : sequence of bool
        Per input: the same values for every member.

    Returns
    -------
    str
        The C function.

    Raises
    ------
    ValueError
        If ``function`` is not an SX function, an input or output is not a dense column,
        or ``shared`` does not have one entry per input.
    NotImplementedError
        If ``function`` has an operation without lanes code (CasADi's remainder,
        inverse error function and print instructions) or calls a function that is not
        an SX function.
    """
    if not function.is_a("SXFunction"):
        raise ValueError(f"{function.name()} must be an SX function (call expand())")
    if len(shared) != function.n_in():
        raise ValueError(f"shared needs {function.n_in()} entries, got {len(shared)}")
    for kind, count, sparsity in (
        ("input", function.n_in(), function.sparsity_in),
        ("output", function.n_out(), function.sparsity_out),
    ):
        for i in range(count):
            if not (sparsity(i).is_dense() and sparsity(i).is_column()):
                raise ValueError(f"{function.name()}: {kind} {i} must be a dense column")
    callees: dict = {}
    calls = _gather_callees(function, name, callees)
    inputs = [
        f"const double* in{i}" if is_shared else f"const sc_v* in{i}"
        for i, is_shared in enumerate(shared)
    ]
    outputs = [f"sc_v* out{i}" for i in range(function.n_out())]
    definitions = [code for _, code in callees.values()]
    main = _definition(function, name, [*inputs, *outputs], _Signature(shared), calls)
    return "\n".join([*definitions, main])


def _callees(function: ca.Function) -> dict[int, ca.Function]:
    """The function each call instruction of ``function`` calls, by instruction."""
    ids = (function.instruction_id(k) for k in range(function.n_instructions()))
    calls = [k for k, op in enumerate(ids) if op == ca.OP_CALL]
    if not calls:
        return {}
    instructions = function.instructions_sx()
    return {k: instructions[k].which_function() for k in calls}


def _gather_callees(function: ca.Function, prefix: str, callees: dict) -> dict[int, str]:
    """Add every function ``function`` calls, directly or not, to ``callees`` by name,
    each before those that call it (``name -> (C name, C definition)``; CasADi's code
    generator names a called function once per name, as here), and return the C name
    each call instruction of ``function`` calls."""
    found = _callees(function)
    for callee in found.values():
        if callee.name() in callees:
            continue
        if not callee.is_a("SXFunction"):
            raise NotImplementedError(f"{function.name()} calls {callee.name()}, not SX")
        calls = _gather_callees(callee, prefix, callees)
        c_name = f"{prefix}_call{len(callees)}"
        signature = _Signature([False] * callee.n_in(), _offsets(callee))
        parameters = ["const sc_v* in", "sc_v* out"]
        callees[callee.name()] = (
            c_name,
            _definition(callee, c_name, parameters, signature, calls),
        )
    return {k: callees[f.name()][0] for k, f in found.items()}


def _definition(function, name, parameters, signature, calls) -> str:
    body = [_statement(function, k, signature, calls) for k in range(function.n_instructions())]
    declarations = []
    if function.sz_w() <= STACK_WORK:
        body = [re.sub(r"\bw\[(\d+)\]", r"w\1", line) for line in body]
        names = ", ".join(f"w{i}" for i in range(function.sz_w()))
        declarations = ["(void)w;", f"sc_v {names};" if names else ""]
    if calls:  # the callees work beyond this function's rows of the array
        declarations.append(f"sc_v* restrict w_call = w + {function.sz_w()};")
    header = f"static void {name}({', '.join([*parameters, 'sc_v* restrict w'])}) {{"
    return "\n  ".join([header, *declarations, *body]) + "\n}\n"


def lanes_work(function: ca.Function) -> int:
    """Vectors of work array that the :func:`lanes_function` of ``function`` needs
    (its own rows, then the most any function it calls needs).

    Parameters
    ----------
    function : casadi.Function
        An SX function.

    Returns
    -------
    int
        At least 1.
    """
    called = {f.name(): f for f in _callees(function).values()}
    called = [lanes_work(callee) for callee in called.values()]
    return max(function.sz_w() + max(called, default=0), 1)


class CompiledLanes(NamedTuple):
    """A compiled lanes source: the loaded ``library`` (``ctypes.CDLL``), its ``entry``
    (a ctypes function returning int) and whether it uses the vector math library."""

    library: ctypes.CDLL
    entry: object
    vector_math: bool


def compile_lanes(stem: str, source_for, entry: str, argtypes: list) -> CompiledLanes | None:
    """A lanes source compiled and loaded: with the vector math library where
    :func:`vector_math_available` and it links, else with the C library's functions.

    Parameters
    ----------
    stem : str
        Start of the library's file name in the cache.
    source_for : callable
        ``source_for(vector_math) -> str``, the C source (with :func:`lanes_prelude` of
        that ``vector_math``).
    entry : str
        The exported function, which returns an int.
    argtypes : list
        Its ctypes argument types.

    Returns
    -------
    CompiledLanes or None
        None where no C compiler builds it or ``source_for`` raises
        ``NotImplementedError`` (an operation without lanes code).
    """
    attempts = [(True, VECTOR_MATH_LIBRARY)] if vector_math_available() else []
    for vector_math, link in [*attempts, (False, ())]:
        try:
            library = compile_source(stem, source_for(vector_math), link, (entry,))
        except NotImplementedError:
            return None
        if library is not None:
            function = getattr(library, entry)
            function.restype, function.argtypes = ctypes.c_int, argtypes
            return CompiledLanes(library, function, vector_math)
    return None
