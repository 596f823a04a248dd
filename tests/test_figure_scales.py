"""The static figures as a new user meets them: equal axes on the tip plot, a time window
that follows the motion (states, tip path and animation alike), round-off drawn as zero,
the animation's ticks, frames and progress, and the size, resolution and frame rate of
the animation and the command's figures as options."""

from __future__ import annotations

import os
import sys

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from mpl_toolkits.mplot3d import proj3d
from PIL import Image

import softcurve as sc
from softcurve.base.validation import ParameterError
from softcurve.cli import main
from softcurve.figures.scales import equal_limits, settled_time, time_window
from softcurve.figures.trajectories import animation_axes, frame_samples, motion_window


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


@pytest.fixture(scope="module")
def ringing(paper_model):
    """The paper's case over 2 s: it rings for about 0.65 s, then rests."""
    return sc.simulate(paper_model, [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0], t_final=2.0)


def test_animation_frames_cover_only_the_motion(ringing, tmp_path):
    start, end = motion_window(ringing)
    assert start == 0.0 and 0.3 < end < 1.0
    frames = frame_samples(ringing, fps=25)
    assert frames.size == np.ceil(end * 25) and ringing.t[frames[-1]] <= end
    assert frame_samples(ringing, window="all", fps=25).size == 50
    assert ringing.t[frame_samples(ringing, window=(1.0, 1.2), fps=25)] == pytest.approx(
        [1.0, 1.04, 1.08, 1.12, 1.16]
    )
    with pytest.raises(ParameterError, match="overlap the record"):
        frame_samples(ringing, window=(3.0, 4.0))
    path = ringing.animate(tmp_path / "a.gif", dpi=40)
    with Image.open(path) as image:
        assert image.n_frames == frames.size


def test_the_tip_figure_shows_the_states_window(ringing):
    start, end = motion_window(ringing)
    figure = ringing.plot_tip()
    (ax,) = [a for a in figure.axes if a.name == "3d"]
    times = ax.collections[0].get_array()
    assert times.min() == start and end - 1e-3 < times.max() <= end
    assert ax.collections[0].get_clim() == pytest.approx((start, times.max()))
    (colour_bar,) = [a for a in figure.axes if a.name != "3d"]
    assert colour_bar.get_ylim()[1] == pytest.approx(times.max())
    assert f"of {ringing.t[-1]:.3g} s" in ax.get_title()
    whole = [a for a in ringing.plot_tip(window="all").axes if a.name == "3d"][0]
    assert whole.collections[0].get_array().max() == ringing.t[-1]


def test_animation_tick_labels_do_not_overlap():
    """Adjacent ticks of each axis lie further apart on the frame than their labels are
    long along the axis (what the frame shows: labels one after another)."""
    limits = equal_limits([[-40, -40, -10], [40, 40, 75]])
    figure, ax = animation_axes((5.0, 5.0), limits, 80)
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    for k, axis in enumerate((ax.xaxis, ax.yaxis, ax.zaxis)):
        low, high = limits[k]
        ticks = [v for v in axis.get_majorticklocs() if low <= v <= high]
        assert len(ticks) >= 3, axis  # every axis keeps ticks
        corner = limits[:, 0].copy()
        points = np.repeat(corner[None, :], len(ticks), axis=0)
        points[:, k] = ticks
        x, y, _ = proj3d.proj_transform(*points.T, ax.get_proj())
        pixels = ax.transData.transform(np.column_stack([x, y]))
        steps = np.diff(pixels, axis=0)
        direction = np.abs(steps[0]) / np.linalg.norm(steps[0])
        sizes = [
            label.get_window_extent(renderer) for label in axis.get_ticklabels() if label.get_text()
        ]
        along = max(box.width * direction[0] + box.height * direction[1] for box in sizes)
        assert np.linalg.norm(steps, axis=1).min() > along, axis


def test_animation_progress_counts_frames(ringing, tmp_path, capsys):
    ringing.animate(tmp_path / "a.gif", dpi=40, progress=True)
    frames = frame_samples(ringing).size
    assert f"{frames}/{frames} frames" in capsys.readouterr().err


def test_mp4_frames_go_to_ffmpeg(ringing, tmp_path, monkeypatch):
    """A stand-in ffmpeg on the PATH that writes how many bytes it was fed."""
    fake = tmp_path / "bin" / "ffmpeg"
    fake.parent.mkdir()
    fake.write_text(
        f"#!{sys.executable}\nimport sys\n"
        "open(sys.argv[-1], 'w').write(str(len(sys.stdin.buffer.read())))\n"
    )
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake.parent}{os.pathsep}{os.environ['PATH']}")
    path = ringing.animate(tmp_path / "a.mp4", dpi=40, figsize=(3.0, 2.0))
    assert int(path.read_text()) == frame_samples(ringing).size * 120 * 80 * 3


