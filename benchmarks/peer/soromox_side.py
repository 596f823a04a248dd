"""The SoRoMoX side of the peer comparison (benchmarks/bench_peer.py).

Run by the peer's own Python (a separate virtual environment with ``soromox``; see
docs/strains.md), never imported by softcurve::

    /path/to/peer-venv/bin/python benchmarks/peer/soromox_side.py CASE.json RESULT.json

``CASE.json`` describes the robot in softcurve's conventions (written by
``bench_peer.py``); this script is the one place that translates it into SoRoMoX's
public API (``soromox.PCS``, ``soromox.LinkSpec``, ``soromox.PCSStructure``,
``soromox.SystemState``, ``PCS.rollout_to``) and the results back.

The map between the conventions (read from soromox 0.5.0's ``systems/pcs/pcs.py``):

- Backbone axis. softcurve's slice frame has ``z`` along the backbone and the strains
  ``(u_x, u_y, u_z, v_x, v_y, v_z)`` (bend x, bend y, twist, shear x, shear y,
  stretch). SoRoMoX's material frame has ``x`` along the backbone and the strains
  ``(kappa_x, kappa_y, kappa_z, sigma_x, sigma_y, sigma_z)`` (twist, bend y, bend z,
  stretch, shear y, shear z). With the peer's axes ``(x, y, z) = `` softcurve's
  ``(z, x, y)`` (a cyclic, right-handed relabelling, ``P = [e_z, e_x, e_y]``) the
  peer's strains are softcurve's ``(u_z, u_x, u_y, v_z, v_x, v_y)``: same signs, no
  sign flips. The peer's base rotation is softcurve's base rotation times ``P``, so
  both backbones leave the base along the same world direction and a peer frame ``R_s``
  is softcurve's ``R_s P^T`` (reported that way).
- Coordinates. SoRoMoX's ``q`` is the strain minus the reference strain
  (``xi = B q + xi_ref``, ``B`` selecting the active strains); softcurve's are the
  strains themselves. Results are returned as strains.
- Stiffness. ``LinkSpec.circular(young_modulus=E, shear_modulus=G)`` builds, per link,
  ``L diag(G J, E I, E I, E A, G A, G A)`` with ``J = 2 I = pi r^4 / 2`` and no shear
  coefficient (``k = 1``): the energy ``1/2 L (xi - xi*)^T K (xi - xi*)`` of
  ``softcurve.StrainSegment`` with ``K = diag(E I, E I, G J, G A, G A, E A)`` in softcurve's order.
- Inertia. Per unit reference length ``rho diag(J, I, I, A, A, A)`` (peer's order),
  i.e. mass ``rho A`` and rotary inertia per unit mass ``r^2 (1/2, 1/4, 1/4)`` about
  (backbone, transverse, transverse): softcurve's default ``slice_inertia``
  ``r^2 (1/4, 1/4, 1/2)`` in its own order. Mass and gravity integrals use
  ``num_gauss_points`` Gauss-Legendre points per link.
- Damping. An explicit generalized matrix per link (``tau = -D xi_dot``), given in
  softcurve's order and permuted here.
- Statics. SoRoMoX has no equilibrium solver; the static shape is the root of its
  public ``potential_force(q)`` (gravity plus elastic force) found by Newton's method
  with the Jacobian by ``jax.jacfwd``, from the rest configuration.
- Trajectory. ``PCS.rollout_to`` (diffrax; Tsit5 with a PID step-size controller at
  the case's ``rtol``/``atol``), tip position from ``forward_kinematics`` at
  ``s = L_total``.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import soromox  # noqa: E402
from soromox.utils.geometry.rotations import (  # noqa: E402
    quaternion_to_rotation_matrix,
    rotation_matrix_to_quaternion,
)

# softcurve's strain names in its canonical order, and where each sits in the peer's
# per-link strain vector (kappa_x, kappa_y, kappa_z, sigma_x, sigma_y, sigma_z)
STRAINS = ("bend_x", "bend_y", "twist", "shear_x", "shear_y", "stretch")
PEER_INDEX = np.array([1, 2, 0, 4, 5, 3])  # ours[i] = peer[PEER_INDEX[i]]
# the peer's material axes (x, y, z) in softcurve's slice frame: z, x, y
AXES = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def to_peer(ours: np.ndarray) -> np.ndarray:
    """Reorder a (..., 6) array from softcurve's strain order to the peer's."""
    ours = np.asarray(ours, dtype=float)
    peer = np.empty_like(ours)
    peer[..., PEER_INDEX] = ours
    return peer


def to_ours(peer: np.ndarray) -> np.ndarray:
    """Reorder a (..., 6) array from the peer's strain order to softcurve's."""
    return np.asarray(peer, dtype=float)[..., PEER_INDEX]


def build(case: dict) -> soromox.PCS:
    """The case's robot as a spatial SoRoMoX PCS model."""
    n = case["n_segments"]
    rest = np.asarray(case["rest_strain"], dtype=float).reshape(n, 6)
    damping = np.asarray(case["damping"], dtype=float).reshape(n, 6)
    links = [
        soromox.LinkSpec.circular(
            length=case["rest_length"],
            radius=case["radius"],
            density=case["density"],
            reference_strain=jnp.asarray(to_peer(rest[i])),
            young_modulus=case["youngs_modulus"],
            shear_modulus=case["shear_modulus"],
            damping=jnp.diag(jnp.asarray(to_peer(damping[i]))),
        )
        for i in range(n)
    ]
    chosen = np.array([name in case["strains"] for name in STRAINS])
    selector = np.tile(to_peer(chosen.astype(float)) > 0.5, n)
    rotation = np.asarray(case["base_rotation"], dtype=float) @ AXES
    quaternion = rotation_matrix_to_quaternion(jnp.asarray(rotation))
    if not np.allclose(quaternion_to_rotation_matrix(quaternion), rotation, atol=1e-12):
        raise RuntimeError("the peer's quaternion does not reproduce the base rotation")
    return soromox.PCS.from_links(
        links,
        structure=soromox.PCSStructure(
            num_gauss_points=case["num_gauss_points"],
            strain_selector=jnp.asarray(selector),
        ),
        gravity=jnp.asarray(case["gravity"], dtype=float),
        base_pose=jnp.concatenate([quaternion, jnp.zeros(3)]),
        backend="jax",
    )


