"""Figures: one ``.plot(ax=None)`` signature returning a Figure, drawn into new or given
Axes; the package never changes Matplotlib's backend; figures are written whole."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import types

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

import softcurve as sc
from softcurve.analysis.quasistatic import input_sweep
from softcurve.analysis.statics import equilibria
from softcurve.figures import plot_input_sweep, save_figure

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def trajectory(paper_model):
    return sc.simulate(paper_model, [0.0644, 5.0, 0.0], np.zeros(3), t_final=0.01)


@pytest.fixture(scope="module")
def batch(paper_model):
    return sc.simulate_batch(
        paper_model, [[0.064, 5.0, 0.0], [0.064, -5.0, 0.0]], np.zeros(3), t_final=0.1
    )


@pytest.fixture(scope="module")
def pressure_map():
    return sc.ConstantPressureMap.authors_fit(p_max=1e5)


@pytest.fixture(scope="module")
def table(paper_model, pressure_map):
    return equilibria(
        paper_model, starts=2, actuator=pressure_map, inputs=np.array([4e4, 0.0, 1e4])
    )


@pytest.fixture(scope="module")
def sweep(paper_model, pressure_map):
    path = np.outer(np.linspace(0.0, 1e5, 5), [1.0, 0.0, 0.0])
    return input_sweep(paper_model, pressure_map, path)


@pytest.fixture(scope="module")
def fit_report():
    x = np.linspace(-0.5, 0.5, 50)
    force = 0.01 * x + 1e-4 * np.random.default_rng(3).standard_normal(x.size)
    return sc.fit_stiffness(x, force, "linear")


# (result fixture, method, number of panels, projection of the panels)
PLOTS = [
    ("trajectory", "plot", 3, None),
    ("trajectory", "plot_tip", 1, "3d"),
    ("batch", "plot", 3, None),
    ("table", "plot", 1, None),
    ("sweep", "plot", 2, None),
    ("fit_report", "plot", 2, None),
]
IDS = [f"{name}.{method}" for name, method, _, _ in PLOTS]


def _drawn(ax) -> bool:
    return bool(ax.lines or ax.collections)


@pytest.mark.parametrize(("name", "method", "panels", "projection"), PLOTS, ids=IDS)
def test_plot_draws_a_new_figure(request, name, method, panels, projection):
    figure = getattr(request.getfixturevalue(name), method)()
    assert isinstance(figure, Figure)
    assert plt.fignum_exists(figure.number)  # made through pyplot: plt.show() shows it
    drawn = [ax for ax in figure.axes if ax.name == (projection or "rectilinear")]
    assert len(drawn) == panels and all(_drawn(ax) for ax in drawn)


@pytest.mark.parametrize(("name", "method", "panels", "projection"), PLOTS, ids=IDS)
def test_plot_draws_into_given_axes(request, name, method, panels, projection):
    figure, axes = plt.subplots(1, panels, squeeze=False, subplot_kw={"projection": projection})
    axes = list(axes.ravel())
    result = getattr(request.getfixturevalue(name), method)
    assert result(ax=axes) is figure
    assert all(_drawn(ax) for ax in axes)
    if panels == 1:
        other, ax = plt.subplots(subplot_kw={"projection": projection})
        assert result(ax) is other and _drawn(ax)


@pytest.mark.parametrize(("name", "method", "panels", "projection"), PLOTS, ids=IDS)
def test_plot_rejects_the_wrong_number_of_axes(request, name, method, panels, projection):
    result = getattr(request.getfixturevalue(name), method)
    _, axes = plt.subplots(1, panels + 1, squeeze=False, subplot_kw={"projection": projection})
    with pytest.raises(sc.ParameterError, match=rf"{panels} panel\(s\).*{panels} Matplotlib Axes"):
        result(ax=list(axes.ravel()))
    with pytest.raises(sc.ParameterError, match="must be None, a Matplotlib Axes"):
        result(ax="states.png")  # the old path argument


def test_a_subfigure_gives_its_root_figure(trajectory):
    figure = plt.figure()
    left, _ = figure.subfigures(1, 2)
    assert trajectory.plot(left.subplots(3, 1)) is figure


def test_fit_axes_as_a_grid_and_a_title(fit_report):
    figure, axes = plt.subplots(2, 1)
    assert fit_report.plot(axes, title="linear law") is figure
    assert figure.get_suptitle() == "linear law"
    assert axes[1].get_xlabel() == fit_report.abscissa_label
    assert axes[0].get_ylabel().startswith(fit_report.signals[0])


def test_tip_needs_three_dimensional_axes(trajectory):
    _, ax = plt.subplots()
    with pytest.raises(sc.ParameterError, match="projection='3d'"):
        trajectory.plot_tip(ax)


def test_sweep_abscissa_is_a_keyword_option(sweep):
    figure = sweep.plot()
    assert figure.axes[0].get_xlabel().startswith("u1")  # the input that varies most
    x = np.arange(sweep.inputs.shape[0], dtype=float)
    figure = sweep.plot(x=x, x_label="step [-]")
    np.testing.assert_array_equal(figure.axes[0].lines[0].get_xdata(), x)
    assert figure.axes[1].get_xlabel() == "step [-]"
    with pytest.raises(sc.ParameterError, match=r"x must have shape \(5,\)"):
        sweep.plot(x=x[:3])


def test_sweep_pressures_are_drawn_in_kilopascal(sweep):
    pressures = types.SimpleNamespace(
        inputs=np.column_stack([np.zeros(5), np.linspace(0.0, 2e4, 5)]),
        input_unit="Pa",
        tip=sweep.tip,
        curvature=sweep.curvature,
        stability=sweep.stability,
    )
    figure = plot_input_sweep(pressures)
    assert figure.axes[0].get_xlabel() == "u2 [kPa]"
    np.testing.assert_allclose(figure.axes[0].lines[0].get_xdata(), np.linspace(0.0, 20.0, 5))


def test_batch_members_option(batch):
    figure = batch.plot(members=1)
    assert len(figure.axes) == 3 and len(figure.axes[0].lines) == 1
    assert figure.axes[0].get_title() == "1 of 2 members"
    with pytest.raises(sc.ParameterError, match="members must be >= 1"):
        batch.plot(members=0)


def test_figures_of_a_two_segment_trajectory(two_segment_model, tmp_path):
    q0 = np.array([0.0644, 5.0, 0.0, 0.0644, 0.0, 5.0])
    trajectory = sc.simulate(two_segment_model, q0, np.zeros(6), t_final=0.01)
    figure = trajectory.plot()
    assert len(figure.axes[0].lines) == 2
    assert save_figure(figure, tmp_path / "states.png").stat().st_size > 0
    save_figure(trajectory.plot_tip(), tmp_path / "tip.png")
    path = trajectory.animate(tmp_path / "backbone.gif", fps=500)
    assert path.read_bytes()[:6] == b"GIF89a"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["backbone.gif", "states.png", "tip.png"]
    with pytest.raises(sc.ParameterError, match=r"\.gif or \.mp4"):
        trajectory.animate(tmp_path / "backbone.png")


def test_equilibria_and_sweep_figures_are_written(table, sweep, tmp_path):
    assert save_figure(sweep.plot(), tmp_path / "sweep.png").stat().st_size > 0
    assert save_figure(table.plot(), tmp_path / "equilibria.png").stat().st_size > 0
    assert len(table) == 1


def test_plotting_leaves_the_backend_alone(tmp_path):
    """A user's script: import softcurve, simulate, plot; the backend the user chose stays."""
    script = textwrap.dedent(
        """
        import matplotlib
        import numpy as np
        import softcurve as sc

        before = matplotlib.get_backend()
        model = sc.Model(sc.presets.ifac2020(), compile=False)
        trajectory = sc.simulate(model, [0.0644, 5.0, 0.0], np.zeros(3), t_final=0.005)
        trajectory.plot()
        trajectory.plot_tip()
        import matplotlib.pyplot as plt

        print(before, matplotlib.get_backend(), len(plt.get_fignums()))
        """
    )
    environment = {**os.environ, "MPLBACKEND": "svg"}
    run = subprocess.run(
        [sys.executable, "-c", script],
        env=environment,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["svg", "svg", "2"]


def test_save_figure_writes_whole_files(tmp_path):
    figure, ax = plt.subplots()
    ax.plot([0.0, 1.0], [0.0, 1.0])
    assert save_figure(figure, tmp_path / "line.png") == tmp_path / "line.png"
    assert (tmp_path / "line.png").read_bytes()[:8] == PNG_SIGNATURE
    save_figure(figure, tmp_path / "line.svg", dpi=72)
    assert b"<svg" in (tmp_path / "line.svg").read_bytes()[:1000]
    save_figure(figure, tmp_path / "line")  # no suffix: PNG
    assert (tmp_path / "line").read_bytes()[:8] == PNG_SIGNATURE
    assert sorted(p.name for p in tmp_path.iterdir()) == ["line", "line.png", "line.svg"]


def test_save_figure_failing_keeps_the_old_file(tmp_path, monkeypatch):
    figure, _ = plt.subplots()
    target = save_figure(figure, tmp_path / "kept.png")
    old = target.read_bytes()

    def fail_halfway(path, **options):
        with open(path, "wb") as half:
            half.write(old[: len(old) // 2])
        raise OSError("disk full")

    monkeypatch.setattr(figure, "savefig", fail_halfway)
    with pytest.raises(OSError, match="disk full"):
        save_figure(figure, target)
    assert target.read_bytes() == old
    assert [p.name for p in tmp_path.iterdir()] == ["kept.png"]  # no temporary file left


def test_save_figure_rejects_what_it_cannot_write(trajectory, tmp_path):
    figure = trajectory.plot()
    with pytest.raises(sc.ParameterError, match="suffix must be one of"):
        save_figure(figure, tmp_path / "states.docx")
    with pytest.raises(sc.ParameterError, match="must be a matplotlib.figure.Figure"):
        save_figure(figure.axes[0], tmp_path / "states.png")
    with pytest.raises(sc.ParameterError, match="dpi must be > 0"):
        save_figure(figure, tmp_path / "states.png", dpi=0)
    assert list(tmp_path.iterdir()) == []


def test_the_states_of_an_actuated_run_have_a_panel_of_its_inputs(paper_model):
    actuator = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-4, p_max=6e4)
    run = sc.simulate(paper_model, [0.0644, 0, 0], [0, 0, 0], actuator=actuator,
                      inputs=[2e4, 0, 0], t_final=0.05)  # fmt: skip
    axes = run.plot().axes
    assert len(axes) == 4 and axes[-1].get_ylabel() == "pressures [kPa]"
    assert axes[-1].get_xlabel() == "time t [s]" and axes[2].get_xlabel() == ""
    assert axes[-1].lines[0].get_ydata()[-1] == pytest.approx(20.0)  # kPa
    assert axes[-1].get_xlim() == axes[0].get_xlim()
    assert len(run.plot(inputs=False).axes) == 3
    # the caller's three Axes keep the states alone; four take the inputs too
    _, three = plt.subplots(3)
    assert len(run.plot(three).axes) == 3
    _, four = plt.subplots(4)
    assert run.plot(four, inputs=True).axes[3].get_ylabel() == "pressures [kPa]"
    unactuated = sc.simulate(paper_model, [0.0644, 5.0, 0.0], np.zeros(3), t_final=0.01)
    assert len(unactuated.plot().axes) == 3
    with pytest.raises(sc.ParameterError, match="inputs=True needs"):
        unactuated.plot(inputs=True)


def test_the_equilibria_figure_draws_backbones_in_millimetres(table):
    """As every other figure of a robot (before: metres, without a title)."""
    figure = table.plot()
    (ax,) = figure.axes
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [mm]", "z [mm]")
    assert ax.get_title().endswith("seen along y")
    z = np.concatenate([line.get_ydata() for line in ax.lines])
    rest = 1e3 * table.load.model.robot.rest_length  # [mm]
    assert 0.5 * rest < z.max() <= 1.5 * rest
    plt.close(figure)


def test_a_rigid_body_and_a_twisted_segment_are_drawn(tmp_path):
    """The shape figure of a six-strain segment twisted by 1 rad (straight) carrying a
    gripper: the gripper a grey bar of its diameter from its base to its tip, the
    segment's stripe at its radius turning by the twist in the top view."""
    from matplotlib.patches import Polygon

    from tests.test_kinds import six_strain_gripper_robot, twisted

    robot = six_strain_gripper_robot()
    model = sc.Model(robot, compile=False)
    segment, gripper = robot.segments
    q = twisted(robot, twist=10.0)  # 10 1/m over 0.1 m: 1 rad
    figure = sc.figures.plot_configuration(model, q, points=41)
    path = save_figure(figure, tmp_path / "gripper.png")
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    side, top = figure.axes
    bars = [p for p in side.patches if isinstance(p, Polygon)]
    assert len(bars) == 1 and bars[0].get_label() == "rigid body"
    base = model.pose(q, 0.5).position
    tip = model.pose(q, 1.0).position
    corners = bars[0].get_xy()[:4]  # mm, x-z
    ends = 1e3 * np.array([base[[0, 2]], tip[[0, 2]]])
    width = np.linalg.norm(corners[0] - corners[3])
    np.testing.assert_allclose(width, 2e3 * gripper.radius, rtol=1e-12)
    np.testing.assert_allclose(corners[:2].mean(axis=0) + corners[2:].mean(axis=0),
                               ends.sum(axis=0), atol=1e-9)  # fmt: skip
    stripe = next(line for line in top.lines if line.get_label() == "stripe (twist)")
    x, y = stripe.get_data()
    radius = 1e3 * segment.radius
    np.testing.assert_allclose(np.hypot(x, y), radius, rtol=1e-9)  # on the surface
    turned = np.unwrap(np.arctan2(y, x))
    np.testing.assert_allclose(turned[-1] - turned[0], 1.0, rtol=1e-9)  # the twist
    assert np.all(np.diff(turned) > 0)  # turning steadily, one way
    paper = sc.figures.plot_configuration(sc.Model(sc.presets.ifac2020(), compile=False),
                                          [0.064, 20.0, 0.0])  # fmt: skip
    labels = [line.get_label() for ax in paper.axes for line in ax.lines]
    assert "stripe (twist)" not in labels and not paper.axes[0].patches  # cannot twist


def test_the_states_of_a_six_strain_robot_are_its_strains(tmp_path):
    """One panel per strain, each element that has it a line (the gripper has none)."""
    from tests.test_kinds import six_strain_gripper_robot, twisted

    robot = six_strain_gripper_robot()
    model = sc.Model(robot, compile=False)
    run = sc.simulate(model, twisted(robot, twist=5.0), np.zeros(robot.n), t_final=0.01)
    figure = run.plot()
    labels = [ax.get_ylabel() for ax in figure.axes]
    units = ("1/m",) * 3 + ("-",) * 3
    assert labels == [f"{s} [{u}]" for s, u in zip(sc.STRAINS, units, strict=True)]
    twist = figure.axes[sc.STRAINS.index("twist")].lines
    assert len(twist) == 1
    np.testing.assert_array_equal(twist[0].get_ydata(), run.q[:, sc.STRAINS.index("twist")])
    save_figure(figure, tmp_path / "states.png")


def test_the_animation_draws_the_gripper_and_the_stripe(tmp_path):
    """Frames of a six-strain segment carrying a gripper: a dark grey bar (the gripper)
    and an orange stripe (the twist) besides the blue segment; the paper's robot has
    neither."""
    from PIL import Image

    from tests.test_kinds import six_strain_gripper_robot, twisted

    def colours(model, q0):
        run = sc.simulate(model, q0, np.zeros(model.n), t_final=0.04)
        path = sc.figures.animate(run, tmp_path / "robot.gif", model, fps=25, figsize=(3, 3))
        with Image.open(path) as gif:
            rgb = np.asarray(gif.convert("RGB"), dtype=float) / 255
        grey = (np.ptp(rgb, axis=-1) < 0.05) & (np.abs(rgb.mean(axis=-1) - 0.35) < 0.06)
        orange = (rgb[..., 0] > 0.8) & (np.abs(rgb[..., 1] - 0.5) < 0.12) & (rgb[..., 2] < 0.25)
        return grey.sum(), orange.sum()

    robot = six_strain_gripper_robot()
    grey, orange = colours(sc.Model(robot, compile=False), twisted(robot, twist=10.0))
    paper = sc.Model(sc.presets.ifac2020(), compile=False)
    text, none = colours(paper, [0.064, 10.0, 0.0])  # greys of the ticks' text alone
    assert grey > text + 100 and orange > 20 and none == 0, (grey, text, orange, none)
