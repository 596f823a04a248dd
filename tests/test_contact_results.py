"""Contact in results, scenario files and the rest of the library (issue 13, items 3-4 and
"everywhere"): the contact history of a trajectory, its figure and the obstacles in the 3-D
figures; ``[environment]`` in TOML; batches in worker processes, C export, equilibria and
linearization with contact. Models run in CasADi's virtual machine (no compile)."""

from __future__ import annotations

import pickle
import re

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

import softcurve as sc

from .conftest import assert_close

RC = 1e-3
"""Contact radius [m]: a thin body."""
WALL_X = 0.03
"""The wall x = 30 mm (solid beyond), which a robot bent toward +x presses."""


def _environment(*extra) -> sc.Environment:
    wall = sc.Plane([WALL_X, 0.0, 0.0], [-1.0, 0.0, 0.0])
    law = sc.ContactLaw(1e7, damping=1.0, smoothing=1e-6)
    return sc.Environment([wall, *extra], law, contact_radius=[RC])


@pytest.fixture(scope="module")
def model() -> sc.Model:
    robot = sc.presets.ifac2020()
    return sc.Model(robot, environment=_environment(sc.Sphere([0, 0.1, 0.05], 0.02)), compile=False)


@pytest.fixture(scope="module")
def pressed(model) -> sc.Trajectory:
    """States bending the robot progressively into the wall (no integration needed)."""
    t = np.linspace(0.0, 0.1, 11)
    q = np.column_stack([np.full(t.size, 0.0644), np.linspace(0.0, 16.0, t.size), 0 * t])
    qd = np.column_stack([0 * t, np.full(t.size, 300.0), 0 * t])
    lam = np.zeros((t.size, model.n_creep))
    return sc.Trajectory(t=t, q=q, qd=qd, lam=lam, model=model)


def test_contact_history_equals_the_model_at_every_time(model, pressed):
    history = pressed.contact()
    assert history.forces.shape == (11, 2, 3) and history.points.shape == (11, 2, 3)
    assert history.labels == ("0: plane", "1: sphere")
    for k in range(pressed.t.size):
        one = model.contact(pressed.q[k], pressed.qd[k])
        assert_close(history.forces[k], one["forces"], atol=1e-14, what="forces")
        assert_close(history.generalized[k], one["generalized"], atol=1e-14, what="Fc")
        assert_close(history.energy[k], one["energy"], atol=1e-18, what="Vc")
        np.testing.assert_array_equal(np.isnan(history.points[k]), np.isnan(one["points"]))
        assert_close(np.nan_to_num(history.points[k]), np.nan_to_num(one["points"]), atol=1e-15)
    assert not history.in_contact[0, 0] and history.in_contact[-1, 0]  # straight, then bent
    assert not history.in_contact[:, 1].any()  # the sphere is never touched
    assert history.magnitude[-1, 0] > 0 and history.forces[-1, 0, 0] < 0  # the wall pushes -x
    assert_close(history.points[-1, 0, 0], WALL_X - RC, atol=2e-3, what="point on the wall")
    with pytest.raises(ValueError):
        history.forces[0, 0, 0] = 1.0  # immutable


def test_contact_history_needs_an_environment(pressed):
    free = sc.Model(sc.presets.ifac2020(), compile=False)
    with pytest.raises(sc.ParameterError, match="has no environment"):
        pressed.contact(free)


def test_contact_figure_and_obstacles_in_the_3d_figures(pressed, tmp_path):
    figure = pressed.contact().plot()
    assert isinstance(figure, Figure) and len(figure.axes) == 2
    assert len(figure.axes[0].lines) == 2  # one magnitude per obstacle
    plt.close(figure)
    figure = pressed.plot_tip()
    surfaces = [c for c in figure.axes[0].collections if type(c).__name__ == "Poly3DCollection"]
    assert len(surfaces) == 2  # the wall and the sphere
    plt.close(figure)
    path = pressed.animate(tmp_path / "a.gif", fps=5, speed=0.5, points=5, dpi=30)
    assert path.stat().st_size > 0


def test_capsule_surface_is_on_the_capsule():
    from softcurve.figures.obstacles import obstacle_surfaces

    capsule = sc.Capsule([0, 0, 0], [0.1, 0.0, 0.0], 0.02)
    for grid in obstacle_surfaces(capsule, 0.1):
        x = np.stack(grid).reshape(3, -1).T
        t = np.clip(x[:, 0] / 0.1, 0, 1)
        distance = np.linalg.norm(x - np.outer(t, [0.1, 0, 0]), axis=1)
        assert_close(distance, 0.02, rtol=1e-12, what="capsule surface")


