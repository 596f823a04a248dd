"""Issue 29, items 1 and 2: no result outside the model's or the actuator's domain is
SUCCESS (equilibria, inverse statics, quasi-static sweeps, simulations), and a routing
outside the body is refused; with the property test of the domain."""

from __future__ import annotations

import math

import numpy as np
import pytest

import softcurve as sc
from softcurve.cli import main
from softcurve.description.robot import MAX_BEND, MAX_STRETCH

PAPER_RADIUS = 0.0235
"""The paper robot's segment radius [m] (sc.presets.ifac2020)."""

TWO_BELLOWS = (0.0, math.pi)
"""Azimuths of two opposite bellows [rad]: bending toward one shortens the other."""


def _fiber_lengths(actuator, q) -> np.ndarray:
    """Independent of the library: every tendon's or bellow's length in every segment it
    runs through, ``l (1 - rho (kx cos phi + ky sin phi))`` [m]."""
    if isinstance(actuator, sc.TendonActuator):
        pieces = [(t.azimuth, t.distance, range(t.anchor + 1)) for t in actuator.tendons]
    else:
        pieces = [(b.azimuth, b.distance, b.segments) for b in actuator.bellows]
    return np.array(
        [
            q[3 * j] * (1 - rho * (q[3 * j + 1] * math.cos(phi) + q[3 * j + 2] * math.sin(phi)))
            for phi, rho, segments in pieces
            for j in segments
        ]
    )


def _inside(robot, q, actuator=None) -> bool:
    """The model's domain (docs/model.md) and the actuator's, written out again here."""
    q = np.asarray(q, dtype=float)
    if not np.all(np.isfinite(q)):
        return False
    length, kx, ky = q[0::3], q[1::3], q[2::3]
    if not np.all((length > 0) & (length <= MAX_STRETCH * robot.rest_lengths)):
        return False
    if not np.all(length * np.hypot(kx, ky) <= MAX_BEND):
        return False
    return actuator is None or bool(np.all(_fiber_lengths(actuator, q) > 0))


# -- item 1: equilibria outside the model's domain -------------------------------------
def test_compressive_tip_load_is_not_a_successful_equilibrium(paper_model):
    e = sc.equilibrium(paper_model, [0.0644, 0.0, 0.0], tip_force=[0.0, 0.0, -150.0])
    assert e.status is sc.Status.LEFT_DOMAIN
    assert e.q[0] < 0  # the root the solver found: l = -3 mm
    assert "l of segment 1" in e.message and "0 < l" in e.message


def test_equilibria_under_a_compressive_tip_load_name_the_coordinate(paper_model, capsys):
    table = sc.equilibria(paper_model, starts=8, tip_force=[0.0, 0.0, -150.0])
    assert table.status is sc.Status.LEFT_DOMAIN and len(table) == 0
    assert "outside the model's domain" in table.message and "l of segment 1" in table.message
    assert main(["equilibria", "--tip-force", "0", "0", "-150", "--starts", "8"]) == 1
    captured = capsys.readouterr()
    assert "l of segment 1" in captured.out + captured.err
    assert "Traceback" not in captured.err


def test_bellows_far_out_is_not_a_successful_equilibrium(paper_model):
    # a body wide enough for the routing (the same structure: the paper's library)
    segment = paper_model.robot.segments[0].replace(radius=0.3)
    model = sc.Model(paper_model.robot.replace(segments=(segment,)))
    actuator = sc.PneumaticActuator.three_bellows(distance=0.2, area=2e-4, p_max=6e4)
    e = sc.equilibrium(model, [0.0644, 0.0, 0.0], actuator=actuator, inputs=[3e4, 0, 0])
    assert e.status is sc.Status.LEFT_DOMAIN and not e.success
    assert "l of segment 1" in e.message


def test_chamber_volume_below_zero_is_not_a_successful_equilibrium(paper_model):
    """The configuration lies in the robot's domain (kx = -45 1/m, a bend of 2.6 rad),
    but the inner bellow at rho = 23.5 mm has crossed the centre of curvature."""
    actuator = sc.PneumaticActuator.three_bellows(
        distance=PAPER_RADIUS, area=2e-4, p_max=6e4, azimuths=TWO_BELLOWS
    )
    e = sc.equilibrium(
        paper_model, [0.0644, 0.0, 0.0], tau=[0.0, -0.02, 0.0], actuator=actuator, inputs=[0, 0]
    )
    assert _inside(paper_model.robot, e.q) and not _inside(paper_model.robot, e.q, actuator)
    assert e.status is sc.Status.LEFT_DOMAIN
    assert "bellows[1] in segment 1" in e.message and "chamber volume" in e.message
    assert "allowed > 0" in e.message


