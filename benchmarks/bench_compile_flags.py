"""Compiler flags for the generated C: compile time against speed of one evaluation.

Run:  python benchmarks/bench_compile_flags.py [--quick] [--repeat 5]
      [--only rhs,dynamics_terms,stepper,sensitivity] [--robot paper|two-segment]

Functions of the paper robot (preset ifac2020) with the bellows of
examples/pneumatic.toml, each generated once by CasADi and compiled by the C compiler
softcurve uses, with every flag set below; one evaluation is timed inside C (a loop of
calls, best of ``--repeat`` runs, alternating the builds so that a slow minute of the
machine hits them alike):

1. ``rhs`` and ``dynamics_terms``: the model's right-hand side ``(x, tau, p) -> xdot``
   and its terms ``D, C qd, N, R qd`` (the model library's two large functions, compiled
   with ``FUNCTION_FLAGS -march=native``); ``--robot two-segment`` takes them from the
   robot of examples/two-segment.toml instead (its build is what a new robot waits for);
2. ``stepper``: one 20 ms control period of the environments' stepper (ROS34PW2 x 16,
   actuator lag; compiled by :func:`softcurve.compiled.compile_function`);
3. ``sensitivity``: the identification's augmented right-hand side (state and five
   sensitivity columns, ``benchmarks/bench_identification.py``'s case; compiled by
   ``compile_function``).

``--quick`` skips the ``-O2``/``-O3`` builds of the sensitivity function (about 150 s
each). The flags softcurve uses for each are marked with ``*``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import softcurve as sc
from softcurve.compiled import _build as build
from softcurve.simulation.sensitivity import _sensitivity as sensitivity
from softcurve.simulation.solvers._cvodes import ActuatorInput
from softcurve.simulation.stepper import _scheme as stepper_scheme
from softcurve.simulation.stepper._scheme import period_function
from softcurve.simulation.stepper._stepper import DEFAULT_METHOD, DEFAULT_SUBSTEPS

sys.path.insert(0, str(Path(__file__).parent))
import bench_identification
from bench_stepper import PERIOD, paper_actuator

HARNESS = r"""
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
int %(name)s(const double** arg, double** res, long long* iw, double* w, int mem);
int main(int argc, char** argv) {
  static double in[%(n_in)d][%(width)d], out[%(width_out)d], w[%(sz_w)d + 1];
  static long long iw[%(sz_iw)d + 1];
  static const double* arg[%(sz_arg)d + 1];
  static double* res[%(sz_res)d + 1];
  long calls = atol(argv[1]), k;
  int i, j;
  res[0] = out;
  for (i = 0; i < %(n_in)d; ++i) {
    for (j = 0; j < %(width)d; ++j)
      if (scanf("%%lf", &in[i][j]) != 1) return 2;
    arg[i] = in[i];
  }
  struct timespec a, b;
  double checksum = 0;
  clock_gettime(CLOCK_MONOTONIC, &a);
  for (k = 0; k < calls; ++k) {
    in[0][1] += 1e-12 * (k & 7);  /* defeat hoisting */
    %(name)s(arg, res, iw, w, 0);
    checksum += out[0];
  }
  clock_gettime(CLOCK_MONOTONIC, &b);
  printf("%%.6e %%.17g\n", ((b.tv_sec - a.tv_sec) + 1e-9 * (b.tv_nsec - a.tv_nsec)) / calls,
         checksum);
  return 0;
}
"""

FLAG_SETS = {
    "-O0": ("-O0",),
    "-O0 -march=native": ("-O0", "-march=native"),
    "-O1": ("-O1",),
    "-O1 -march=native": ("-O1", "-march=native"),
    "-O1 -march=native -ftree-slp-vectorize -fschedule-insns2": (
        "-O1", "-march=native", "-ftree-slp-vectorize", "-fschedule-insns2",
    ),
    "-O2 -march=native": ("-O2", "-march=native"),
    # softcurve's FUNCTION_FLAGS (-O2 without GCSE, PRE and code hoisting)
    " ".join(build.FUNCTION_FLAGS + build._NATIVE_FLAGS): (
        build.FUNCTION_FLAGS + build._NATIVE_FLAGS
    ),
    "-O3 -march=native": ("-O3", "-march=native"),
}  # fmt: skip
USED = {
    "rhs": build.FUNCTION_FLAGS + build._NATIVE_FLAGS,  # the model library's
    "dynamics_terms": build.FUNCTION_FLAGS + build._NATIVE_FLAGS,
    "stepper": stepper_scheme.STEPPER_FLAGS + build._NATIVE_FLAGS,
    "sensitivity": build.FUNCTION_FLAGS + build._NATIVE_FLAGS,
}
SLOW = ("-O2 -march=native", "-O3 -march=native")


def paper_model_and_inputs():
    model = sc.Model(sc.presets.ifac2020())
    return model, ActuatorInput.of(paper_actuator(), model.n)


def captured_function(module, run, name=None):
    """The CasADi Function that ``run()`` hands to ``module.compile_function``, or the
    one called ``name`` among those it hands to ``module.compile_functions``."""
    captured = {}
    single = module.compile_function
    several = getattr(module, "compile_functions", None)

    def capture(function, *args, **kwargs):
        captured["f"] = function
        return single(function, *args, **kwargs)

    def capture_several(functions, *args, **kwargs):
        for function in functions:
            if function.name() == name:
                captured["f"] = function
        return several(functions, *args, **kwargs)

    module.compile_function = capture
    if several is not None:
        module.compile_functions = capture_several
    try:
        run()
    finally:
        module.compile_function = single
        if several is not None:
            module.compile_functions = several
    return captured["f"]


def _model_functions(model, q):
    """The model library's two large functions, with a moving state inside the domain."""
    x = np.zeros(model.n_state)
    x[: model.n] = q
    x[model.n : 2 * model.n] = np.resize([0.01, 3.0, -2.0], model.n)
    yield "rhs", model.symbolic["rhs"], [x, np.zeros(model.n), model.parameters]
    terms = model.symbolic["dynamics_terms"]
    values = [x[: model.n], x[model.n : 2 * model.n], model.parameters]
    if terms.n_in() > len(values):  # the creep states
        values.insert(2, np.zeros(terms.size1_in(2)))
    yield "dynamics_terms", terms, values