# -- scenario files ------------------------------------------------------------------
WALL_TOML = """
[robot]
preset = "ifac2020"

[environment]
contact_radius = [0.001]

[environment.law]
stiffness = 1e7
damping = 1.0

[[environment.obstacles]]
kind = "plane"
point = [0.03, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]

[[environment.obstacles]]
kind = "capsule"
a = [0.0, 0.05, 0.0]
b = [0.0, 0.05, 0.1]
radius = 0.01

[simulation]
t_final = 0.01
q0 = [0.0644, 5.0, 0.0]
"""


def _scenario(text, tmp_path):
    path = tmp_path / "contact.toml"
    path.write_text(text)
    return sc.load_config(path)


def test_environment_table_is_read(tmp_path):
    scenario = _scenario(WALL_TOML, tmp_path)
    environment = scenario.environment
    assert isinstance(environment, sc.Environment)
    assert [type(o).__name__ for o in environment.obstacles] == ["Plane", "Capsule"]
    assert environment.law == sc.ContactLaw(1e7, damping=1.0)
    assert environment.contact_radius == (0.001,)
    np.testing.assert_array_equal(environment.obstacles[1].b, [0.0, 0.05, 0.1])


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ('kind = "plane"', 'kind = "wall"', "obstacles[0].kind must be one of"),
        ("normal = [-1.0, 0.0, 0.0]", "normal = [0.0, 0.0, 0.0]", "Plane.normal must be a nonzero"),
        ("radius = 0.01", "radius = -0.01", "obstacles[1]: Capsule.radius must be > 0, got -0.01"),
        ("radius = 0.01", "radius = 0.01\ncolour = 1", "obstacles[1]: unknown key(s) ['colour']"),
        ("damping = 1.0", "dampnig = 1.0", "environment.law: unknown key(s) ['dampnig']"),
        ("stiffness = 1e7", "stiffness = -1e7", "ContactLaw.stiffness must be > 0"),
        ("stiffness = 1e7", "", "environment.law: missing required key(s) ['stiffness']"),
        ("contact_radius = [0.001]", "contact_radius = [0.001, 0.002]", "one entry per segment"),
        ("contact_radius = [0.001]", "radius = [0.001]", "environment: unknown key(s) ['radius']"),
        ("q0 = [0.0644, 5.0, 0.0]", "q0 = [0.0644, 25.0, 0.0]", "inside obstacle 0 (Plane)"),
    ],
)
def test_environment_table_errors_are_named(tmp_path, old, new, words):
    assert old in WALL_TOML
    with pytest.raises(sc.ParameterError, match=re.escape(words)) as error:
        _scenario(WALL_TOML.replace(old, new, 1), tmp_path)
    assert str(tmp_path / "contact.toml") in str(error.value)


def test_start_inside_an_obstacle_is_refused_before_any_work(model):
    # bent by 25 1/m the tip is at x = 41 mm: its backbone 11 mm inside the wall
    with pytest.raises(
        sc.ParameterError, match=r"obstacle 0 \(Plane\): its backbone is 1\d\.\d+ mm"
    ):
        sc.simulate(model, [0.0644, 25.0, 0.0], np.zeros(3), t_final=0.01)
    with pytest.raises(sc.ParameterError, match=r"q0\[1\] \(member 1\) starts the robot inside"):
        sc.simulate_batch(model, [[0.0644, 5.0, 0.0], [0.0644, 25.0, 0.0]], np.zeros(3),
                          t_final=0.01)  # fmt: skip
    touching = [0.0644, 16.0, 0.0]  # backbone 0.3 mm below the surface, less than RC: allowed
    assert model.contact(touching)["energy"] > 0
    from softcurve.symbolic.gaps import start_problem

    assert start_problem(model.environment, model.robot, touching) is None


def test_a_thick_body_pressed_deep_into_a_wall_is_refused_by_its_force():
    """The paper robot (contact radius 23.5 mm) with a wall 10-15 mm from its straight
    backbone: no body point is entirely inside, but the penalty force would exceed the
    k_e(0) l0 = 31.6 N that squeezes the segment to zero length; 30 mm away it touches
    lightly and is allowed."""
    from softcurve.symbolic.gaps import start_problem

    robot = sc.presets.ifac2020()
    law = sc.ContactLaw(stiffness=1e6)
    for wall, refused in ((0.01, True), (0.015, True), (0.03, False)):
        environment = sc.Environment([sc.Plane([wall, 0, 0], [-1, 0, 0])], law)
        problem = start_problem(environment, robot, [0.0644, 0.0, 0.0])
        assert (problem is not None) == refused, problem
        if refused:
            assert "penalty force of" in problem and "31.56 N" in problem


