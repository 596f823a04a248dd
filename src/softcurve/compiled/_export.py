"""Standalone C for embedded controllers: forward and inverse dynamics, ``N(q)``, ``H(q)``.

A model with an environment exports its contact too: forward and inverse dynamics
include the contact force (with damping and friction) and ``N(q)`` the gradient of the
penalty energy; the obstacles and the law are constants of the code.

``H(q)`` is the input matrix of an :class:`~softcurve.description.actuator.Actuator`
(``tau = H(q) u``: pressures, tensions), exported as ``<prefix>_input_matrix``.

:func:`export_c` writes ``<prefix>.c`` and ``<prefix>.h`` (CasADi's code generator:
plain C99, no dependency but ``libm``) and a test program ``test_<prefix>.c`` that calls
every function on one sample state, prints the results and compares them with the
values the Python model gave at export time (exit code 0 when all agree to
``1e-12`` relative). With ``embed_parameters=True`` (default) the robot's numbers are
compiled in; otherwise every function takes the parameter vector ``p``
(``Robot.parameter_vector()``) as its last input.

Every function uses CasADi's calling convention::

    int NAME(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem);
    int NAME_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w);

with dense column-major inputs and outputs (vectors are plain arrays; ``H`` is ``n x m``
column-major). ``test_<prefix>.c`` shows a complete call.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from softcurve.base.files import atomic_write
from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError
from softcurve.description.actuator import Actuator
from softcurve.description.elements import Segment
from softcurve.symbolic.contact import contact_statics
from softcurve.symbolic.functions import common_subexpressions

_TOLERANCE = 1e-12

MAX_PREFIX = 255 - len("test_.c") - len(".") - len(".pid1234567@") - 64 - len(".01234567.c")
"""Longest ``prefix`` [characters] (160): the longest file :func:`export_c` writes,
``test_<prefix>.c``, is first written under a temporary name
(:func:`softcurve.base.files.atomic_write`: ``.<name>.pid<pid>@<host>.<8 hex>.c``, a pid
of up to 7 digits and a host name of up to 64 characters, POSIX's ``HOST_NAME_MAX``),
and a file name has at most 255 bytes on Linux's, macOS's and Windows's file systems
(measured: a prefix of 240 characters fails there, one of 300 in CasADi's own writer)."""


@dataclass(frozen=True)
class ExportedC(Result):
    """What :func:`export_c` wrote.

    Attributes
    ----------
    status : Status
        SUCCESS (a failure raises instead).
    message : str
        What was written where.
    source, header, test : Path
        ``<prefix>.c``, ``<prefix>.h`` and ``test_<prefix>.c``.
    functions : tuple of str
        C names of the exported functions.
    sample_inputs : dict
        The inputs the test program uses, by function name (lists of arrays).
    compile_command : list of str
        A command (run in the output directory) that builds the test program.
    """

    status: Status
    message: str
    source: Path
    header: Path
    test: Path
    functions: tuple[str, ...]
    sample_inputs: dict
    compile_command: list[str]


def _functions(model, actuator: Actuator | None, prefix: str, embed: bool):
    e = model.expressions
    specs = {
        "forward_dynamics": (
            [e.q, e.qd, e.tau, e.lam],
            ["q", "qd", "tau", "lam"],
            e.forward_dynamics,
        ),
        "inverse_dynamics": (
            [e.q, e.qd, e.qdd, e.lam],
            ["q", "qd", "qdd", "lam"],
            e.inverse_dynamics,
        ),
        "potential_force": ([e.q], ["q"], e.gravity_force + e.elastic_force),
    }
    contact = contact_statics(e)  # with an environment: the penalty's gradient too
    if contact is not None:
        specs["potential_force"] = ([e.q], ["q"], e.gravity_force + e.elastic_force - contact[0])
    if actuator is not None:
        actuator.check_robot(model.robot)
        specs["input_matrix"] = ([e.q], ["q"], actuator.input_matrix_symbolic(e.q))
    functions = {}
    for name, (inputs, names, output) in specs.items():
        output = ca.densify(ca.SX(output))
        if embed:
            output = ca.substitute(output, e.p, ca.DM(model.parameters))
        else:
            inputs, names = [*inputs, e.p], [*names, "p"]
        output = common_subexpressions(output, e.n_segments)
        functions[name] = ca.Function(f"{prefix}_{name}", inputs, [output], names, ["out"])
    return functions


def _sample_inputs(model, functions, embed: bool, seed: int) -> dict:
    """A bent, moving state (seeded) for the test program: a constant-curvature segment
    3 % stretched and bent by up to 15 1/m, any other element's coordinates within a
    fifth of their scale of rest (:meth:`Robot.coordinate_scale`), inside the domain."""
    rng = np.random.default_rng(seed)
    parts = []
    for element in model.robot.segments:
        if element.kind == Segment.kind:
            parts.append([element.rest_length * 1.03, *rng.uniform(-15, 15, 2)])
        else:
            away = rng.uniform(-0.2, 0.2, element.n_coordinates)
            parts.append(element.rest_configuration() + away * element.coordinate_scale())
    q = np.concatenate(parts)
    sizes = {"qd": model.n, "tau": model.n, "qdd": model.n, "lam": model.n_creep}
    samples = {}
    for name, f in functions.items():
        values = []
        for i in range(f.n_in()):
            label = f.name_in(i)
            if label == "q":
                values.append(q)
            elif label == "p":
                values.append(model.parameters)
            else:
                values.append(rng.normal(scale=0.1, size=sizes[label]))
        samples[name] = values
    return samples


def _c_array(name: str, values) -> str:
    values = np.asarray(values, dtype=np.float64).ravel(order="F")
    body = ", ".join(f"{v:.17g}" for v in values) if values.size else "0"
    return f"static const casadi_real {name}[{max(values.size, 1)}] = {{{body}}};"


HARNESS = Path(__file__).parent / "c" / "export_harness.c"
"""The test program's fixed C (package data): ``run``, which calls one function on its
samples and compares."""


def _test_program(prefix: str, functions, samples, expected) -> str:
    lines = [
        f"/* Test of {prefix}.c: generated by softcurve.export_c. */",
        f'#include "{prefix}.h"',
        f"#define TOLERANCE {_TOLERANCE!r}",
        HARNESS.read_text(encoding="utf-8"),
    ]
    main = ["int main(void) {", "  int failed = 0;"]
    for name, f in functions.items():
        c_name = f.name()
        for i, value in enumerate(samples[name]):
            lines.append(_c_array(f"{name}_in{i}", value))
        lines.append(_c_array(f"{name}_expected", expected[name]))
        inputs = ", ".join(f"{name}_in{i}" for i in range(f.n_in()))
        main.append(f"  {{ const casadi_real *in[] = {{{inputs}}};")
        main.append(
            f'    failed |= run("{name}", {c_name}_work, {c_name}, in, {f.n_in()}, '
            f"{name}_expected, {f.numel_out(0)}); }}"
        )
    main += ['  puts(failed ? "FAILED" : "OK");', "  return failed;", "}"]
    return "\n".join([*lines, "", *main, ""])


def c_identifier(name: str, value: str) -> str:
    """``value``, checked to be a C identifier (ASCII letters, digits and ``_``, not
    starting with a digit) of at most :data:`MAX_PREFIX` characters (the files
    :func:`export_c` names after it); :class:`~softcurve.ParameterError` naming ``name``
    otherwise.

    Parameters
    ----------
    name : str
        The field, for the message.
    value : str
        The identifier.
    """
    if not (isinstance(value, str) and value.isidentifier() and value.isascii()):
        raise ParameterError(
            f"{name} must be a C identifier (letters, digits and _, not starting with a "
            f"digit), got {value!r}"
        )
    if len(value) > MAX_PREFIX:
        raise ParameterError(
            f"{name} must have 1 to {MAX_PREFIX} characters (the files named after it must "
            f"fit a file system's 255-byte names), got {len(value)}: {value[:20]}..."
        )
    return value


def export_c(
    model,
    directory,
    *,
    actuator: Actuator | None = None,
    prefix: str = "softcurve_model",
    embed_parameters: bool = True,
    seed: int = 0,
) -> ExportedC:
    """Write standalone C for the model (and ``H(q)`` of ``actuator``) into ``directory``.

    Parameters
    ----------
    model : Model
        The compiled model.
    directory : str or Path
        Created if missing; existing files of the same names are overwritten. A relative
        path is resolved once, against the current working directory: the paths of the
        result are absolute.
    actuator : Actuator, optional
        Adds ``<prefix>_input_matrix(q) -> H`` (n x m, column-major).
    prefix : str
        A C identifier of at most ``MAX_PREFIX`` (160) characters: file names and function
        names start with it.
    embed_parameters : bool
        Compile the robot's numbers in (default) or take ``p`` as the last input.
    seed : int
        Seed of the test program's sample state.
    """
    c_identifier("prefix", prefix)
    directory = Path(directory).resolve()  # once: the test is built and run inside it
    directory.mkdir(parents=True, exist_ok=True)
    functions = _functions(model, actuator, prefix, embed_parameters)
    generator = ca.CodeGenerator(f"{prefix}.c", {"with_header": True})
    for f in functions.values():
        generator.add(f)
    with tempfile.TemporaryDirectory() as staging:  # then each file whole or not at all
        generator.generate(staging + os.sep)
        for name in (f"{prefix}.c", f"{prefix}.h"):
            atomic_write(directory / name, Path(staging, name).read_bytes())
    samples = _sample_inputs(model, functions, embed_parameters, seed)
    expected = {
        name: np.array(f(*samples[name]), dtype=np.float64).ravel(order="F")
        for name, f in functions.items()
    }
    test = directory / f"test_{prefix}.c"
    atomic_write(test, _test_program(prefix, functions, samples, expected).encode())
    command = [
        "cc", "-std=c99", "-O2", f"test_{prefix}.c", f"{prefix}.c", "-o", f"test_{prefix}", "-lm"
    ]  # fmt: skip
    return ExportedC(
        status=Status.SUCCESS,
        message=f"{len(functions)} functions and their test program written to {directory}",
        source=directory / f"{prefix}.c",
        header=directory / f"{prefix}.h",
        test=test,
        functions=tuple(f.name() for f in functions.values()),
        sample_inputs=samples,
        compile_command=command,
    )


def build_and_run_test(
    exported: ExportedC, compiler: str | None = None, optimization: str = "-O2"
) -> str:
    """Compile and run the exported test program; return its output.

    Parameters
    ----------
    exported : ExportedC
        What :func:`export_c` wrote.
    compiler : str, optional
        The C compiler (default: ``cc``, ``gcc`` or ``clang``, the first found).
    optimization : str
        Replaces ``-O2`` (e.g. ``"-O0"`` compiles several times faster).

    Returns
    -------
    str
        The test program's standard output.

    Raises
    ------
    FileNotFoundError
        When no C compiler is found.
    subprocess.CalledProcessError
        When compiling fails or the test reports a mismatch.
    """
    compiler = compiler or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if compiler is None:
        raise FileNotFoundError("no C compiler (cc, gcc or clang) found")
    directory = exported.source.parent.resolve()  # the program runs by its absolute path
    command = [compiler, *(optimization if a == "-O2" else a for a in exported.compile_command[1:])]
    subprocess.run(command, cwd=directory, check=True, capture_output=True, text=True)
    program = directory / exported.compile_command[exported.compile_command.index("-o") + 1]
    result = subprocess.run(
        [str(program)], cwd=directory, check=True, capture_output=True, text=True
    )
    return result.stdout