def cases(robot: str):
    """(label, SX/MX Function, input values) of the functions."""
    if robot == "two-segment":
        config = sc.load_config(Path(__file__).parents[1] / "examples" / "two-segment.toml")
        model = sc.Model(config.robot, environment=config.environment)
        q = np.resize([0.064, 25.0, -10.0], model.n)
        yield from _model_functions(model, q)
        return
    model, inputs = paper_model_and_inputs()
    x = np.zeros(model.n_state)
    x[:3] = [0.064, 25.0, -10.0]
    x[3:6] = [0.01, 3.0, -2.0]
    yield from _model_functions(model, x[:3])
    stepper = captured_function(
        stepper_scheme, lambda: period_function(model, inputs, DEFAULT_SUBSTEPS, DEFAULT_METHOD)
    )
    xu = np.concatenate([x, np.full(inputs.n_inputs, 2e4)])
    commands = np.full(inputs.n_inputs, 3e4)
    yield "stepper", stepper, [xu, commands, model.parameters, np.array([PERIOD])]
    f = captured_function(
        sensitivity,
        lambda: bench_identification.dynamic_evaluator(1.0, "linear"),
        "softcurve_sensitivity",
    )
    rng = np.random.default_rng(0)
    values = [rng.random(f.size1_in(i)) for i in range(f.n_in())]
    values[0][0] = 0.064
    values[2][: model.parameters.size] = model.parameters
    yield "sensitivity", f, values


def compile_and_time(function, values, flags, calls, directory):
    """(compile seconds, callable returning one evaluation's seconds) of ``function``."""
    name = function.name()
    source = Path(directory, f"{name}.c")
    if not source.exists():
        function.generate(f"{name}.c", {"with_header": False})
        os.replace(f"{name}.c", source)
        width = max(v.size for v in values)
        Path(directory, "harness.c").write_text(
            HARNESS
            % dict(
                name=name,
                n_in=len(values),
                width=width,
                width_out=function.nnz_out(0),
                sz_w=function.sz_w(),
                sz_iw=function.sz_iw(),
                sz_arg=function.sz_arg(),
                sz_res=function.sz_res(),
            )
        )
        padded = [np.pad(v.astype(float), (0, width - v.size)) for v in values]
        Path(directory, "input.txt").write_text(
            "\n".join(" ".join(repr(float(a)) for a in v) for v in padded)
        )
    binary = Path(directory, "run_" + "".join(f.strip("-=") for f in flags))
    compiler = build.find_compiler()
    start = time.perf_counter()
    subprocess.run(
        [*compiler, *flags, str(source), str(Path(directory, "harness.c"))]
        + ["-o", str(binary), "-lm"],
        check=True,
        capture_output=True,
    )
    built = time.perf_counter() - start

    def run():
        with open(Path(directory, "input.txt")) as stdin:
            out = subprocess.run(
                [str(binary), str(calls)], stdin=stdin, capture_output=True, text=True, check=True
            )
        return float(out.stdout.split()[0])

    return built, run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip -O2/-O3 of the sensitivity")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument(
        "--only", type=lambda text: text.split(","), help="these functions only (comma list)"
    )
    parser.add_argument("--robot", choices=("paper", "two-segment"), default="paper")
    args = parser.parse_args()
    compiler = build.find_compiler()
    print(f"load average {os.getloadavg()}, {os.cpu_count()} cores, compiler {compiler}")
    calls_of = {"rhs": 100_000, "dynamics_terms": 100_000, "stepper": 2_000}
    for label, function, values in cases(args.robot):
        if args.only is not None and label not in args.only:
            continue
        calls = calls_of.get(label, 10_000) // (10 if args.robot == "two-segment" else 1)
        print(f"\n{label}: {function.n_instructions()} instructions in CasADi's graph")
        with tempfile.TemporaryDirectory() as directory:
            runs = {}
            for name, flags in FLAG_SETS.items():
                if args.quick and label == "sensitivity" and name in SLOW:
                    continue
                mark = " *" if flags == USED[label] else ""
                runs[name + mark] = compile_and_time(function, values, flags, calls, directory)
            best = {name: np.inf for name in runs}
            for _ in range(args.repeat):
                for name, (_, run) in runs.items():
                    best[name] = min(best[name], run())
            reference = best["-O1"]
            for name, (built, _) in runs.items():
                print(
                    f"  {name:48s} compile {built:6.1f} s   {best[name] * 1e6:9.2f} us"
                    f"   {reference / best[name]:4.2f}x -O1"
                )


if __name__ == "__main__":
    main()
