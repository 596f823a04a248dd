"""The tendon plan of ``bench_planning.py --tendons`` with its dynamics written explicitly or
implicitly at the collocation stages: does IPOPT converge on chains of many segments when
the stages' equations avoid the inverse of the mass matrix?

Both formulations keep, per step of Radau IIA, the stage increments ``Z`` and the slopes
``S`` as unknowns, tied by ``Z = h S A^T`` and the continuity of the nodes; they differ in
the equation each stage's slope meets:

- ``explicit``: ``S - f(x, u) = 0``, ``f`` the actuated right-hand side
  (``Transcription.rhs``, with ``D(q)^-1`` inside);
- ``implicit``: ``S_q - qd = 0`` and ``ID(q, qd, S_qd) - tau(q, u) = 0``, ``ID`` the
  model's inverse dynamics (``Model.symbolic["inverse_dynamics"]``, no inverse of ``D``)
  and ``tau`` the tendons' generalized force.

Each stage's equations are compiled with their second derivatives, and the Hessian of the
Lagrangian and the Jacobian of the constraints are assembled stage by stage, as
``optimize_trajectory`` assembles its own. The task is ``--tendons``' without the rest at
the end: 1 s in 20 steps, the tip within 2 mm of ``TENDON_GOAL`` at the end (and its
squared distance over the squared rest length in the cost), the tensions' effort weighted
by ``--effort-weight``, from the straight start held by the rest tensions as the first
guess. It prints IPOPT's iterations, status, solve time and the last iterate's
constraint violation.

Run:  python benchmarks/study_implicit_dynamics.py [--segments 6 10]
      [--formulations explicit implicit] [--effort-weight 1] [--iterations 150]
"""

from __future__ import annotations

import argparse
import time

import casadi as ca
import numpy as np
from bench_planning import TENDON_GOAL, tendon_chain  # the robot of --tendons

import softcurve as sc
from softcurve.compiled import compile_function
from softcurve.simulation.solvers import nominal_scale

INTERVALS, HORIZON, TOLERANCE = 20, 1.0, 2e-3
"""The plan of ``bench_planning.py --tendons``: steps, horizon [s], tip tolerance [m]."""


def stage_equations(tr, formulation: str, x0: np.ndarray, x_scale: np.ndarray, h: float):
    """``(x, u, s) -> r`` (n_x,): a stage's slope equation, compiled with its second
    derivatives; the rows scaled to order one at a slope of one state scale per step (the
    accelerations' by the mass matrix's diagonal at the start: the force of such a slope)."""
    model, n = tr.model, tr.model.n
    x, u, s = ca.SX.sym("x", tr.n_x), ca.SX.sym("u", tr.n_u), ca.SX.sym("s", tr.n_x)
    p = ca.DM(tr.parameters)
    slope_scale = x_scale / h
    if formulation == "explicit":
        rows = (s - tr.rhs_sx(x, u, p)) / slope_scale
    else:
        xm, um = ca.MX.sym("x", tr.n_x), ca.MX.sym("u", tr.n_u)
        force = ca.Function("tau", [xm, um], [tr.inputs.force(xm[:n], um)]).expand()
        inverse = model.symbolic["inverse_dynamics"](x[:n], x[n:], s[n:], ca.SX(0, 1), p)
        mass = np.diag(np.asarray(model.mass_matrix(x0[:n])))
        rows = ca.vertcat((s[:n] - x[n:]) / slope_scale[:n],
                          (inverse - force(x, u)) / (mass * slope_scale[n:]))  # fmt: skip
    function = ca.Function(f"stage_{formulation}", [x, u, s], [rows])
    return compile_function(function, flags=("-O1",), derivatives=2)


