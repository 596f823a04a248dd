"""Study: what one evaluation of the identification's sensitivity function costs, and
whether another form of the exact ``f_x S + f_d`` is cheaper.

Run:  python benchmarks/study_sensitivity_cost.py [--states 64] [--rounds 7]

The case is ``bench_identification.py``'s (the paper robot, three bellows, five
sensitivity columns). The driver evaluates ``fs(x;vec(S), u, d;scale) -> f;vec(S')``
once or twice per CVODES step, and that is most of a dynamic fit's evaluation. This
script times, on ``--states`` different states evaluated in turn in a C loop (best of
``--rounds`` alternating rounds), in the order it prints them:

1. the driver's own library of ``fs`` (``compile_function``'s ``FUNCTION_FLAGS`` and
   ``-march=native``), called through its function pointer;
2. CasADi's C of the same ``fs`` (built here, like every variant below, with the
   model's flags ``-O2 -march=native``);
3. ``[f; f_x; f_d]`` with the product ``f_x S + f_d`` formed in C (what a driver that
   reuses the Jacobian while the corrector iterates at one state calls once per step);
4. the columns as forward-mode directional derivatives of ``f`` along
   ``(S_j, scale_j e_j)``, one column per lane (``softcurve.compiled._lanes``): two calls
   of 4 lanes with glibc's vector math, or one call of 8 lanes, each lane also
   recomputing ``f``.

It prints the operation counts of ``f``, of ``f`` with its Jacobian's ``q`` columns and
of each variant, then each variant's microseconds per evaluation and largest
difference from (1) relative to each output's largest value.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np

from softcurve.compiled._lanes import (
    VECTOR_MATH_LIBRARY,
    lanes_function,
    lanes_prelude,
    lanes_work,
    vector_math_available,
)
from softcurve.compiled._source import compile_source

sys.path.insert(0, str(Path(__file__).parent))
import bench_identification

TRIAL = 2.0
"""Length of the benchmark's trial [s] built here: only its functions are used."""
PRESSURE = 1.5e4
"""Every chamber's pressure at the states timed [Pa], mid-range of the trial's."""
SPREAD = 1e-2
"""Relative spread of the states timed around the trial's start (seeded)."""
FLOOR = 1e-3
"""Absolute part of that spread, for entries that start at zero."""

ENTRY = "run"
"""Every harness exports ``run(x (N, W), u, d_scaled, out (N, W), N)``; the one of the
driver's library ``run_pointer(fs, sizes (4,), x, u, d_scaled, out, N)``."""


def harness(body: str, width: int, prelude: str) -> str:
    """C of :data:`ENTRY`, evaluating ``body`` for each state ``i``.

    Parameters
    ----------
    body : str
        C that reads ``xs`` (the state and columns), ``u`` and ``dsc`` and writes ``y``.
    width : int
        ``nx (1 + m)``: entries of a state with its columns.
    prelude : str
        C before the entry (the function it calls).

    Returns
    -------
    str
    """
    return "\n".join(
        [
            prelude,
            f'__attribute__((visibility("default"))) void {ENTRY}(const double* x, '
            "const double* u, const double* dsc, double* out, long n) {",
            "  for (long i = 0; i < n; i++) {",
            f"    const double* xs = x + i * {width}; double* y = out + i * {width};",
            body,
            "  }",
            "}",
        ]
    )


POINTER_HARNESS = r"""
#include <stdlib.h>
typedef int (*casadi_fn)(const double **, double **, long long *, double *, int);
__attribute__((visibility("default"))) void run_pointer(
    casadi_fn fs, const long long *sizes, const double *x, const double *u,
    const double *dsc, double *out, long width, long n) {
  const double **arg = calloc(sizes[0] > 3 ? sizes[0] : 3, sizeof(double *));
  double **res = calloc(sizes[1] > 1 ? sizes[1] : 1, sizeof(double *));
  long long *iw = calloc(sizes[2] + 1, sizeof(long long));
  double *w = calloc(sizes[3] + 1, sizeof(double));
  for (long i = 0; arg && res && iw && w && i < n; i++) {
    arg[0] = x + i * width; arg[1] = u; arg[2] = dsc; res[0] = out + i * width;
    fs(arg, res, iw, w, 0);
  }
  free(arg); free(res); free(iw); free(w);
}
"""


def driver_library(columns, width: int):
    """``run(x, u, dsc, out, n)`` on the driver's own compiled ``fs``.

    Parameters
    ----------
    columns : softcurve.compiled.NativeFunction
        The loaded ``fs`` of the evaluator's driver route.
    width : int
        ``nx (1 + m)``.

    Returns
    -------
    callable
    """
    library = compile_source("study_sensitivity_pointer", POINTER_HARNESS)
    if library is None:
        raise SystemExit("no C compiler: nothing to compare")
    run = library.run_pointer
    run.argtypes = [ctypes.c_void_p] * 6 + [ctypes.c_long] * 2
    sizes = np.array([columns._sz_arg, columns._sz_res, columns._sz_iw, columns._sz_w])
    pointer = ctypes.cast(columns._function, ctypes.c_void_p).value
    return lambda *arrays: run(
        pointer, sizes.ctypes.data, *(a.ctypes.data for a in arrays), width, len(arrays[0])
    )


