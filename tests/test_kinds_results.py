"""Results of robots of every kind: batches of a chain with rigid bodies agree with their
members' single runs, its equilibria and modes, trajectory files that name each element's
coordinates (and read back a robot whose coordinate count is not three per element), the
forward sensitivities of a six-strain robot."""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc
from softcurve.identification.experiments import Experiment
from softcurve.identification.fits._parameters import Free, FreeParameters
from softcurve.identification.maps import tip_position_map
from softcurve.simulation.results import TrajectoryFileError, column_names, coordinate_columns
from softcurve.simulation.sensitivity._sensitivity import trajectory_sensitivities
from softcurve.simulation.solvers import _driver as native

from .conftest import assert_close
from .test_kinds import gripper, robots, six_strain_segment


@pytest.fixture(scope="module")
def mixed_model():
    """A constant-strain segment that bends and twists, a rigid link, a constant-curvature
    segment and a gripper, on a moved base (tests/test_kinds.py), compiled."""
    return sc.Model(robots()["mixed"])


def test_a_batch_of_a_chain_with_rigid_bodies_is_its_members_runs(rng, mixed_model):
    robot = mixed_model.robot
    scale = robot.coordinate_scale()
    q0 = robot.rest_configuration() + 0.2 * scale * rng.uniform(-1, 1, (3, robot.n))
    qd0 = scale * rng.uniform(-1, 1, (3, robot.n))
    batch = sc.simulate_batch(mixed_model, q0, qd0, t_final=0.2, dt=0.01)
    assert batch.success, batch.message
    for b in range(3):
        single = sc.simulate(mixed_model, q0[b], qd0[b], t_final=0.2, dt=0.01)
        member = batch.member(b)
        assert member.stats["route"] == single.stats["route"] == "driver"
        assert_close(
            member.x, single.x, rtol=1e-9, scale=np.abs(single.x).max(axis=0) + scale.max()
        )


def test_trajectory_files_name_each_kinds_coordinates(tmp_path, mixed_model):
    robot = mixed_model.robot
    columns = coordinate_columns(robot)
    assert columns == ["bend_x1", "bend_y1", "twist1", "l3", "kx3", "ky3"]
    run = sc.simulate(mixed_model, robot.rest_configuration(), np.zeros(robot.n), t_final=0.05)
    for suffix in (".csv", ".npz"):
        path = run.save(tmp_path / f"run{suffix}")
        if suffix == ".csv":
            header = path.read_text().splitlines()[1].split(",")
            assert header[1:7] == columns and header[7:13] == [f"{c}_dot" for c in columns]
        loaded = sc.load_trajectory(path)
        np.testing.assert_array_equal(loaded.q, run.q)


def test_a_file_of_four_coordinates_reads_back(tmp_path):
    """Before, a file had to hold three coordinates per segment: a robot of four strains
    and a gripper wrote it and could not read it."""
    segment = six_strain_segment(
        strains=("bend_x", "bend_y", "twist", "stretch"), shear_stiffness=None, damping=False
    )
    model = sc.Model(sc.Robot(segments=(segment, gripper())), compile=False)
    run = sc.simulate(model, model.robot.rest_configuration(), np.zeros(4), t_final=0.02)
    assert run.success and run.q.shape[1] == 4
    path = run.save(tmp_path / "four.csv")
    loaded = sc.load_trajectory(path)
    np.testing.assert_array_equal(loaded.q, run.q)
    assert path.read_text().splitlines()[1].startswith("t,bend_x1,bend_y1,twist1,stretch1,")
    text = path.read_text().replace('"coordinates": ["bend_x1", ', '"coordinates": [')
    broken = tmp_path / "broken.csv"
    broken.write_text(text)
    with pytest.raises(TrajectoryFileError, match="coordinates must be 4 distinct names"):
        sc.load_trajectory(broken)


def test_files_without_names_are_constant_curvature():
    assert column_names(3, 0, False)[:4] == ["t", "l1", "kx1", "ky1"]
    assert column_names(6, 0, False, coordinates=["a", "b", "c", "d", "e", "f"])[1:3] == ["a", "b"]


def test_equilibria_and_modes_of_a_chain_with_rigid_bodies(mixed_model):
    table = sc.equilibria(mixed_model, starts=4)
    assert table.success and table.stable, table.message
    e = table.stable[0]
    assert e.status is sc.Status.SUCCESS and np.all(e.eigenvalues > 0)
    assert e.curvature.shape == (4,) and e.curvature[1] == e.curvature[3] == 0.0  # rigid
    assert "twist(0) [1/m]" in table.table() and "l(2) [m]" in table.table()
    lin = sc.linearize(mixed_model, e.q)
    assert lin.success and lin.asymptotically_stable
    assert lin.frequencies.size == mixed_model.n and np.all(lin.frequencies > 0)


@pytest.mark.slow  # compiles its own structures: in the slow study, under the CI budget
def test_trajectory_sensitivities_of_a_six_strain_robot():
    """The identification's forward sensitivities (bending, torsion and shear stiffness,
    the tip's position) through the C driver agree with CasADi's route and with finite
    differences, on a segment that bends, twists, shears and stretches."""
    model = sc.Model(sc.Robot(segments=(six_strain_segment(),)))
    t = np.linspace(0.0, 0.3, 31)
    experiment = Experiment(t, {"x": 0 * t, "y": 0 * t, "z": 0 * t}, {})
    names = ("bending_stiffness.k0", "torsion_stiffness.k0", "shear_stiffness.k0")

    def evaluator():
        free = [Free(f"segments[0].{name}") for name in names]
        parameters = FreeParameters(model, free, {}, {}, None)
        x0 = np.zeros(model.n_state)
        x0[: model.n] = [3.0, -2.0, 5.0, 0.01, 0.0, 1.02]
        output = tip_position_map(model)
        return trajectory_sensitivities(model, parameters, output, None, x0, experiment, None), (
            parameters.theta0
        )

    evaluate, theta = evaluator()
    y, jacobian = evaluate(theta)
    assert evaluate.stats["route"] == "sensitivity-driver" and jacobian.shape == (3 * t.size, 3)
    with native.casadi_only():
        reference, theta_again = evaluator()
        y_ref, jacobian_ref = reference(theta_again)
    assert_close(y, y_ref, atol=1e-9, scale=0.0)
    assert_close(jacobian, jacobian_ref, atol=1e-7 * np.abs(jacobian_ref).max(), scale=0.0)
    for k in range(3):  # each column against a forward difference (h: 1e-6 relative)
        step = theta.copy()
        step[k] *= 1 + 1e-6
        moved, _ = evaluate(step)
        difference = (moved - y).ravel(order="F") / (theta[k] * 1e-6)
        column = jacobian[:, k]
        assert np.abs(difference - column).max() <= 1e-2 * np.abs(column).max()