def test_command_says_what_it_animates(tmp_path, capsys):
    code = main(["simulate", "-o", str(tmp_path), "--t-final", "2", "--animate", "--no-figures",
                 "--progress", "--dpi", "40"])  # fmt: skip
    assert code == 0
    error = capsys.readouterr().err
    # by default the motion: the paper's case settles within 0.7 s of its 2 s
    assert "writing animation.gif, 17 frames of t = 0 .. 0.6" in error
    assert "17/17 frames" in error
    with Image.open(tmp_path / "animation.gif") as image:
        assert image.n_frames == 17


def test_the_command_animates_a_chosen_window_and_a_long_one_faster(tmp_path, capsys):
    long = ["simulate", "-o", str(tmp_path), "--t-final", "12", "--dt", "0.01", "--animate",
            "--no-figures", "--dpi", "30"]  # fmt: skip
    assert main([*long, "--window", "0.2", "0.52"]) == 0
    assert "writing animation.gif, 8 frames of t = 0.2 .. 0.52 s ..." in capsys.readouterr().err
    assert main([*long, "--window", "0", "12"]) == 0
    # 12 s at 25 frames per second is 300 frames; MOST_FRAMES (250) play it faster
    assert "250 frames of t = 0 .. 12 s at 1.2x real time" in capsys.readouterr().err
    with Image.open(tmp_path / "animation.gif") as image:
        assert image.n_frames == 250


@pytest.mark.parametrize(
    "window", [("-0.1", "0.5"), ("0.5", "0.5"), ("0.6", "0.5"), ("0", "3"), ("0", "nan")]
)
def test_a_window_outside_the_run_exits_2_before_any_work(tmp_path, capsys, window):
    out = tmp_path / "out"
    assert main(["simulate", "-o", str(out), "--t-final", "2", "--window", *window]) == 2
    error = capsys.readouterr().err
    assert "--window must be two times 0 <= T0 < T1 <= the end time 2 s" in error
    assert error.count("\n") == 1 and not out.exists()  # one line, nothing written


def test_the_figures_draw_the_window_and_say_it(ringing):
    states = ringing.plot(window=(0.2, 0.5))
    assert states.axes[-1].get_xlim() == pytest.approx((0.2, 0.5))
    assert states.axes[0].get_title().endswith(", t = 0.2 .. 0.5 s of 2 s")
    whole = ringing.plot(window="all")
    assert whole.axes[0].get_title().endswith(", t = 0 .. 2 s")  # said for the whole run too


@pytest.mark.parametrize("window", ["auto", "all", (0.1, 0.25)])
def test_the_tip_figure_title_and_legend_agree_on_the_window(ringing, window):
    (ax,) = [a for a in ringing.plot_tip(window=window).axes if a.name == "3d"]
    start, end = (text.get_text().split("t = ")[1] for text in ax.get_legend().get_texts())
    assert f", t = {start.removesuffix(' s')} .. {end}" in ax.get_title(), ax.get_title()


def _segments(count: int):
    """A ringing of ``count`` segments, each ``_synthetic``'s scaled."""
    one = _synthetic()
    q = np.hstack([one.q * (1.0 + 0.1 * i) for i in range(count)])
    return sc.Trajectory(one.t, q, np.zeros_like(q), np.empty((one.t.size, 0)))


@pytest.mark.parametrize("count", [2, 6, 20])
def test_the_states_legend_covers_no_curve(count):
    """The legend of many segments stands beside the panels, clear of the data area."""
    figure = _segments(count).plot()
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    legend = figure.axes[0].get_legend()
    assert len(legend.get_texts()) == count
    box = legend.get_window_extent(renderer)
    for axis in figure.axes:
        data = axis.get_window_extent(renderer)
        assert box.x0 >= data.x1 or box.y1 <= data.y0 or box.y0 >= data.y1, axis
    assert box.x1 <= figure.bbox.x1  # inside the figure


def test_sweep_figure_draws_round_off_as_a_constant():
    """A tip coordinate that is round-off of 0 (1e-5 mm on a 65 mm reach) and one of
    exact zeros are drawn as constants and say so, without an offset or exponent label
    of noise; an output that varies is drawn as its values."""
    from softcurve.figures import plot_sweep

    count = 8
    z = 0.0648 + 1e-4 * np.linspace(0.0, 1.0, count)  # [m]: 0.1 mm, a real spread
    table = {
        "index": np.arange(count),
        "q0[1]": np.linspace(-20.0, 20.0, count),
        "final_tip_x": 1e-8 * np.random.default_rng(0).standard_normal(count),  # [m]
        "final_tip_y": np.zeros(count),
        "final_tip_z": z,
        "status": np.array(["success"] * count),
    }
    figure = plot_sweep(table)
    figure.canvas.draw()
    x_axis, y_axis, z_axis = figure.axes
    for axis in (x_axis, y_axis):
        assert axis.yaxis.get_offset_text().get_text() == "", axis.get_ylabel()
        assert np.all(axis.lines[0].get_ydata() == 0.0)
        (text,) = axis.texts
        assert text.get_text().startswith("constant: 0 mm (spread < 0.01 % of 64.9 mm)")
    assert not len(z_axis.texts) and z_axis.yaxis.get_offset_text().get_text() == ""
    np.testing.assert_array_equal(z_axis.lines[0].get_ydata(), 1e3 * z)