def casadi_c(function: ca.Function, stem: str, nx: int, m: int, product: bool):
    """``run`` on CasADi's C of ``function``.

    Parameters
    ----------
    function : casadi.Function
        ``fs``, or with ``product`` the ``[f; vec(f_x); vec(F)]`` of :func:`variants`.
    stem : str
        The harness's name in the cache.
    nx, m : int
        States and columns.
    product : bool
        Form the columns ``f_x S_j + F_j`` in C from ``function``'s output.

    Returns
    -------
    ctypes.CDLL or None
    """
    generator = ca.CodeGenerator(f"{stem}.c", {"with_header": False})
    generator.add(function)
    lines = [
        f"    static casadi_real w[{function.sz_w()}], lin[{function.numel_out(0)}];",
        f"    static casadi_int iw[{max(function.sz_iw(), 1)}];",
        f"    const casadi_real* arg[{function.sz_arg()}] = {{xs, u, dsc}};",
        f"    casadi_real* res[{function.sz_res()}] = {{{'lin' if product else 'y'}}};",
        f"    {function.name()}(arg, res, iw, w, 0);",
    ]
    if product:
        forcing = nx * (1 + nx)
        lines += [
            f"    for (int i = 0; i < {nx}; i++) y[i] = lin[i];",
            f"    for (int j = 0; j < {m}; j++) {{",
            f"      double* c = y + {nx} * (1 + j); const double* s = xs + {nx} * (1 + j);",
            f"      for (int i = 0; i < {nx}; i++) c[i] = lin[{forcing} + {nx} * j + i];",
            f"      for (int k = 0; k < {nx}; k++)",
            f"        for (int i = 0; i < {nx}; i++) c[i] += lin[{nx} + {nx} * k + i] * s[k];",
            "    }",
        ]
    return compile_source(stem, harness("\n".join(lines), nx * (1 + m), generator.dump()))


def lanes(direction: ca.Function, width: int, nx: int, m: int, vector_math: bool):
    """``run`` on the columns as ``width`` forward directions per call of ``direction``.

    Parameters
    ----------
    direction : casadi.Function
        ``(x, u, (d, scale), tx, tp) -> (f; f_x tx + F (tp / scale))`` of :func:`variants`.
    width : int
        Lanes per call.
    nx, m : int
        States and columns.
    vector_math : bool
        With glibc's vector math (width 4 only).

    Returns
    -------
    ctypes.CDLL or None
    """
    scales = direction.size1_in(2) - m  # where the column scales start in (d, scale)
    body = f"""    static sc_v w[{lanes_work(direction)}];
    sc_v tx[{nx}], tp[{m}], o[{2 * nx}];
    for (int g = 0; g < {m}; g += SC_W) {{
      for (int l = 0; l < SC_W; l++) {{
        int j = g + l < {m} ? g + l : {m} - 1;
        for (int i = 0; i < {nx}; i++) tx[i][l] = xs[{nx} * (1 + j) + i];
        for (int k = 0; k < {m}; k++) tp[k][l] = k == j ? dsc[{scales} + k] : 0.0;
      }}
      directions(xs, u, dsc, tx, tp, o, w);
      if (g == 0) for (int i = 0; i < {nx}; i++) y[i] = o[i][0];
      for (int l = 0; l < SC_W && g + l < {m}; l++)
        for (int i = 0; i < {nx}; i++) y[{nx} * (1 + g + l) + i] = o[{nx} + i][l];
    }}"""
    prelude = lanes_prelude(width, vector_math) + lanes_function(
        direction, "directions", (True, True, True, False, False)
    )
    link = VECTOR_MATH_LIBRARY if vector_math else ()
    source = harness(body, nx * (1 + m), prelude)
    return compile_source(f"study_sensitivity_lanes_{width}", source, link)