def plan(segments: int, formulation: str, effort: float, iterations: int) -> dict:
    """IPOPT's solve of the plan on a chain of ``segments`` segments."""
    model, actuator, q0 = tendon_chain(segments)
    tr = sc.Transcription(model, actuator)
    if tr.n_x != 2 * model.n:
        raise ValueError("the study's robot has no creep and no lag")
    n_x, n_u, K, stages = tr.n_x, tr.n_u, INTERVALS, tr.stages
    h, x0 = HORIZON / K, tr.start(q0)
    x_scale = nominal_scale(model, x0)
    lower_u, upper_u = tr.input_bounds
    span, rest_u = upper_u - lower_u, actuator.rest_inputs()
    equations = stage_equations(tr, formulation, x0, x_scale, h)
    p = ca.DM(tr.parameters)

    # unknowns, scaled: nodes, tensions, stage increments, slopes
    X, U = ca.MX.sym("X", n_x, K + 1), ca.MX.sym("U", n_u, K)
    Z, S = ca.MX.sym("Z", n_x, stages * K), ca.MX.sym("S", n_x, stages * K)
    w = ca.vertcat(ca.vec(X), ca.vec(U), ca.vec(Z), ca.vec(S))
    Xp, Up = X * ca.DM(x_scale), U * ca.DM(span) + ca.DM(lower_u)
    Zp, Sp = Z * ca.DM(x_scale), S * ca.DM(x_scale / h)
    repeat = ca.DM(np.kron(np.eye(K), np.ones((1, stages))))
    x_stages, u_stages = ca.mtimes(Xp[:, :K], repeat) + Zp, ca.mtimes(Up, repeat)
    linear = []  # the collocation equations and the continuity, as the planner's
    for k in range(K):
        z, slopes = Zp[:, stages * k : stages * (k + 1)], Sp[:, stages * k : stages * (k + 1)]
        collocation, following = tr.collocation_equations(Xp[:, k], z, slopes, h)
        linear.append(ca.vec(collocation / ca.DM(x_scale)))
        linear.append((Xp[:, k + 1] - following) / ca.DM(x_scale))
    margins = ca.vec(tr.domain.map(K)(Xp[:, 1:], p))
    miss = ca.sumsqr(tr.tip(Xp[:, -1], p) - ca.DM(TENDON_GOAL))
    others = ca.vertcat(*linear, margins, miss)
    residual = ca.vec(equations.map(stages * K)(x_stages, u_stages, Sp))
    g = ca.vertcat(residual, others)
    length = float(model.robot.rest_length)
    cost = effort * ca.sumsqr((Up - ca.DM(rest_u)) / ca.DM(span)) / K + miss / length**2

    # the stages' equations differentiated stage by stage, the rest by CasADi
    xa, ua, sa, mu = (ca.MX.sym(name, size) for name, size in
                      (("x", n_x), ("u", n_u), ("s", n_x), ("mu", n_x)))  # fmt: skip
    at = ca.vertcat(xa, ua, sa)
    r = equations(xa, ua, sa)
    width = at.numel()
    hessians = ca.Function("h", [xa, ua, sa, mu], [ca.densify(ca.hessian(ca.dot(mu, r), at)[0])])
    jacobians = ca.Function("j", [xa, ua, sa], [ca.densify(ca.jacobian(r, at))])
    count = stages * K
    carry = ca.jacobian(ca.vec(ca.vertcat(x_stages, u_stages, Sp)), w)
    carry = ca.DM(ca.Function("carry", [w], [carry])(np.zeros(w.numel())))
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.numel())
    rows = residual.numel()
    held = ca.hessian(lam_f * cost + ca.dot(lam_g[rows:], others), w)[0]
    blocks = hessians.map(count, "thread", 2)(x_stages, u_stages, Sp,
                                              ca.reshape(lam_g[:rows], n_x, count))  # fmt: skip
    hessian = held + ca.mtimes([carry.T, ca.diagcat(*ca.horzsplit(blocks, width)), carry])
    blocks = jacobians.map(count, "thread", 2)(x_stages, u_stages, Sp)
    jacobian = ca.vertcat(ca.mtimes(ca.diagcat(*ca.horzsplit(blocks, width)), carry),
                          ca.jacobian(others, w))  # fmt: skip
    none = ca.MX(0, 1)
    options = {
        "hess_lag": ca.Function("nlp_hess_l", [w, none, lam_f, lam_g], [ca.triu(hessian)],
                                ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]),
        "jac_g": ca.Function("nlp_jac_g", [w, none], [g, jacobian], ["x", "p"],
                             ["g", "jac_g_x"]),
        "calc_lam_p": False, "print_time": False,
        "ipopt.max_iter": iterations, "ipopt.tol": 1e-8, "ipopt.print_level": 0, "ipopt.sb": "yes",
    }  # fmt: skip
    solver = ca.nlpsol("study", "ipopt", {"x": w, "f": cost, "g": g}, options)

    lower_w, upper_w = np.full(w.numel(), -np.inf), np.full(w.numel(), np.inf)
    lower_w[:n_x] = upper_w[:n_x] = x0 / x_scale
    inputs = slice(n_x * (K + 1), n_x * (K + 1) + n_u * K)
    lower_w[inputs], upper_w[inputs] = 0.0, 1.0
    equalities = np.zeros(rows + sum(e.numel() for e in linear))
    lower_g = np.concatenate([equalities, np.zeros(margins.numel()), [0.0]])
    upper_g = np.concatenate([equalities, np.full(margins.numel(), np.inf), [TOLERANCE**2]])
    slope = np.asarray(tr.rhs(x0, rest_u, tr.parameters)).ravel() / (x_scale / h)
    guess = np.concatenate([np.tile(x0 / x_scale, K + 1), np.tile((rest_u - lower_u) / span, K),
                            np.zeros(n_x * count), np.tile(slope, count)])  # fmt: skip
    began = time.perf_counter()
    solution = solver(x0=guess, lbx=lower_w, ubx=upper_w, lbg=lower_g, ubg=upper_g)
    solve = time.perf_counter() - began
    values = np.asarray(solution["g"]).ravel()
    violation = max(0.0, float(np.max(np.maximum(lower_g - values, values - upper_g))))
    stats = solver.stats()
    return {"iterations": stats["iter_count"], "status": stats["return_status"],
            "solve": solve, "violation": violation}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[6, 10])
    parser.add_argument("--formulations", nargs="+", default=["explicit", "implicit"],
                        choices=("explicit", "implicit"))  # fmt: skip
    parser.add_argument("--effort-weight", type=float, default=1.0)
    parser.add_argument("--iterations", type=int, default=150)
    args = parser.parse_args()
    odd = [n for n in args.segments if n < 2 or n % 2]
    if odd:
        parser.error(f"--segments must be even numbers of at least 2, got {odd}")
    if not args.effort_weight > 0 or args.iterations < 1:
        parser.error("--effort-weight must be positive and --iterations at least 1, got "
                     f"{args.effort_weight} and {args.iterations}")  # fmt: skip
    print(f"effort weight {args.effort_weight:g}, at most {args.iterations} iterations")
    print("| segments | formulation | iterations | IPOPT's status | solve [s] | violation |")
    print("| --- | --- | --- | --- | --- | --- |")
    for segments in args.segments:
        for formulation in args.formulations:
            r = plan(segments, formulation, args.effort_weight, args.iterations)
            print(f"| {segments} | {formulation} | {r['iterations']} | {r['status']} | "
                  f"{r['solve']:.1f} | {r['violation']:.1e} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