def test_a_model_with_obstacles_is_integrated_with_the_stiff_family():
    """A start clear of the wall has the free model's stiffness; the contact ahead does
    not, so "cvodes" picks BDF from the start (engine.multistep_family)."""
    environment = sc.Environment([sc.Plane([0.03, 0, 0], [-1, 0, 0])], sc.ContactLaw(1e6))
    model = sc.Model(sc.presets.ifac2020(), environment=environment, compile=False)
    run = sc.simulate(model, [0.0644, 0.0, 0.0], np.zeros(3), t_final=0.01)
    assert run.stats["method"] == "cvodes-bdf"
    free = sc.simulate(sc.Model(sc.presets.ifac2020(), compile=False), [0.0644, 0.0, 0.0],
                       np.zeros(3), t_final=0.01)  # fmt: skip
    assert free.stats["method"] != "cvodes-bdf"


# -- everywhere: batches in worker processes, C export, statics and linearization -------
def test_batch_in_worker_processes_keeps_the_environment(model):
    """Workers rebuild the model WITH its environment (and uncompiled, as the parent's):
    a chunk run as a worker runs it, from the pickled description, equals simulate."""
    from softcurve.simulation.batch._batch import _chunk
    from softcurve.simulation.batch._workers import model_description

    description = pickle.loads(pickle.dumps(model_description(model)))
    assert description[2].key() == model.environment.key() and description[3] is False
    q0 = np.array([[0.0644, 14.0, 0.0], [0.0644, 15.5, 0.0]])  # near the wall, touching it
    qd0 = np.array([[0.0, 300.0, 0.0]] * 2)  # toward the wall
    arrays = {"q0": q0, "qd0": qd0, "lam0": np.zeros((2, 3)), "tau": np.zeros((2, 3)),
              "parameters": np.tile(model.parameters, (2, 1))}  # fmt: skip
    settings = sc.SimulationSettings(t_final=0.01, dt=0.005)
    status, _, _, _, x = _chunk(description, arrays, settings)
    assert all(s is sc.Status.SUCCESS for s in status)
    for b in range(2):
        single = sc.simulate(model, q0[b], qd0[b], settings=settings)
        assert_close(x[b, :, :3], single.q, rtol=1e-5, scale=np.abs(single.q).max(0), what="q")
    assert model.contact(x[1, 1, :3])["energy"] > 0  # member 1 presses the wall
    batch = sc.simulate_batch(model, q0, qd0, settings=settings)
    assert batch.member_model(0).environment is model.environment
    assert batch.member(1).contact().in_contact[:, 0].any()


def test_c_export_includes_the_contact(tmp_path):
    from softcurve.compiled._export import _functions, build_and_run_test

    robot = sc.presets.ifac2020()
    law = sc.ContactLaw(1e7, damping=1.0, friction=0.5, points_per_segment=2)  # small code
    environment = sc.Environment([sc.Plane([WALL_X, 0, 0], [-1, 0, 0])], law, [RC])
    model = sc.Model(robot, environment=environment, compile=False)
    free = sc.Model(robot, compile=False)
    functions = _functions(model, None, "walled", True)
    q, qd = np.array([0.0644, 16.0, 0.0]), np.array([0.0, 50.0, 10.0])  # pressed, moving
    assert model.contact(q)["energy"] > 0
    exported_n = np.array(functions["potential_force"](q)).ravel()
    assert_close(exported_n, model.potential_force(q), rtol=1e-12, what="N(q) with contact")
    assert np.abs(exported_n - free.potential_force(q))[1] > 1e-3  # not the free model's
    qdd = np.array(functions["forward_dynamics"](q, qd, np.zeros(3), np.zeros(3))).ravel()
    assert_close(qdd, model.forward_dynamics(q, qd), rtol=1e-12, what="forward dynamics")
    exported = sc.export_c(model, tmp_path, prefix="walled")
    assert "OK" in build_and_run_test(exported, optimization="-O0")