def coordinates(case: dict, strains: np.ndarray) -> np.ndarray:
    """The peer's q (active strains minus reference) of per-segment strains (ours)."""
    n = case["n_segments"]
    peer = to_peer(np.asarray(strains, dtype=float).reshape(n, 6))
    rest = to_peer(np.asarray(case["rest_strain"], dtype=float).reshape(n, 6))
    chosen = to_peer(np.array([name in case["strains"] for name in STRAINS], float)) > 0.5
    return (peer - rest)[:, chosen].reshape(-1)


def strains_of(case: dict, q: np.ndarray) -> np.ndarray:
    """Per-segment strains (N, 6) in softcurve's order of the peer's q."""
    n = case["n_segments"]
    chosen = to_peer(np.array([name in case["strains"] for name in STRAINS], float)) > 0.5
    peer = to_peer(np.asarray(case["rest_strain"], dtype=float).reshape(n, 6))
    peer[:, chosen] += np.asarray(q).reshape(n, -1)
    return to_ours(peer)


@eqx.filter_jit
def _residual(robot: soromox.PCS, q: jnp.ndarray) -> jnp.ndarray:
    return robot.potential_force(q)


@eqx.filter_jit
def _jacobian(robot: soromox.PCS, q: jnp.ndarray) -> jnp.ndarray:
    return jax.jacfwd(robot.potential_force)(q)


def solve_static(robot: soromox.PCS, q0: jnp.ndarray, tol: float, max_iter: int) -> tuple:
    """Newton's method on the peer's potential force; (q, iterations, |residual|)."""

    def residual(q):
        return _residual(robot, q)

    def jacobian(q):
        return _jacobian(robot, q)

    q = q0
    for iteration in range(1, max_iter + 1):
        f = residual(q)
        step = jnp.linalg.solve(jacobian(q), -f)
        # halve the step while it does not reduce the residual (the first steps from
        # the rest shape under a large load can overshoot)
        for _ in range(30):
            trial = q + step
            if float(jnp.linalg.norm(residual(trial))) < float(jnp.linalg.norm(f)):
                break
            step = step / 2
        q = trial
        if float(jnp.linalg.norm(step)) < tol:
            return q, iteration, float(jnp.linalg.norm(residual(q)))
    raise RuntimeError(f"Newton did not converge in {max_iter} iterations")