def test_equilibria_drop_roots_outside_the_domain(paper_model):
    actuator = sc.PneumaticActuator.three_bellows(
        distance=PAPER_RADIUS, area=2e-4, p_max=6e4, azimuths=TWO_BELLOWS
    )
    table = sc.equilibria(
        paper_model, starts=4, tau=[0.0, -0.02, 0.0], actuator=actuator, inputs=[0, 0]
    )
    assert not table.success and table.status is sc.Status.LEFT_DOMAIN
    assert len(table) == 0 and "chamber volume" in table.message


def test_input_sweep_stops_being_success_where_a_chamber_leaves(paper_model):
    actuator = sc.PneumaticActuator.three_bellows(
        distance=PAPER_RADIUS, area=2e-4, p_max=6e4, azimuths=TWO_BELLOWS
    )
    sweep = sc.input_sweep(paper_model, actuator, [[0.0, 0.0]] * 2, tau=[0.0, -0.02, 0.0])
    assert sweep.status is sc.Status.LEFT_DOMAIN and not sweep.converged.any()
    assert "left the model's domain" in sweep.message and "bellows[1]" in sweep.message


# -- item 2: actuator geometry ----------------------------------------------------------
@pytest.mark.parametrize("distance", [0.05, 0.2])
def test_tendons_outside_the_body_are_refused(paper_model, distance):
    actuator = sc.TendonActuator.three_per_segment(distance=distance, t_max=10.0)
    with pytest.raises(sc.ParameterError) as info:
        sc.equilibrium(paper_model, [0.0644, 0.0, 0.0], actuator=actuator, inputs=[1, 0, 0])
    text = str(info.value)
    assert "tendons[0].distance" in text and f"{distance:g} m" in text
    assert f"distance <= {PAPER_RADIUS:g} m" in text and "outside the body" in text


def test_bellows_outside_the_body_are_refused_before_a_simulation(paper_model):
    actuator = sc.PneumaticActuator.three_bellows(distance=0.05, area=2e-4, p_max=6e4)
    with pytest.raises(sc.ParameterError, match=r"bellows\[0\]\.distance = 0\.05 m"):
        sc.simulate(paper_model, [0.0644, 0, 0], [0, 0, 0], actuator=actuator,
                    inputs=[1e4, 0, 0], t_final=0.01)  # fmt: skip


def test_a_routing_on_the_surface_is_accepted(paper_model):
    actuator = sc.TendonActuator.three_per_segment(distance=PAPER_RADIUS, t_max=10.0)
    actuator.check_robot(paper_model.robot)  # rho = r: a tendon on the surface


def test_simulation_stops_where_a_tendon_length_crosses_zero(paper_model):
    # the example's 15 mm routing (examples/tendons.toml) on the soft paper robot
    actuator = sc.TendonActuator.three_per_segment(distance=0.015, t_max=20.0)
    run = sc.simulate(paper_model, [0.0644, 0, 0], [0, 0, 0], actuator=actuator,
                      inputs=[20.0, 0, 0], t_final=0.3, dt=0.01)  # fmt: skip
    assert run.status is sc.Status.LEFT_DOMAIN
    assert "tendons[0] in segment 1: tendon length" in run.message and "allowed > 0" in run.message
    assert run.t[-1] < 0.3
    assert all(np.all(_fiber_lengths(actuator, q) > 0) for q in run.q)  # kept: inside only


def test_simulation_stops_where_a_chamber_volume_crosses_zero(paper_model):
    actuator = sc.PneumaticActuator.three_bellows(
        distance=PAPER_RADIUS, area=2e-4, p_max=6e4, azimuths=TWO_BELLOWS
    )
    run = sc.simulate(paper_model, [0.0644, 0, 0], [0, 0, 0], actuator=actuator,
                      inputs=[6e4, 0.0], t_final=0.3, dt=0.01)  # fmt: skip
    assert run.status is sc.Status.LEFT_DOMAIN
    assert "bellows[1] in segment 1: chamber volume" in run.message and "t = " in run.message
    assert all(_inside(paper_model.robot, q, actuator) for q in run.q)


