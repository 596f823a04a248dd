"""Study: what one evaluation of the identification's sensitivity function costs, and
whether vector lanes make the exact ``f_x S + f_d`` cheaper.

Run:  python benchmarks/study_sensitivity_cost.py [--states 64] [--rounds 7]

The case is ``bench_identification.py``'s (the paper robot, three bellows, five
sensitivity columns). The driver evaluates ``fs(x;vec(S), u, d;scale) -> f;vec(S')``
(CasADi's C, about 75,000 operations) once or twice per CVODES step, and that is most
of a dynamic fit's evaluation. This script times, on ``--states`` different states
called in turn in a C loop (best of ``--rounds`` alternating rounds):

1. CasADi's C of ``fs``;
2. the same columns as forward-mode directional derivatives of ``f`` along
   ``(S_j, scale_j e_j)``, one column per lane (``softcurve.compiled.lanes``): two calls
   of 4 lanes with glibc's vector math, or one call of 8 lanes, each lane also
   recomputing ``f``;
3. ``[f; f_x; f_d]`` with the product ``f_x S + f_d`` formed in C (what a driver that
   reuses the Jacobian while the corrector iterates at one state would call once per
   step).

Every harness is compiled with the model's flags (``-O2 -march=native``). It prints each
variant's operation count, microseconds per evaluation and largest
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

from softcurve.compiled.lanes import (
    VECTOR_MATH_LIBRARY,
    lanes_function,
    lanes_prelude,
    lanes_work,
    vector_math_available,
)
from softcurve.compiled.source import compile_source

sys.path.insert(0, str(Path(__file__).parent))
import bench_identification

ENTRY = "run"
"""Every harness exports ``run(x (N, W), u, d_scaled, out (N, W), N)``."""


def _loop(body: str, n_x: int, m: int, n_u: int, prelude: str) -> str:
    """A harness: ``body`` evaluates state ``i`` (pointers ``xs``, ``u``, ``dsc``, ``y``)."""
    width = n_x * (1 + m)
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
    ).replace("N_U", str(n_u))


def scalar(function: ca.Function, stem: str, n_x: int, m: int, n_u: int, product: bool):
    """CasADi's C of ``function`` per state; with ``product``, ``function`` is
    ``[f; f_x; f_d]`` and the columns are formed here."""
    generator = ca.CodeGenerator(f"{stem}.c", {"with_header": False})
    generator.add(function)
    name = function.name()
    lines = [
        f"    static casadi_real w[{function.sz_w()}], lin[{function.numel_out(0)}];",
        f"    static casadi_int iw[{max(function.sz_iw(), 1)}];",
        f"    const casadi_real* arg[{function.sz_arg()}] = {{xs, u, dsc}};",
        f"    casadi_real* res[{function.sz_res()}] = {{{'lin' if product else 'y'}}};",
        f"    {name}(arg, res, iw, w, 0);",
    ]
    if product:
        lines += [
            f"    for (int i = 0; i < {n_x}; i++) y[i] = lin[i];",
            f"    for (int j = 0; j < {m}; j++) {{",
            f"      double* c = y + {n_x} * (1 + j); const double* s = xs + {n_x} * (1 + j);",
            f"      for (int i = 0; i < {n_x}; i++) c[i] = lin[{n_x * (1 + n_x)} + {n_x} * j + i];",
            f"      for (int k = 0; k < {n_x}; k++)",
            f"        for (int i = 0; i < {n_x}; i++) c[i] += lin[{n_x} + {n_x} * k + i] * s[k];",
            "    }",
        ]
    return compile_source(stem, _loop("\n".join(lines), n_x, m, n_u, generator.dump()))


def lanes(direction: ca.Function, width: int, n_x: int, m: int, n_u: int, vector_math: bool):
    """The columns as ``width`` forward directions per call of ``direction``."""
    n_d = direction.size1_in(2) - m  # the column scales follow d
    body = f"""    static sc_v w[{lanes_work(direction)}];
    sc_v tx[{n_x}], tp[{m}], o[{2 * n_x}];
    for (int g = 0; g < {m}; g += SC_W) {{
      for (int l = 0; l < SC_W; l++) {{
        int j = g + l < {m} ? g + l : {m} - 1;
        for (int i = 0; i < {n_x}; i++) tx[i][l] = xs[{n_x} * (1 + j) + i];
        for (int k = 0; k < {m}; k++) tp[k][l] = k == j ? dsc[{n_d} + k] : 0.0;
      }}
      directions(xs, u, dsc, tx, tp, o, w);
      if (g == 0) for (int i = 0; i < {n_x}; i++) y[i] = o[i][0];
      for (int l = 0; l < SC_W && g + l < {m}; l++)
        for (int i = 0; i < {n_x}; i++) y[{n_x} * (1 + g + l) + i] = o[{n_x} + i][l];
    }}"""
    prelude = lanes_prelude(width, vector_math) + lanes_function(
        direction, "directions", (True, True, True, False, False)
    )
    source = _loop(body, n_x, m, n_u, prelude)
    link = VECTOR_MATH_LIBRARY if vector_math else ()
    return compile_source(f"study_sensitivity_lanes_{width}", source, link)


def variants(fs: ca.Function, n_x: int):
    """The SX functions of each variant, from the library's ``fs``."""
    n_u, n_ds = fs.size1_in(1), fs.size1_in(2)
    m = fs.size1_in(0) // n_x - 1
    x, u, d = ca.SX.sym("x", n_x), ca.SX.sym("u", n_u), ca.SX.sym("d", n_ds - m)
    scale = ca.SX.sym("scale", m)
    f = fs(ca.vertcat(x, ca.SX.zeros(n_x * m)), u, ca.vertcat(d, scale))[:n_x]
    f_d = ca.jacobian(fs(ca.vertcat(x, ca.SX.zeros(n_x * m)), u, ca.vertcat(d, scale)), scale)
    # f_d: the columns' forcing, read from fs at S = 0 (d S'/d scale_j is column j's).
    forcing = ca.horzcat(*(f_d[n_x * (1 + j) : n_x * (2 + j), j] * scale[j] for j in range(m)))
    blocks = ca.vertcat(f, ca.vec(ca.jacobian(f, x)), ca.vec(forcing))
    linearization = ca.Function(
        "linearization", [x, u, ca.vertcat(d, scale)], [ca.densify(ca.cse(blocks))]
    )
    tx, tp = ca.SX.sym("tx", n_x), ca.SX.sym("tp", m)
    tangent = ca.jtimes(f, x, tx) + forcing @ (tp / scale)
    direction = ca.Function(
        "directions",
        [x, u, ca.vertcat(d, scale), tx, tp],
        [ca.densify(ca.cse(ca.vertcat(f, tangent)))],
    )
    return linearization, direction, m, n_u


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=64, help="states evaluated in turn")
    parser.add_argument("--rounds", type=int, default=7, help="alternating rounds (best kept)")
    args = parser.parse_args()
    print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()}")
    evaluate, theta = bench_identification.dynamic_evaluator(2.0, "linear")
    fs, n_x = evaluate.variational, evaluate.n_x
    linearization, direction, m, n_u = variants(fs, n_x)
    d_value = np.array(evaluate.direct(theta)[0]).ravel()
    rng = np.random.default_rng(16)
    n = args.states
    x = np.tile(np.concatenate([d_value[-n_x:], evaluate.seed.ravel("F")]), (n, 1))
    x += rng.normal(0.0, 1e-2, x.shape) * (np.abs(x) + 1e-3)
    u = np.array([1.5e4, 1.2e4, 1.8e4])
    dsc = np.concatenate([d_value, evaluate.scale])
    built = {"CasADi's C of fs": (scalar(fs, "study_fs", n_x, m, n_u, False), fs)}
    built["[f; f_x; f_d], product in C"] = (
        scalar(linearization, "study_lin", n_x, m, n_u, True), linearization
    )  # fmt: skip
    for width, vector_math in ((4, vector_math_available()), (8, False)):
        name = f"directions, lanes of {width}" + (", libmvec" if vector_math else "")
        built[name] = (lanes(direction, width, n_x, m, n_u, vector_math), direction)
    outputs, best = {}, {}
    for name, (library, _) in built.items():
        if library is None:
            raise SystemExit("no C compiler: nothing to compare")
        outputs[name] = np.zeros_like(x)
        best[name] = np.inf
    for _ in range(args.rounds):
        for name, (library, _) in built.items():
            run = getattr(library, ENTRY)
            run.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_long]
            start = time.perf_counter()
            run(*(a.ctypes.data for a in (x, u, dsc, outputs[name])), n)
            best[name] = min(best[name], (time.perf_counter() - start) / n)
    reference = outputs["CasADi's C of fs"]
    span = np.abs(reference).max(axis=0) + np.finfo(float).tiny
    print(f"{m} columns, {n_x} states, {n} states in turn, best of {args.rounds} rounds")
    for name, (_, function) in built.items():
        difference = (np.abs(outputs[name] - reference) / span).max()
        print(
            f"  {name:34s} {function.n_instructions():7d} operations  "
            f"{best[name] * 1e6:6.2f} us per evaluation  difference {difference:.1e}"
        )


if __name__ == "__main__":
    main()