def pose(robot: soromox.PCS, q: jnp.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
    """World position (3,) and softcurve-convention rotation (3, 3) at arc length s."""
    g = np.asarray(robot.forward_kinematics(q, jnp.asarray(s)))
    return g[:3, 3], g[:3, :3] @ AXES.T


def map_error(case: dict, robot: soromox.PCS) -> float:
    """Largest entry of the difference between the peer's tip transform and softcurve's
    convention, ``g = G_base prod_i expm(L0 hat(xi_i))`` with ``xi = (u, v)`` in the
    slice frame (z along the backbone), at distinct strains (all six nonzero): checks
    the map of strains, axes and base rotation."""
    from scipy.linalg import expm

    n, length = case["n_segments"], case["rest_length"]
    strains = np.array([[1.0, -2.0, 3.0, 0.1, -0.2, 1.1]]) * np.arange(1, n + 1)[:, None] ** 0.5
    expected = np.eye(4)
    expected[:3, :3] = np.asarray(case["base_rotation"], dtype=float)
    for ux, uy, uz, vx, vy, vz in strains:
        twist = np.array(
            [[0, -uz, uy, vx], [uz, 0, -ux, vy], [-uy, ux, 0, vz], [0, 0, 0, 0]], dtype=float
        )
        expected = expected @ expm(length * twist)
    q = jnp.asarray(coordinates(case, strains))
    position, rotation = pose(robot, q, n * length)
    return float(
        max(np.abs(position - expected[:3, 3]).max(), np.abs(rotation - expected[:3, :3]).max())
    )


def run(case: dict) -> dict:
    """Build, solve the statics, integrate the free motion; timings cold and warm."""
    start = time.perf_counter()
    robot = build(case)
    build_time = time.perf_counter() - start
    total = case["n_segments"] * case["rest_length"]
    n_q = int(robot.num_internal_dofs)
    error = map_error(case, robot) if len(case["strains"]) == len(STRAINS) else None
    if error is not None and error > 1e-12:
        raise RuntimeError(f"the peer's kinematics differ from softcurve's by {error:.3g}")
    q_rest = jnp.zeros(n_q)

    static_times = []
    for _ in range(2):
        start = time.perf_counter()
        q_static, iterations, residual = solve_static(
            robot, q_rest, case["static_tol"], case["static_max_iter"]
        )
        q_static.block_until_ready()
        static_times.append(time.perf_counter() - start)
    tip_position, tip_rotation = pose(robot, q_static, total)
    s_grid = np.linspace(0.0, 1.0, case["n_backbone"])
    backbone = np.array([pose(robot, q_static, s * total)[0] for s in s_grid])

    t_out = np.arange(case["n_out"]) * case["t_final"] / (case["n_out"] - 1)
    q0 = jnp.asarray(coordinates(case, case["initial_strain"]))
    state = soromox.SystemState(t=jnp.asarray(0.0), y=robot.pack_state(q0, jnp.zeros(n_q)))
    controller = diffrax.PIDController(rtol=case["rtol"], atol=case["atol"])
    rollout = eqx_rollout(robot)
    trajectory_times = []
    for _ in range(2):
        start = time.perf_counter()
        t_saved, y_saved = rollout(
            state, jnp.asarray(t_out), controller, case["t_final"], case["max_steps"]
        )
        y_saved.block_until_ready()
        trajectory_times.append(time.perf_counter() - start)
    q_t = y_saved[:, :n_q]
    tip_of = jax.jit(jax.vmap(lambda q: robot.forward_kinematics(q, jnp.asarray(total))[:3, 3]))
    tip_t = np.asarray(tip_of(q_t))

    return {
        "peer": "soromox",
        "peer_version": soromox.__version__,
        "jax_version": jax.__version__,
        "python": platform.python_version(),
        "n_q": n_q,
        "build_time": build_time,
        "kinematics_map_error": error,
        "static": {
            "strains": strains_of(case, np.asarray(q_static)).tolist(),
            "tip_position": tip_position.tolist(),
            "tip_rotation": tip_rotation.tolist(),
            "backbone_s": s_grid.tolist(),
            "backbone": backbone.tolist(),
            "newton_iterations": iterations,
            "residual_norm": residual,
            "time_cold": static_times[0],
            "time_warm": static_times[1],
        },
        "trajectory": {
            "t": np.asarray(t_saved).tolist(),
            "tip_position": tip_t.tolist(),
            "final_strains": strains_of(case, np.asarray(q_t[-1])).tolist(),
            "time_cold": trajectory_times[0],
            "time_warm": trajectory_times[1],
        },
    }


def eqx_rollout(robot: soromox.PCS):
    """The peer's open-loop rollout on an adaptive Tsit5, compiled as one function
    (its first call traces and compiles, later calls reuse it)."""

    @eqx.filter_jit
    def rollout(robot, state, t_out, controller, t_final, max_steps):
        states = robot.rollout_to(
            state,
            t1=t_final,
            # the first trial step; the controller adapts it
            solver_dt=1e-5,
            save_ts=t_out,
            solver=diffrax.Tsit5(),
            stepsize_controller=controller,
            max_steps=max_steps,
        )
        return states.t, states.y

    return lambda *args: rollout(robot, *args)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", type=Path, help="the case (JSON, softcurve's conventions)")
    parser.add_argument("result", type=Path, help="where to write the results (JSON)")
    args = parser.parse_args(argv)
    case = json.loads(args.case.read_text())
    result = run(case)
    args.result.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