def test_batch_members_stop_where_a_tendon_length_crosses_zero(paper_model):
    actuator = sc.TendonActuator.three_per_segment(distance=0.015, t_max=20.0)
    batch = sc.simulate_batch(paper_model, [[0.0644, 0, 0]] * 2, np.zeros((2, 3)),
                              actuator=actuator, inputs=[[1.0, 0, 0], [20.0, 0, 0]],
                              t_final=0.3, dt=0.01, threads=1)  # fmt: skip
    assert batch.member_status[0] is sc.Status.SUCCESS
    assert batch.member_status[1] is sc.Status.LEFT_DOMAIN and not batch.success
    assert "tendons[0] in segment 1: tendon length" in batch.member_message[1]
    kept = batch.q[1, : batch.reached[1]]
    assert batch.reached[1] < batch.t.size and np.all(np.isnan(batch.q[1, batch.reached[1] :]))
    assert all(np.all(_fiber_lengths(actuator, q) > 0) for q in kept)


def test_initial_state_outside_the_actuator_domain_is_refused(paper_model):
    actuator = sc.TendonActuator.three_per_segment(distance=0.015, t_max=20.0)
    with pytest.raises(sc.ParameterError, match=r"q0: tendons\[0\] in segment 1"):
        sc.simulate(paper_model, [0.0644, 80.0, 0], [0, 0, 0], actuator=actuator,
                    inputs=[1.0, 0, 0], t_final=0.01)  # fmt: skip


def test_actuator_domain_methods():
    actuator = sc.TendonActuator.three_per_segment(distance=0.01, t_max=5.0, n_segments=2)
    q = np.array([[0.1, 0, 0, 0.1, 0, 0], [0.1, 50, 0, 0.1, 120, 0]])
    assert actuator.in_domain(q).tolist() == [True, False]
    assert actuator.domain_problem(q[0]) is None
    assert "tendons[3] in segment 2" in actuator.domain_problem(q[1])  # the distal set
    fixed = sc.ConstantPressureMap(np.ones((3, 1)), p_max=1e4)
    assert fixed.in_domain(q[:, :3]).all() and fixed.domain_problem(q[1, :3]) is None


# -- the property test ------------------------------------------------------------------
CASES_PER_ROBOT = 8
"""Random load cases per random robot (3 robots: 1, 2 and 3 segments)."""


def _random_robot(rng, paper, segments: int):
    """A robot of the paper's structure (one compiled library serves every one-segment
    robot; the others run in CasADi's virtual machine), random numbers."""
    base = paper.segments[0]
    made = tuple(
        base.replace(
            rest_length=float(rng.uniform(0.04, 0.12)),
            mass=float(rng.uniform(0.02, 0.08)),
            radius=float(rng.uniform(0.01, 0.03)),
        )
        for _ in range(segments)
    )
    return paper.replace(segments=made)


def _random_actuator(rng, robot):
    radius = min(s.radius for s in robot.segments)
    distance = float(rng.uniform(0.3, 1.0) * radius)
    n_segments = robot.n_segments
    if rng.random() < 0.5:
        return sc.TendonActuator.three_per_segment(
            distance=distance, t_max=float(rng.uniform(5, 60)), n_segments=n_segments
        )
    return sc.PneumaticActuator.three_bellows(
        distance=distance, area=float(rng.uniform(1e-4, 4e-4)), p_max=float(rng.uniform(3e4, 1e5)),
        n_segments=n_segments, azimuths=TWO_BELLOWS + (0.5 * math.pi,),
    )  # fmt: skip


def _assert_honest(result, robot, actuator, what):
    q = np.atleast_2d(result.q)
    if result.success:
        assert all(_inside(robot, row, actuator) for row in q), f"{what}: SUCCESS outside"


