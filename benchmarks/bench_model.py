"""Cost of the compiled model: compile time and one forward-dynamics evaluation.

For robots of N = 1, 3, 6 paper segments with creep (n = 3N coordinates) it prints:
- the time to build and compile the model in an empty cache, and to load it from the cache;
- one forward-dynamics evaluation inside compiled C (a C loop calling the generated
  function, compiled with the same flags as the model), and for N = 1 the same built
  portable (``SOFTCURVE_PORTABLE=1``, without ``-march=native``);
- the same from Python, through the model's ctypes path and through CasADi's own
  Function call (the virtual machine), for comparison.

Run: ``python benchmarks/bench_model.py [--segments 1 3 6] [--repeat 200000] [--no-portable]``
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import shutil
import subprocess
import tempfile
import time
import timeit
from pathlib import Path

import casadi as ca
import numpy as np

import softcurve as sc
from softcurve.compiled._build import FUNCTION_FLAGS, _native_flags, find_compiler

HARNESS = r"""
#include <stdio.h>
#include <time.h>
#define casadi_real double
#define casadi_int long long int
int forward_dynamics(const casadi_real** arg, casadi_real** res, casadi_int* iw,
                     casadi_real* w, int mem);
int forward_dynamics_work(casadi_int* a, casadi_int* r, casadi_int* i, casadi_int* w);
int main(int argc, char** argv) {
  long repeat = atol(argv[1]);
  static casadi_real q[64], qd[64], tau[64], lam[64], p[4096], out[64], w[1 << 20];
  static casadi_int iw[1 << 16];
  int n = atoi(argv[2]), np_ = atoi(argv[3]);
  for (int i = 0; i < np_; i++) scanf("%lf", &p[i]);
  for (int i = 0; i < n; i++) { q[i] = (i % 3 == 0) ? 0.064 : 25.0 / (1 + i); qd[i] = 10.0; }
  casadi_int sz_arg, sz_res, sz_iw, sz_w;  /* called Functions use arg and res beyond 5, 1 */
  forward_dynamics_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  const casadi_real** arg = calloc(sz_arg, sizeof *arg);
  casadi_real** res = calloc(sz_res, sizeof *res);
  arg[0] = q; arg[1] = qd; arg[2] = tau; arg[3] = lam; arg[4] = p;
  res[0] = out;
  if (sz_w > (1 << 20) || sz_iw > (1 << 16)) return 3;
  struct timespec a, b;
  double checksum = 0;
  clock_gettime(CLOCK_MONOTONIC, &a);
  for (long k = 0; k < repeat; k++) {
    q[1] = 25.0 + 1e-9 * (k & 7);  /* defeat hoisting */
    forward_dynamics(arg, res, iw, w, 0);
    checksum += out[0];
  }
  clock_gettime(CLOCK_MONOTONIC, &b);
  double seconds = (b.tv_sec - a.tv_sec) + 1e-9 * (b.tv_nsec - a.tv_nsec);
  printf("%.6e %.17g\n", seconds / repeat, checksum);
  return 0;
}
"""


@contextlib.contextmanager
def _harness(model: sc.Model, flags: tuple[str, ...]):
    """Build the C loop over the model's forward dynamics with ``flags`` in a temporary
    directory; yield the command that runs it (its stdin: the model's parameters), or
    None without a C compiler."""
    compiler = find_compiler()
    if compiler is None:
        yield None
        return
    with tempfile.TemporaryDirectory() as tmp:
        generator = ca.CodeGenerator("fd.c", {"with_header": False})
        generator.add(model.symbolic["forward_dynamics"])
        generator.generate(tmp + os.sep)
        Path(tmp, "main.c").write_text("#include <stdlib.h>\n" + HARNESS)
        subprocess.run(
            [*compiler, *flags, "-o", "bench", "fd.c", "main.c", "-lm"],
            cwd=tmp,
            check=True,
            capture_output=True,
        )
        yield [os.path.join(tmp, "bench"), str(model.n), str(model.parameters.size)]


def _parameters(model: sc.Model) -> str:
    return " ".join(repr(float(v)) for v in model.parameters)


def inside_c(
    model: sc.Model, repeat: int, flags: tuple[str, ...] | None = None, rounds: int = 5
) -> float:
    """Seconds per forward-dynamics evaluation in a C loop (default: the model's flags),
    best of ``rounds`` runs of the loop (on a shared machine one run varies by 30 %)."""
    flags = (*FUNCTION_FLAGS, *_native_flags()) if flags is None else flags
    with _harness(model, flags) as command:
        if command is None:
            return float("nan")
        seconds = []
        for _ in range(rounds):
            out = subprocess.run(
                [command[0], str(repeat), *command[1:]],
                input=_parameters(model),
                text=True,
                capture_output=True,
                check=True,
            ).stdout
            seconds.append(float(out.split()[0]))
    return min(seconds)


def executed_instructions(model: sc.Model, repeat: int = 100) -> float:
    """Machine instructions of one forward-dynamics evaluation in the C loop, counted by
    callgrind (NaN without valgrind or a C compiler): the difference between ``2 repeat``
    and ``repeat`` evaluations, over ``repeat``. A count, the same on any machine that
    runs the same binary, whatever else it is doing. Built with the model's portable
    flags (:data:`FUNCTION_FLAGS`), since valgrind does not decode every instruction set
    that ``-march=native`` may choose (AVX-512 among them)."""
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        return float("nan")
    with _harness(model, FUNCTION_FLAGS) as command:
        if command is None:
            return float("nan")
        counts = []
        for evaluations in (repeat, 2 * repeat):
            run = subprocess.run(
                [valgrind, "--tool=callgrind", "--callgrind-out-file=/dev/null",
                 command[0], str(evaluations), *command[1:]],
                input=_parameters(model), text=True, capture_output=True,
            )  # fmt: skip
            collected = re.search(r"Collected : ([\d,]+)", run.stderr)
            if run.returncode or collected is None:  # valgrind could not run it
                return float("nan")
            counts.append(int(collected.group(1).replace(",", "")))
    return (counts[1] - counts[0]) / repeat


def from_python(model: sc.Model, number: int = 2000) -> tuple[float, float]:
    """Seconds per call through the ctypes path and through CasADi's Function call."""
    rng = np.random.default_rng(1)
    q = np.tile([0.064, 20.0, -5.0], model.robot.n_segments) + rng.normal(0, 1e-3, model.n)
    qd, tau, lam = np.full(model.n, 10.0), np.zeros(model.n), np.zeros(model.n_creep)
    native = timeit.timeit(lambda: model.forward_dynamics(q, qd, tau, lam), number=number)
    vm_function = model.symbolic["forward_dynamics"]
    p = model.parameters
    vm = timeit.timeit(lambda: vm_function(q, qd, tau, lam, p), number=max(number // 10, 10))
    return native / number, vm / max(number // 10, 10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 3, 6])
    parser.add_argument(
        "--repeat",
        type=int,
        default=200_000,
        help="evaluations in the C loop for N = 1 (scaled down for larger N)",
    )
    parser.add_argument(
        "--no-portable",
        action="store_true",
        help="skip the comparison with the portable build (SOFTCURVE_PORTABLE=1) for N = 1",
    )
    args = parser.parse_args()
    header = (
        f"{'N':>2} {'n':>3} {'instr.':>8} {'compile [s]':>11} {'cached [s]':>10} "
        f"{'in C [us]':>9} {'Python [us]':>11} {'CasADi VM [us]':>14}"
    )
    print(header)
    print("-" * len(header))
    for n_segments in args.segments:
        robot = sc.presets.ifac2020().with_segments(n_segments)
        with tempfile.TemporaryDirectory() as cache:
            os.environ["SOFTCURVE_CACHE_DIR"] = cache
            start = time.perf_counter()
            model = sc.Model(robot)
            compile_time = time.perf_counter() - start
            start = time.perf_counter()
            sc.Model(robot)
            cached_time = time.perf_counter() - start
            c_time = inside_c(model, max(args.repeat // n_segments**2, 1000))
            native, vm = from_python(model)
        instructions = model.symbolic["forward_dynamics"].n_instructions()
        print(
            f"{n_segments:>2} {model.n:>3} {instructions:>8} {compile_time:>11.1f} "
            f"{cached_time:>10.3f} {c_time * 1e6:>9.2f} {native * 1e6:>11.1f} {vm * 1e6:>14.1f}",
            flush=True,
        )
    print(
        "\nTarget (issue 2): <= 5 us per forward-dynamics evaluation inside compiled code "
        "for N = 1 with creep."
    )
    if not args.no_portable and _native_flags():
        model = sc.Model(sc.presets.ifac2020())
        default = min(inside_c(model, args.repeat) for _ in range(3))
        portable = min(inside_c(model, args.repeat, FUNCTION_FLAGS) for _ in range(3))
        print(
            f"N = 1 in C, built for this CPU ({' '.join((*FUNCTION_FLAGS, *_native_flags()))}): "
            f"{default * 1e6:.2f} us; portable (SOFTCURVE_PORTABLE=1): {portable * 1e6:.2f} us "
            f"({100 * (1 - default / portable):.0f} % faster for this CPU)"
        )


if __name__ == "__main__":
    main()
