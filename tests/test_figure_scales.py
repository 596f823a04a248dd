"""The static figures as a new user meets them: equal axes on the tip plot, a time window
that follows the motion, round-off drawn as zero, and the size, resolution and frame
rate of the animation and the command's figures as options."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from PIL import Image

import softcurve as sc
from softcurve.base.validation import ParameterError
from softcurve.cli import main
from softcurve.figures.scales import equal_limits, settled_time, time_window
from softcurve.figures.trajectories import animation_axes


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _synthetic(t_final=3.0, planar=False):
    """A ringing that settles at about 0.3 s, recorded for ``t_final`` seconds."""
    t = np.arange(0.0, t_final, 1e-3)
    ring = 20.0 * np.exp(-t / 0.05) * np.cos(60.0 * t)
    ky = 1e-26 * np.sin(t) if planar else 0.5 * ring
    q = np.column_stack([0.064 + 1e-3 * ring / 20.0, ring, ky])
    tip = np.column_stack(
        [0.03 * np.sin(ring / 40.0), 1e-29 * np.cos(t) if planar else ky, 0.06 + 0 * t]
    )
    return sc.Trajectory(t, q, np.zeros_like(q), np.empty((t.size, 0)), tip_positions=tip)


def test_settled_time_and_automatic_window():
    trajectory = _synthetic()
    settled = settled_time(trajectory.t, trajectory.q)
    assert 0.1 < settled < 0.5
    start, end = time_window(trajectory.t, trajectory.q, "auto")
    assert start == 0.0 and end == pytest.approx(1.25 * settled)
    axes = trajectory.plot().axes
    assert axes[-1].get_xlim() == pytest.approx((0.0, end))
    assert "of 3 s" in axes[0].get_title()


def test_window_options():
    trajectory = _synthetic()
    assert trajectory.plot(window="all").axes[-1].get_xlim() == pytest.approx(
        (0.0, trajectory.t[-1])
    )
    assert trajectory.plot(window=(0.1, 0.2)).axes[-1].get_xlim() == pytest.approx((0.1, 0.2))
    for bad in ("some", (0.2, 0.1), 3.0):
        with pytest.raises(ParameterError, match="window"):
            trajectory.plot(window=bad)


def test_a_motion_that_never_settles_shows_everything():
    t = np.linspace(0.0, 2.0, 400)
    assert time_window(t, np.sin(10 * t)[:, None], "auto") == (0.0, 2.0)


def test_round_off_of_a_planar_run_is_drawn_as_zero():
    trajectory = _synthetic(planar=True)
    states = trajectory.plot().axes
    ky = states[2].lines[0].get_ydata()
    assert np.all(ky == 0.0) and "1e-09" in states[2].get_ylabel()
    assert "1e-09" not in states[1].get_ylabel()
    # the round-off ky "moves" until the end; the window follows what is drawn (kx)
    assert states[-1].get_xlim()[1] < 0.6 < trajectory.t[-1]
    (ax,) = [a for a in trajectory.plot_tip().axes if a.name == "3d"]
    assert "1e-09" in ax.get_ylabel() and "1e-09" not in ax.get_xlabel()
    assert np.all(ax.collections[0]._offsets3d[1] == 0.0)


def test_tip_plot_has_equal_axes():
    (ax,) = [a for a in _synthetic().plot_tip().axes if a.name == "3d"]
    spans = [np.diff(getattr(ax, f"get_{k}lim")())[0] for k in "xyz"]
    assert spans == pytest.approx([spans[0]] * 3)
    assert ax.get_box_aspect() == pytest.approx([ax.get_box_aspect()[0]] * 3)


def test_equal_limits_are_a_cube():
    limits = equal_limits([[0, 0, 0], [1, 2, 10]])
    assert np.diff(limits, axis=1).ravel() == pytest.approx([11.0] * 3)


def test_animation_labels_stay_inside_the_frame():
    figure, ax = animation_axes((4.0, 4.0), equal_limits([[-30, -30, 0], [30, 30, 70]]))
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    renderer = canvas.get_renderer()
    box = figure.bbox
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        label = axis.label.get_window_extent(renderer)
        assert box.x0 <= label.x0 and label.x1 <= box.x1, axis.label.get_text()
        assert box.y0 <= label.y0 and label.y1 <= box.y1, axis.label.get_text()


def test_animation_size_resolution_and_frame_rate(paper_model, tmp_path):
    trajectory = sc.simulate(paper_model, [0.064, 10.0, 0.0], np.zeros(3), t_final=0.2)
    path = trajectory.animate(tmp_path / "a.gif", fps=10, dpi=50, figsize=(3.0, 2.0))
    with Image.open(path) as image:
        assert image.size == (150, 100)
        assert image.n_frames == 2
        assert image.info["duration"] == pytest.approx(100, abs=10)
    with pytest.raises(ParameterError, match="figsize"):
        trajectory.animate(tmp_path / "b.gif", figsize=(3.0, -1.0))


def test_command_figure_size_dpi_and_viewer(tmp_path, capsys):
    pytest.importorskip("plotly")
    out = tmp_path / "out"
    code = main(
        ["simulate", "-o", str(out), "--t-final", "0.2", "--no-progress", "--figsize", "4", "3",
         "--dpi", "50", "--html", "-q"]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().err
    for name in ("states.png", "tip.png"):
        with Image.open(out / name) as image:
            assert image.size == (200, 150)
    assert (out / "viewer.html").stat().st_size > 1e6  # Plotly inside
    assert main(["simulate", "-o", str(out), "--figsize", "4", "0"]) == 2
    assert "--figsize" in capsys.readouterr().err
