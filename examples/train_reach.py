"""Train a policy on softcurve/Reach-v0 with Stable-Baselines3 (PPO or SAC) on the native
vector environment, and write what it learned into an output folder:

- ``learning_curve.csv`` and ``learning_curve.png``: mean episode return and success
  rate of the last 100 episodes against environment steps;
- ``rollout.png``: one episode of the trained policy (tip against target, distance);
- ``rollout.html``: the same episode in the 3-D viewer (with Plotly installed);
- ``policy.zip``: the trained model.

Set-up (CPU only)::

    # first, the CPU build from PyTorch's index (plain `torch` pulls a several-GB CUDA build)
    pip install torch --index-url https://download.pytorch.org/whl/cpu
    pip install "softcurve[rl]"  # gymnasium and stable-baselines3

Run ``python examples/train_reach.py --help`` for the options; docs/envs.md quotes the
wall time and final success rate of a run with the defaults.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path


def _arguments(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--algo", choices=("ppo", "sac"), default="ppo", help="the algorithm")
    parser.add_argument("--steps", type=int, default=3_000_000,
                        help="environment steps at most (see --minutes)")  # fmt: skip
    parser.add_argument("--envs", type=int, default=32, help="robots in the vector env")
    parser.add_argument("--seed", type=int, default=0, help="seed of the run")
    parser.add_argument("--minutes", type=float, default=11.0,
                        help="stop learning after this wall time [min] (the steps reached "
                        "are printed)")  # fmt: skip
    parser.add_argument("--output", type=Path, default=Path("train-reach"), help="folder")
    return parser.parse_args(argv)


def sb3_vector_env(env):
    """Stable-Baselines3's ``VecEnv`` view of a Gymnasium vector environment with
    same-step autoreset (softcurve's): final observations become
    ``infos[i]["terminal_observation"]``, truncations ``"TimeLimit.truncated"``.

    Parameters
    ----------
    env : gymnasium.vector.VectorEnv
        The vector environment (e.g. ``gymnasium.make_vec("softcurve/Reach-v0", ...)``).
    """
    import numpy as np
    from stable_baselines3.common.vec_env import VecEnv

    class Adapter(VecEnv):
        def __init__(self):
            super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)
            self._actions = None

        def reset(self):
            seed = self._seeds[0] if self._seeds and self._seeds[0] is not None else None
            observation, _ = env.reset(seed=seed)
            self._reset_seeds()
            return observation

        def step_async(self, actions):
            self._actions = actions

        def step_wait(self):
            observation, reward, terminated, truncated, info = env.step(self._actions)
            done = terminated | truncated
            infos = [{} for _ in range(self.num_envs)]
            for i in np.flatnonzero(done):
                infos[i]["terminal_observation"] = info["final_obs"][i]
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                infos[i]["is_success"] = bool(info["final_info"]["is_success"][i])
            return observation, reward.astype(np.float32), done, infos

        def close(self):
            env.close()

        def get_attr(self, attr_name, indices=None):
            return [getattr(env, attr_name)] * len(self._get_indices(indices))

        def set_attr(self, attr_name, value, indices=None):
            setattr(env, attr_name, value)

        def env_method(self, method_name, *args, indices=None, **kwargs):
            raise NotImplementedError("one batch, no member environments")

        def env_is_wrapped(self, wrapper_class, indices=None):
            return [False] * len(self._get_indices(indices))

    return Adapter()


def _rollout(model, env_single, seed: int):
    """One deterministic episode: times, tips, targets, distances and states."""
    import numpy as np

    observation, info = env_single.reset(seed=seed)
    rows, states = (
        [(0.0, info["tip"], info["target"], info["distance"])],
        [env_single.episodes.x[0].copy()],
    )
    done = False
    while not done:
        action, _ = model.predict(observation, deterministic=True)
        observation, _, terminated, truncated, info = env_single.step(action)
        rows.append((info["time"], info["tip"], info["target"], info["distance"]))
        states.append(env_single.episodes.x[0].copy())
        done = terminated or truncated
    t = np.array([r[0] for r in rows])
    return (
        t,
        np.array([r[1] for r in rows]),
        np.array([r[2] for r in rows]),
        np.array([r[3] for r in rows]),
        np.array(states),
        info,
    )


def _success_rate(model, vector, seed: int) -> float:
    """Success at the end of one episode of every member of ``vector`` (fresh targets,
    deterministic policy)."""
    import numpy as np

    observation, _ = vector.reset(seed=seed)
    while True:
        action, _ = model.predict(observation, deterministic=True)
        observation, _, terminated, truncated, info = vector.step(action)
        if np.all(terminated | truncated):  # equal episode lengths: all end together
            return float(np.mean(info["final_info"]["is_success"]))


def main(argv=None) -> int:
    args = _arguments(argv)
    import gymnasium
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor

    import softcurve.envs as envs

    args.output.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    vector = gymnasium.make_vec("softcurve/Reach-v0", num_envs=args.envs)
    venv = VecMonitor(sb3_vector_env(vector))
    venv.seed(args.seed)
    curve = []

    class Curve(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % (10 * args.envs) == 0 and self.model.ep_info_buffer:
                returns = [e["r"] for e in self.model.ep_info_buffer]
                success = list(self.model.ep_success_buffer) or [np.nan]
                curve.append((self.num_timesteps, np.mean(returns), np.mean(success),
                              time.perf_counter() - start))  # fmt: skip
                if len(curve) % 20 == 0:
                    print("steps {:.0f}: mean return {:.1f}, success {:.2f}, {:.0f} s".format(
                        *curve[-1]), flush=True)  # fmt: skip
            return time.perf_counter() - start < 60 * args.minutes

    if args.algo == "sac":
        model = SAC("MlpPolicy", venv, seed=args.seed, learning_starts=2000, batch_size=256,
                    train_freq=1, gradient_steps=max(1, args.envs // 4), verbose=0)  # fmt: skip
    else:
        model = PPO("MlpPolicy", venv, seed=args.seed, n_steps=128, batch_size=512,
                    verbose=0)  # fmt: skip
    model.learn(total_timesteps=args.steps, callback=Curve())
    wall, steps = time.perf_counter() - start, model.num_timesteps
    model.save(args.output / "policy.zip")

    data = np.array(curve)
    np.savetxt(args.output / "learning_curve.csv", data, delimiter=",",
               header="steps,mean_return,success_rate,wall_time_s", comments="")  # fmt: skip
    figure, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5), layout="constrained")
    left.plot(data[:, 0], data[:, 1])
    left.set(xlabel="environment steps", ylabel="mean episode return (last 100)")
    right.plot(data[:, 0], data[:, 2])
    right.set(xlabel="environment steps", ylabel="success rate (last 100)", ylim=(0, 1))
    figure.suptitle(f"Reach-v0, {args.algo.upper()}, {args.envs} envs, {steps} steps, "
                    f"{wall:.0f} s wall")  # fmt: skip
    figure.savefig(args.output / "learning_curve.png", dpi=120)

    rate = _success_rate(model, envs.ReachVector(50), seed=10_000)
    single = envs.Reach()
    t, tips, targets, distance, states, _ = _rollout(model, single, 10_000)
    figure, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5), layout="constrained")
    for j, axis in enumerate("xyz"):
        line = left.plot(t, 1e3 * tips[:, j], label=f"tip {axis}")[0]
        left.plot(t, 1e3 * targets[:, j], "--", color=line.get_color())
    left.set(xlabel="t [s]", ylabel="position [mm] (dashed: target)")
    left.legend()
    right.plot(t, 1e3 * distance)
    right.axhline(1e3 * single.task.tolerance, color="grey", ls=":", label="tolerance")
    right.set(xlabel="t [s]", ylabel="distance to target [mm]")
    right.legend()
    figure.savefig(args.output / "rollout.png", dpi=120)
    _html(single, t, states, args.output / "rollout.html")
    print(f"trained {steps} steps with {args.algo} in {wall:.0f} s wall; final success "
          f"rate {rate:.2f} over 50 new episodes; output in {args.output}")  # fmt: skip
    return 0


def _html(env, t, states, path) -> None:
    """The rollout in the 3-D viewer (skipped without Plotly)."""
    try:
        import plotly  # noqa: F401
    except ModuleNotFoundError:
        return
    import softcurve as sc

    stepper = env.episodes.setup.stepper
    n, model = stepper.model.n, stepper.model
    trajectory = sc.Trajectory(
        t=t, q=states[:, :n], qd=states[:, n : 2 * n],
        lam=states[:, 2 * n : 2 * n + model.n_creep], stats={}, status="success",
        message="a rollout of the trained policy", model=model, actuator=stepper.actuator,
        inputs=states[:, model.n_state :] if states.shape[1] > model.n_state else None,
    )  # fmt: skip
    trajectory.to_html(path)


if __name__ == "__main__":
    raise SystemExit(main())
