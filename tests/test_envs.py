"""The Gymnasium environments (softcurve.envs): Gymnasium's checker, registration,
seeding, the vector environment against single ones, action bounds, failures of single
members and scenario files. The paper's robot with its default bellows throughout (one
compiled model, shared with the other tests); Press, which compiles a model with a wall,
is in tests/test_envs_press.py."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import softcurve as sc  # noqa: E402
import softcurve.envs as envs  # noqa: E402
from softcurve.envs.core import NOT_FINITE  # noqa: E402
from softcurve.envs.setup import build_setup, stepper_method  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

STEPS = 3
"""Episode length of most tests (control periods): short, so that autoresets happen."""


def _actions(rng, count, size, m):
    """Random actions, some beyond [-1, 1] (they are clipped)."""
    return rng.uniform(-1.5, 1.5, size=(count, size, m))


@pytest.mark.parametrize("name", ["Reach", "Track"])
def test_gymnasium_checker_passes(name):
    env = gymnasium.make(f"softcurve/{name}-v0", max_episode_steps=STEPS)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the checker's warnings are failures too
        check_env(env.unwrapped, skip_render_check=True)
    observation, info = env.reset(seed=0)
    assert env.observation_space.contains(observation)
    assert info["failure"] is None


def test_registered_with_and_without_module_prefix():
    assert set(envs.TASK_IDS) <= set(gymnasium.registry)
    env = gymnasium.make("softcurve.envs:softcurve/Reach-v0", max_episode_steps=STEPS)
    assert isinstance(env.unwrapped, envs.Reach)
    vector = gymnasium.make_vec(
        "softcurve/Reach-v0", num_envs=2, vectorization_mode="vector_entry_point",
        max_episode_steps=STEPS,
    )  # fmt: skip
    assert isinstance(vector, envs.ReachVector) and vector.num_envs == 2
    assert vector.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.SAME_STEP


def _episode(env, seed, actions):
    observations, rewards = [env.reset(seed=seed)[0]], []
    for action in actions:
        observation, reward, *_ = env.step(action)
        observations.append(observation)
        rewards.append(reward)
    return np.array(observations), np.array(rewards)


def test_same_seed_same_episode_and_another_seed_another_target():
    env = envs.Reach(max_episode_steps=STEPS)
    actions = _actions(np.random.default_rng(1), STEPS, 1, 3)[:, 0]
    first, rewards = _episode(env, 7, actions)
    again, rewards_again = _episode(envs.Reach(max_episode_steps=STEPS), 7, actions)
    np.testing.assert_array_equal(first, again)
    np.testing.assert_array_equal(rewards, rewards_again)
    targets = {tuple(env.reset(seed=s)[1]["target"]) for s in range(5)}
    assert len(targets) > 1


@pytest.mark.parametrize("method", [None, "ROS34PW2"])
def test_vector_equals_single_environments_with_autoreset(method):
    """Member i of the vector environment seeded with s is the single environment seeded
    with s + i, through an autoreset (episodes of 2 periods, 5 steps), with either kind
    of stepper method (the default robot's default is the explicit RK4)."""
    size, steps, seed = 3, 5, 11
    vector = envs.ReachVector(size, max_episode_steps=2, method=method)
    assert vector.episodes.setup.stepper.method == (method or "RK4")
    singles = [envs.Reach(max_episode_steps=2, method=method) for _ in range(size)]
    actions = _actions(np.random.default_rng(2), steps, size, 3)
    observations, _ = vector.reset(seed=seed)
    resets = 0
    expected = np.array([env.reset(seed=seed + i)[0] for i, env in enumerate(singles)])
    np.testing.assert_allclose(observations, expected, rtol=1e-6, atol=1e-6)
    for k in range(steps):
        observations, rewards, _, truncated, infos = vector.step(actions[k])
        for i, env in enumerate(singles):
            observation, reward, _, ended, info = env.step(actions[k, i])
            assert ended == truncated[i]
            assert reward == pytest.approx(rewards[i], rel=1e-6, abs=1e-9)
            if ended:
                final = infos["final_obs"][i]
                np.testing.assert_allclose(final, observation, rtol=1e-5, atol=1e-5)
                observation, info = env.reset()
                resets += 1
            np.testing.assert_allclose(observations[i], observation, rtol=1e-5, atol=1e-5)
            np.testing.assert_allclose(infos["target"][i], info["target"], rtol=1e-12)
    assert resets == 2 * size  # after steps 2 and 4


def test_actions_beyond_the_bounds_are_clipped():
    vector = envs.ReachVector(2, max_episode_steps=STEPS)
    vector.reset(seed=0)
    stepper = vector.episodes.setup.stepper
    actions = np.array([[5.0, -5.0, 1.0], [-1.0, 0.0, 3.0]])
    _, _, _, _, info = vector.step(actions)
    expected = stepper.lower + (np.clip(actions, -1, 1) + 1) / 2 * (stepper.upper - stepper.lower)
    np.testing.assert_array_equal(info["inputs"], expected)
    assert np.all(info["inputs"] >= stepper.lower) and np.all(info["inputs"] <= stepper.upper)
    lagging = vector.episodes.x[:, stepper.model.n_state :]  # the lagging pressures
    assert np.all(lagging >= stepper.lower - 1e-6 * stepper.upper)
    assert np.all(lagging <= stepper.upper * (1 + 1e-6))


def test_the_actions_of_inputs_invert_the_inputs_of_actions():
    vector = envs.ReachVector(2, max_episode_steps=STEPS)
    episodes = vector.episodes
    actions = np.random.default_rng(5).uniform(-1.0, 1.0, size=(2, episodes.lower.size))
    np.testing.assert_allclose(episodes.actions(episodes.inputs(actions)), actions, atol=1e-12)
    beyond = episodes.actions(np.vstack([episodes.lower - 1.0, episodes.upper + 1.0]))
    np.testing.assert_array_equal(beyond, [[-1.0] * 3, [1.0] * 3])


def test_a_predictive_controller_plays_the_reach_policy():
    """The nonlinear MPC as Reach's policy (controller_action every period), on its own
    model of the robot (three nodes, in CasADi's virtual machine) against the
    environment's: the tip ends within the task's tolerance, and the actions are the
    controller's logged inputs scaled onto [-1, 1]."""
    from softcurve.control.references import Reference, tip_to_coordinates

    env = gymnasium.make("softcurve/Reach-v0", max_episode_steps=50)
    _, info = env.reset(seed=3)
    stepper = env.unwrapped.episodes.setup.stepper
    model = sc.Model(stepper.model.robot, quadrature_nodes=3, compile=False)
    goal = Reference.constant(tip_to_coordinates(info["target"]))
    mpc = sc.PredictiveController(model, stepper.actuator, goal, horizon=0.2, intervals=10)
    start = info["distance"]
    actions, truncated = [], False
    while not truncated:
        actions.append(env.unwrapped.controller_action(mpc))
        _, reward, _, truncated, info = env.step(actions[-1])
    assert len(actions) == 50 and info["failure"] is None
    assert start > 5 * env.unwrapped.task.tolerance > info["distance"]
    scaled = env.unwrapped.episodes.actions(mpc.history("inputs"))
    np.testing.assert_allclose(actions, scaled, atol=1e-6)  # float32
    env.close()


def test_controllers_play_the_members_of_a_vector_environment():
    """One linear MPC per member of ReachVector, each to its member's target: the
    actions are each controller's logged inputs scaled; a list of another length is
    refused."""
    from softcurve.control.mpc import ActuatorMPC
    from softcurve.control.references import Reference, tip_to_coordinates

    vector = envs.ReachVector(2, max_episode_steps=STEPS)
    _, info = vector.reset(seed=4)
    stepper = vector.episodes.setup.stepper
    model = sc.Model(stepper.model.robot, quadrature_nodes=3, compile=False)
    controllers = [
        ActuatorMPC(
            model,
            stepper.actuator,
            Reference.constant(tip_to_coordinates(target)),
            horizon=5,
            sample_time=stepper.period,
        )  # fmt: skip
        for target in info["target"]
    ]
    for _ in range(2):
        actions = vector.controller_actions(controllers)
        vector.step(actions)
        for i, controller in enumerate(controllers):
            scaled = vector.episodes.actions(controller.history("inputs")[-1:])[0]
            np.testing.assert_allclose(actions[i], scaled, atol=1e-6)
    assert not np.allclose(*actions)  # two targets, two commands
    with pytest.raises(sc.ParameterError, match=r"one per environment \(2\), got 1"):
        vector.controller_actions(controllers[:1])
    vector.close()


def test_a_controller_of_another_period_or_actuator_is_refused():
    from softcurve.control.references import Reference

    env = gymnasium.make("softcurve/Reach-v0", max_episode_steps=STEPS)
    env.reset(seed=0)
    stepper = env.unwrapped.episodes.setup.stepper
    rest = Reference.constant([0.064, 0.0, 0.0])
    model = sc.Model(stepper.model.robot, quadrature_nodes=3, compile=False)
    slow = sc.PredictiveController(model, stepper.actuator, rest, horizon=0.2, intervals=5)
    with pytest.raises(sc.ParameterError, match="sample_time must be the environment's period"):
        env.unwrapped.controller_action(slow)
    other = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    foreign = sc.PredictiveController(model, other, rest, horizon=0.2, intervals=10)
    with pytest.raises(sc.ParameterError, match="actuator must be the environment's"):
        env.unwrapped.controller_action(foreign)
    with pytest.raises(sc.ParameterError, match="must be a SampledController"):
        env.unwrapped.controller_action(lambda t, q, qd, lam: np.zeros(3))
    env.close()


def test_a_failing_member_ends_only_its_own_episode():
    vector = envs.ReachVector(3, max_episode_steps=50)
    vector.reset(seed=3)
    vector.step(np.zeros((3, 3)))
    vector.episodes.x[1] = np.nan  # a member broken from outside
    observations, rewards, terminated, truncated, infos = vector.step(np.zeros((3, 3)))
    assert list(truncated) == [False, True, False] and not terminated.any()
    assert np.all(np.isfinite(observations)) and np.all(np.isfinite(rewards))
    assert infos["final_info"]["failure"][1] == NOT_FINITE and infos["_final_info"][1]
    assert np.all(np.isfinite(infos["final_obs"][1]))
    assert rewards[1] == -1.0
    assert list(infos["time"]) == pytest.approx([0.04, 0.0, 0.04])  # member 1 restarted
    # the restarted member's info is its reset's: no inputs acted on it yet (masked, no NaN)
    assert list(infos["_inputs"]) == [True, False, True]
    assert np.all(np.isfinite(infos["inputs"])) and infos["_time"].all()
    stepper = vector.episodes.setup.stepper  # action 0 is the middle of the bounds
    assert infos["final_info"]["inputs"][1] == pytest.approx((stepper.lower + stepper.upper) / 2)
    assert np.all(np.isfinite(vector.episodes.x))
    observations, _, _, truncated, infos = vector.step(np.zeros((3, 3)))
    assert not truncated.any() and np.all(np.isfinite(observations))
    assert list(infos["failure"]) == [None, None, None]


def test_single_environment_failure_is_a_truncation_with_its_reason():
    env = envs.Reach(max_episode_steps=50)
    env.reset(seed=0)
    env.episodes.x[0, 0] = np.inf
    observation, reward, terminated, truncated, info = env.step(np.zeros(3))
    assert truncated and not terminated and reward == -1.0
    assert info["failure"] == NOT_FINITE
    assert np.all(np.isfinite(observation))


SCENARIO = """
[robot]
preset = "ifac2020"

[actuation]
kind = "bellows"
distance = 0.012
area = 2.0e-4
p_max = 6.0e4
time_constant = 0.02

[simulation]
dt = 0.02
t_final = 0.1
"""


def test_a_scenario_file_gives_robot_actuator_period_and_episode_length(tmp_path):
    path = tmp_path / "reach.toml"
    path.write_text(textwrap.dedent(SCENARIO))
    env = envs.Reach.from_scenario(path)
    setup = env.episodes.setup
    assert setup.period == 0.02 and setup.max_episode_steps == 5
    bent = tmp_path / "bent.toml"  # the start, checked on the setup (no calibration)
    bent.write_text(textwrap.dedent(SCENARIO) + "q0 = [0.064, 5.0, 0.0]\n")
    assert build_setup(scenario=bent, duration=1.0).x0[:3].tolist() == [0.064, 5.0, 0.0]
    vector = gymnasium.make_vec("softcurve/Reach-v0", num_envs=2, scenario=str(path))
    assert vector.episodes.setup.max_episode_steps == 5
    without = tmp_path / "bare.toml"
    without.write_text('[robot]\npreset = "ifac2020"\n')
    with pytest.raises(ValueError, match="actuation"):
        envs.Reach.from_scenario(without)


def test_the_default_method_is_the_explicit_one_where_the_robot_allows_it(paper_model):
    """RK4 for the default robot; the stepper's default (L-stable ROS34PW2) where RK4's
    check refuses the robot (stiff axial modes, as the tendon robot's), where obstacles
    are given, or where ``substeps`` is given; a method given is kept."""
    assert build_setup(duration=1.0).stepper.method == "RK4"
    bellows = envs.setup.default_actuator(1)
    assert stepper_method(paper_model, bellows, 0.02, None, None) == "RK4"
    assert stepper_method(paper_model, bellows, 0.02, 16, None) is None
    assert stepper_method(paper_model, bellows, 0.02, None, "ROS2") == "ROS2"
    robot = sc.presets.ifac2020()  # a thousand times stiffer in elongation
    segment, law = robot.segments[0], robot.segments[0].elongation_stiffness
    stiffer = dataclasses.replace(law, a1=1000 * law.a1, a2=1000 * law.a2)
    stiff = sc.Model(robot.replace(segments=(segment.replace(elongation_stiffness=stiffer),)))
    assert stepper_method(stiff, bellows, 0.02, None, None) is None
    ceiling = sc.Plane([0.0, 0.0, 0.062], [0.0, 0.0, -1.0])
    obstacle = sc.Environment([ceiling], sc.ContactLaw(stiffness=1e7), contact_radius=[1e-3])
    walled = sc.Model(sc.presets.ifac2020(), environment=obstacle, compile=False)
    assert stepper_method(walled, bellows, 0.02, None, None) is None


def test_the_environments_take_the_exact_jacobian(paper_model, tmp_path):
    """``jacobian="exact"`` reaches the stepper and makes the L-stable method the default
    (the stepper's test checks the Jacobian itself), as a scenario's ``[simulation]
    jacobian`` does; RK4 with it, and an unknown name, are refused naming the field."""
    bellows = envs.setup.default_actuator(1)
    assert stepper_method(paper_model, bellows, 0.02, None, None, "exact") is None
    env = envs.Reach(jacobian="exact")
    stepper = env.episodes.setup.stepper
    assert stepper.jacobian == "exact" and stepper.method == "ROS34PW2"
    assert "exact Jacobian" in stepper.route.reason
    observation, _ = env.reset(seed=0)
    observation, *_ = env.step(env.action_space.sample())
    assert np.all(np.isfinite(observation))
    scenario = tmp_path / "exact.toml"
    scenario.write_text(EXAMPLES.joinpath("pneumatic.toml").read_text()
                        + '\n[simulation]\njacobian = "exact"\n')  # fmt: skip
    assert envs.Reach.from_scenario(scenario).episodes.setup.stepper.jacobian == "exact"
    kept = envs.Reach.from_scenario(scenario, method="RK4").episodes.setup.stepper
    assert (kept.method, kept.jacobian) == ("RK4", None)  # the method asked wins
    with pytest.raises(sc.ParameterError, match="jacobian='exact'"):
        envs.Reach(method="RK4", jacobian="exact")
    with pytest.raises(sc.ParameterError, match="jacobian must be one of"):
        envs.Reach(jacobian="finite")


def test_softcurve_imports_without_gymnasium():
    code = (
        "import sys; sys.modules['gymnasium'] = None\n"
        "import softcurve\n"
        "try:\n    import softcurve.envs\nexcept ModuleNotFoundError as e:\n    print(e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "pip install 'softcurve[envs]'" in out.stdout


@pytest.mark.parametrize("period", [0.02, 0.03])  # 2 s is 100 periods; 66.7: not whole
def test_the_track_target_is_reachable_by_its_own_command(period):
    """Driving Track with the rotating command that drew its path puts the tip on the
    moving target once the start transient has decayed (0.02 mm, tolerance 5 mm), also
    where the path's turn is not a whole number of periods (the same 16 steps per period:
    no new compile)."""
    from softcurve.envs.calibration import rotating_inputs

    env = envs.Track(period=period, substeps=16)
    env.reset(seed=3)
    stepper, task = env.episodes.setup.stepper, env.task
    turn = task.path.shape[0]  # the path's points: one per period over one turn
    start, after_a_turn = (
        task.target(env.episodes.parameters, np.array([k]))[0] for k in (0, turn)
    )
    np.testing.assert_allclose(after_a_turn, start, rtol=0, atol=1e-12)
    phase = env.episodes.parameters[0, 0] + task.rate * stepper.period * np.arange(1, 201)
    commands = rotating_inputs(stepper, phase)
    distances = []
    for command in commands:
        action = 2 * (command - stepper.lower) / (stepper.upper - stepper.lower) - 1
        *_, info = env.step(action)
        distances.append(info["distance"])
    assert max(distances[150:]) < 0.02 * task.tolerance


def test_the_benchmark_makes_its_vectors_as_a_user_does():
    """benchmarks/bench_envs.py measures what ``gymnasium.make_vec`` returns: its rows
    come from ``make_vec`` with the registered id (no class of softcurve.envs named in
    the script), the default rows with the defaults a user gets (RK4 on the paper's
    robot), another method by ``method=``."""
    import ast
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_envs.py"
    tree = ast.parse(path.read_text())
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    attributes = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    assert "make_vec" in attributes
    assert not (names | attributes) & {"ReachVector", "SoftRobotVectorEnv", "Episodes"}
    spec = importlib.util.spec_from_file_location("bench_envs", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    vector = bench._make(2, bench.DEFAULT, {})
    user = gymnasium.make_vec("softcurve/Reach-v0", num_envs=2)
    assert type(vector) is type(user) is envs.ReachVector
    assert vector.episodes.setup.stepper is user.episodes.setup.stepper  # one stepper
    assert vector.episodes.setup.stepper.method == "RK4"
    assert bench._make(1, "ROS34PW2", {}).episodes.setup.stepper.method == "ROS34PW2"


@pytest.mark.slow  # compiles its own structures: in the slow study, under the CI budget
def test_a_robot_carrying_a_gripper_reaches():
    """The tasks take any robot: the paper's segment with a rigid gripper at its tip,
    and a six-strain segment with it, each with the default bellows on its soft segment
    (none on the gripper)."""
    from tests.test_kinds import gripper, six_strain_segment

    paper = sc.Robot(segments=(sc.presets.ifac2020().segments[0], gripper()))
    thick = sc.Robot(segments=(six_strain_segment(radius=0.015), gripper()))  # bellows at 12 mm
    for robot in (paper, thick):
        env = gymnasium.make("softcurve/Reach-v0", robot=robot, max_episode_steps=STEPS)
        stepper = env.unwrapped.episodes.setup.stepper
        assert stepper.model.robot == robot
        assert [b.segments for b in stepper.actuator.bellows] == [(0,)] * 3
        env.reset(seed=3)
        for _ in range(STEPS):
            _, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            assert np.isfinite(reward) and not terminated
        assert truncated


def test_a_six_strain_robot_with_a_gripper_is_an_environment():
    """The tasks on a segment that bends, twists, shears and stretches, carrying a
    gripper: actions drive its bending and twist through a constant input matrix; the
    episode steps with the L-stable method (its shear and stretch are stiff)."""
    from tests.test_kinds import six_strain_gripper_robot

    robot = six_strain_gripper_robot()
    h = np.zeros((robot.n, 3))
    h[0, 0] = h[1, 1] = 8e-3  # bend_x, bend_y [N m^2 per unit input]
    h[2, 2] = 5e-3  # twist
    actuator = sc.ConstantPressureMap(constant=h, p_max=1.0, p_min=-1.0)
    env = gymnasium.make(
        "softcurve/Reach-v0", robot=robot, actuator=actuator, max_episode_steps=STEPS
    )
    assert env.unwrapped.episodes.setup.stepper.method == "ROS34PW2"
    env.reset(seed=0)
    for _ in range(STEPS):
        _, reward, terminated, truncated, _ = env.step(np.array([1.0, -1.0, 1.0]))
        assert np.isfinite(reward) and not terminated
    assert truncated