def variants(fs: ca.Function, nx: int, n_q: int) -> tuple:
    """The other forms of ``fs``, from its SX function.

    Parameters
    ----------
    fs : casadi.Function
        ``fs(x;vec(S), u, d;scale) -> f;vec(S')`` (``SensitivityEvaluator.variational``).
    nx, n_q : int
        States, and coordinates ``q`` (the first ``n_q`` states).

    Returns
    -------
    tuple
        ``(linearization [f; vec(f_x); vec(F)], direction, f, f with its Jacobian's
        q columns)`` as CasADi Functions, ``F`` the columns' forcing
        ``f_d[:, active] diag(scale)``.
    """
    n_u, n_ds = fs.size1_in(1), fs.size1_in(2)
    m = fs.size1_in(0) // nx - 1
    x, u, d = ca.SX.sym("x", nx), ca.SX.sym("u", n_u), ca.SX.sym("d", n_ds - m)
    scale = ca.SX.sym("scale", m)
    at_zero = fs(ca.vertcat(x, ca.SX.zeros(nx * m)), u, ca.vertcat(d, scale))
    f = at_zero[:nx]
    # At S = 0, column j's S' is f_d[:, active_j] scale_j: its derivative in scale_j.
    d_fs_d_scale = ca.jacobian(at_zero, scale)
    forcing = ca.horzcat(
        *(d_fs_d_scale[nx * (1 + j) : nx * (2 + j), j] * scale[j] for j in range(m))
    )
    inputs = [x, u, ca.vertcat(d, scale)]
    blocks = ca.vertcat(f, ca.vec(ca.jacobian(f, x)), ca.vec(forcing))
    linearization = ca.Function("linearization", inputs, [ca.densify(ca.cse(blocks))])
    tx, tp = ca.SX.sym("tx", nx), ca.SX.sym("tp", m)
    tangent = ca.jtimes(f, x, tx) + forcing @ (tp / scale)
    direction = ca.Function(
        "directions", [*inputs, tx, tp], [ca.densify(ca.cse(ca.vertcat(f, tangent)))]
    )
    plain = ca.Function("f", inputs, [f])
    with_q = ca.vertcat(f, ca.vec(ca.jacobian(f, x[:n_q])))
    q_columns = ca.Function("f_q", inputs, [ca.cse(with_q)])
    return linearization, direction, plain, q_columns


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=64, help="states evaluated in turn")
    parser.add_argument("--rounds", type=int, default=7, help="alternating rounds (best kept)")
    args = parser.parse_args()
    for name in ("states", "rounds"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be at least 1, got {getattr(args, name)}")
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()}")  # fmt: skip
    evaluate, theta = bench_identification.dynamic_evaluator(TRIAL, "linear")
    fs, nx = evaluate.variational, evaluate.n_x
    route = evaluate._route()
    if route is None:
        raise SystemExit("softcurve's CVODES driver is not available here: nothing to time")
    # the case's state is (q, qd, creep states), as many of each
    linearization, direction, plain, q_columns = variants(fs, nx, nx // 3)
    m, n_u = len(evaluate.active), fs.size1_in(1)
    d_value = np.array(evaluate.direct(theta)[0]).ravel()
    rng = np.random.default_rng(16)
    x = np.tile(np.concatenate([d_value[-nx:], evaluate.seed.ravel("F")]), (args.states, 1))
    x += rng.normal(0.0, SPREAD, x.shape) * (np.abs(x) + FLOOR)
    u = np.full(n_u, PRESSURE)
    dsc = np.concatenate([d_value, evaluate.scale])
    built = {"the driver's library of fs": (driver_library(route[1][0], nx * (1 + m)), fs)}
    for name, function, library in (
        ("CasADi's C of fs", fs, casadi_c(fs, "study_fs", nx, m, False)),
        ("[f; f_x; f_d], product in C", linearization,
         casadi_c(linearization, "study_lin", nx, m, True)),
        (f"directions, lanes of 4{', libmvec' if vector_math_available() else ''}", direction,
         lanes(direction, 4, nx, m, vector_math_available())),
        ("directions, lanes of 8", direction, lanes(direction, 8, nx, m, False)),
    ):  # fmt: skip
        if library is None:
            raise SystemExit("no C compiler with vector extensions: nothing to compare")
        run = getattr(library, ENTRY)
        run.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_long]
        built[name] = (
            lambda *arrays, run=run: run(*(a.ctypes.data for a in arrays), len(arrays[0])),
            function,
        )
    outputs = {name: np.zeros_like(x) for name in built}
    best = dict.fromkeys(built, np.inf)
    for _ in range(args.rounds):
        for name, (run, _) in built.items():
            start = time.perf_counter()
            run(x, u, dsc, outputs[name])
            best[name] = min(best[name], (time.perf_counter() - start) / args.states)
    reference = outputs["the driver's library of fs"]
    span = np.abs(reference).max(axis=0) + np.finfo(float).tiny
    print(
        f"{m} columns, {nx} states; operations: f {plain.n_instructions()}, f with its "
        f"Jacobian's q columns {q_columns.n_instructions()}"
    )
    print(f"{args.states} states in turn, best of {args.rounds} rounds")
    for name, (_, function) in built.items():
        difference = (np.abs(outputs[name] - reference) / span).max()
        print(
            f"  {name:34s} {function.n_instructions():7d} operations  "
            f"{best[name] * 1e6:6.2f} us per evaluation  difference {difference:.1e}"
        )


if __name__ == "__main__":
    main()