def test_equilibrium_against_a_wall_and_its_linearization():
    """A tip force pushes the robot against the wall: the equilibrium is stable, the
    contact carries part of the load, and the wall stiffens the bending mode."""
    robot = sc.presets.ifac2020()
    free = sc.Model(robot, compile=False)
    force = np.array([0.3, 0.0, 0.0])
    loose = sc.equilibrium(free, [0.0644, 0.0, 0.0], tip_force=force)
    wall = 0.6 * loose.tip_position[0] + RC  # the free robot would pass it
    law = sc.ContactLaw(1e7, damping=1.0, smoothing=1e-6)
    environment = sc.Environment([sc.Plane([wall, 0, 0], [-1, 0, 0])], law, [RC])
    model = sc.Model(robot, environment=environment, compile=False)
    pressed = sc.equilibrium(model, loose.q, tip_force=force)
    assert pressed.success and pressed.stability == "stable", pressed.message
    contact = model.contact(pressed.q)
    assert 0.0 < -contact["forces"][0, 0] < force[0]
    assert wall - RC < pressed.tip_position[0] < wall  # the body touches the wall
    linear = sc.linearize(model, pressed.q, tip_force=force)
    assert linear.asymptotically_stable
    loose_linear = sc.linearize(free, pressed.q, tip_force=force)
    stiff, loose = np.sort(linear.frequencies), np.sort(loose_linear.frequencies)
    assert stiff[1] > 3 * loose[1]  # bending toward the wall: the wall's stiffness
    assert_close(stiff[0], loose[0], rtol=0.01, what="out-of-plane bending, frictionless")


def _history(force):
    """A ContactHistory of one obstacle pushing along x with ``force(t)`` [N], 1 ms grid."""
    t = np.arange(0.0, 3.0, 1e-3)
    forces = np.zeros((t.size, 1, 3))
    forces[:, 0, 0] = force(t)
    return sc.ContactHistory(
        t, forces, np.full_like(forces, np.nan), np.zeros((t.size, 3)), 0 * t, ("0: plane",)
    )


def test_contact_figure_shows_the_contact_alone():
    """An impact of a few ms, as examples/contact_wall.toml gives: the axis spans it."""
    history = _history(lambda t: np.where((t > 0.0295) & (t < 0.0375), 12.0, 0.0))
    figure = history.plot()
    assert not figure.axes[0].child_axes  # the impact is the whole contact: no zoom
    low, high = figure.axes[1].get_xlim()
    assert low == pytest.approx(0.029 - 0.25 * 0.009) and high == pytest.approx(0.038 + 0.00225)
    assert figure.axes[0].lines[0].get_marker() == "."  # 14 samples shown, each marked
    assert "of 3 s" in figure.axes[0].get_title()
    plt.close(figure)


def test_a_short_impact_in_a_long_contact_gets_a_zoom():
    """A 3 ms spike of 10 N at 0.5 s, then 1 N of resting contact until 2 s."""
    history = _history(
        lambda t: (
            np.where((t >= 0.5) & (t < 2.0), 1.0, 0.0)
            + np.where(np.abs(t - 0.501) < 1.5e-3, 9.0, 0.0)
        )
    )
    figure = history.plot()
    main, components = figure.axes
    (inset,) = main.child_axes
    low, high = components.get_xlim()
    assert low < 0.5 and 1.999 < high < 2.5 and low > 0.1
    zoom = inset.get_xlim()
    assert zoom[0] < 0.4995 and 0.5025 < zoom[1] and zoom[1] - zoom[0] < 0.02
    assert max(inset.lines[0].get_ydata()) == 10.0 and inset.texts[0].get_text() == "impact"
    plt.close(figure)


def test_contact_figure_without_contact_shows_the_record():
    figure = _history(lambda t: 0 * t).plot()
    assert figure.axes[1].get_xlim() == pytest.approx((0.0, 2.999))
    assert "no contact" in figure.axes[0].get_title()
    plt.close(figure)


def test_contact_figure_of_an_empty_record_is_drawn():
    """A run that failed before its first output: the figure is drawn, empty, as before
    the contact window (which raised on the empty record)."""
    empty = sc.ContactHistory(
        np.zeros(0), np.zeros((0, 1, 3)), np.zeros((0, 1, 3)), np.zeros((0, 3)), np.zeros(0),
        ("0: plane",),
    )  # fmt: skip
    figure = empty.plot()
    assert "no contact" in figure.axes[0].get_title()
    plt.close(figure)