def test_property_no_success_outside_the_domain(paper_model):
    """Random robots (1-3 segments), actuators (tendons, bellows) and loads (tip force,
    inputs at up to their bounds, gravity) through equilibrium, simulate and
    inverse_statics: no SUCCESS ever carries a state outside the model's or the
    actuator's domain. Some equilibria and simulations must end outside (else the test
    shows nothing): with this seed 10 of 24 equilibria and 2 of 8 simulations do."""
    rng = np.random.default_rng(29)
    outcomes = []
    for segments in (1, 2, 3):
        robot = _random_robot(rng, paper_model.robot, segments)
        model = sc.Model(robot, compile=segments == 1)
        rest = np.zeros(robot.n)
        rest[0::3] = robot.rest_lengths
        for case in range(CASES_PER_ROBOT):
            actuator = _random_actuator(rng, robot)
            inputs = actuator.upper * rng.uniform(0, 1, actuator.n_inputs) ** 0.5
            force = rng.normal(0, 20.0, 3) * [0.5, 0.5, 3.0]
            gravity = 9.81 * rng.choice([-1.0, 1.0]) * np.array([0, 0, 1.0])
            what = f"{segments} segments, case {case}"
            e = sc.equilibrium(model, rest, actuator=actuator, inputs=inputs, tip_force=force,
                               gravity=gravity, max_evaluations=100)  # fmt: skip
            _assert_honest(e, robot, actuator, f"equilibrium, {what}")
            outcomes.append(("equilibrium", e.status))
            if segments == 1:  # the step response overshoots the equilibrium: full inputs
                run = sc.simulate(model, rest, np.zeros(robot.n), actuator=actuator,
                                  inputs=actuator.upper, t_final=0.2, dt=0.01)  # fmt: skip
                _assert_honest(run, robot, actuator, f"simulate, {what}")
                outcomes.append(("simulate", run.status))
            if segments == 1 and case % 4 == 1:
                target = np.array([0.0, 0.0, robot.rest_length]) + rng.normal(0, 0.02, 3)
                inverse = sc.inverse_statics(model, actuator, target, starts=1)
                _assert_honest(inverse, robot, actuator, f"inverse_statics, {what}")
                outcomes.append(("inverse_statics", inverse.status))
    for kind in ("equilibrium", "simulate"):  # the cases reach both sides of the boundary
        assert {(kind, sc.Status.SUCCESS), (kind, sc.Status.LEFT_DOMAIN)} <= set(outcomes)


def test_scenario_with_a_routing_outside_the_body_exits_2(tmp_path, capsys):
    config = tmp_path / "far.toml"
    config.write_text(
        '[robot]\npreset = "ifac2020"\n\n[actuation]\nkind = "tendons"\n'
        "distance = 0.05\nt_max = 10.0\n\n[simulation]\nt_final = 0.1\ninputs = [1.0, 0.0, 0.0]\n"
    )
    out = tmp_path / "out"
    assert main(["equilibria", str(config), "--inputs", "1", "0", "0"]) == 2
    assert main(["simulate", str(config), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "tendons[0].distance = 0.05 m" in err and "outside the body" in err
    assert "Traceback" not in err and not out.exists()


def test_fit_of_equilibria_accepts_no_root_outside_the_actuator_domain(paper_model):
    """A fit's prediction whose equilibria put a chamber past the centre of curvature
    fails naming it, as one outside the robot's domain does."""
    from softcurve.identification.experiments._loading import Experiment
    from softcurve.identification.fits._equilibria import EquilibriumPredictor
    from softcurve.identification.fits._parameters import Free, FreeParameters
    from softcurve.identification.maps import curvature_map
    from softcurve.identification.maps._inputs import actuator_input_map

    actuator = sc.PneumaticActuator.three_bellows(
        distance=PAPER_RADIUS, area=2e-4, p_max=6e4, azimuths=TWO_BELLOWS
    )
    t = np.linspace(0.0, 1.0, 3)
    experiment = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, {"p0": [1e4, 3e4, 6e4], "p1": 0 * t})
    inputs, output = actuator_input_map(actuator), curvature_map()
    names = ("segments[0].bending_stiffness.a1", "segments[0].bending_stiffness.a2")
    free = [Free(name, 1e-3, 10.0) for name in names]
    parameters = FreeParameters(paper_model, free, {**inputs.parameters, **output.parameters}, {})
    q0 = np.array([0.0644, 0.0, 0.0])
    evaluate = EquilibriumPredictor(paper_model, parameters, output, inputs, q0)(experiment)
    bending = paper_model.robot.segments[0].bending_stiffness
    evaluate(np.array([bending.a1, bending.a2]))  # the paper's stiffness: inside
    with pytest.raises(RuntimeError, match=r"bellows\[1\] in segment 1: chamber volume"):
        evaluate(0.3 * np.array([bending.a1, bending.a2]))  # softer: a chamber crosses
