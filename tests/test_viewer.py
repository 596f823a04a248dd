"""The interactive 3-D viewer: the scene it draws, one offline HTML file, and the page
in a real browser (headless Chromium over the DevTools pipe, tests/chromium.py)."""

from __future__ import annotations

import io
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import softcurve as sc
from softcurve.base.validation import ParameterError
from softcurve.figures.scene import build_scene, frame_indices, ring_frames

pytest.importorskip("plotly", reason="the viewer needs Plotly (pip install softcurve[viewer])")

sys.path.insert(0, str(Path(__file__).parent))
from chromium import Chromium, find_browser

FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"
UPDATE_SCREENSHOTS = "SOFTCURVE_UPDATE_SCREENSHOTS"
"""Set to 1 to rewrite docs/figures/viewer_t0.png and viewer_t1.png from the test."""


@pytest.fixture(scope="module")
def trajectory(paper_model):
    return sc.simulate(paper_model, [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0], t_final=0.3)


@pytest.fixture(scope="module")
def tendons():
    return sc.TendonActuator.three_per_segment(distance=0.015, t_max=20.0)


@pytest.fixture(scope="module")
def pulled(paper_model, tendons):
    return sc.simulate(
        paper_model, [0.064, 0.0, 0.0], np.zeros(3), actuator=tendons, inputs=[5.0, 0.0, 0.0],
        t_final=0.2,
    )  # fmt: skip


class Box:
    """A drawable obstacle: a unit cube's surface, 12 triangles."""

    def surface(self):
        corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)]) * 0.02
        faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                 [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]  # fmt: skip
        return corners + [0.05, 0.0, 0.0], np.array(faces)


def test_rings_are_the_models_poses(paper_model):
    q = np.array([[0.064, 25.0, 3.0], [0.07, -10.0, 8.0]])
    rings = ring_frames(paper_model, q, 5)  # s = 0, 0.25, ..., 1
    for f in range(2):
        rotation, position = paper_model.pose(q[f], 0.75)
        np.testing.assert_allclose(rings[f, 3, :3], 1e3 * position, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(rings[f, 3, 3:6], rotation[:, 0], atol=1e-12)
        np.testing.assert_allclose(rings[f, 3, 6:], rotation[:, 1], atol=1e-12)


def test_frames_at_the_frame_rate():
    t = np.arange(0.0, 1.0001, 0.001)
    frames = frame_indices(t, 25)
    assert frames.size == 26 and frames[-1] == t.size - 1
    np.testing.assert_allclose(np.diff(t[frames]), 0.04, atol=1e-9)
    with pytest.raises(ParameterError, match="fps"):
        frame_indices(t, 0)


def test_scene_axes_are_equal_and_hold_the_robot(paper_model, trajectory):
    scene = build_scene(paper_model, trajectory.q, ["a"] * trajectory.t.size, rings=4)
    spans = np.diff(scene.bounds, axis=1).ravel()
    np.testing.assert_allclose(spans, spans[0])
    centres = scene.rings[..., :3].reshape(-1, 3)
    assert (centres >= scene.bounds[:, 0]).all() and (centres <= scene.bounds[:, 1]).all()


class Wall:
    """A drawable obstacle ten times the robot's size: a 0.6 m square at x = -45 mm."""

    def surface(self):
        y, z = np.meshgrid([-0.3, 0.3], [-0.3, 0.3])
        vertices = np.stack([np.full(4, -0.045), y.ravel(), z.ravel()], axis=1)
        return vertices, np.array([[0, 1, 3], [0, 3, 2]])


def test_a_large_obstacle_is_cut_to_the_robots_box_not_framed(paper_model, trajectory):
    """The scene is framed on the robot's motion, the obstacle cut to that box (before,
    a 0.6 m wall set the axes and the robot filled a tenth of them)."""
    labels = ["a"] * trajectory.t.size
    alone = build_scene(paper_model, trajectory.q, labels, rings=4)
    scene = build_scene(paper_model, trajectory.q, labels, rings=4, obstacles=[Wall()])
    np.testing.assert_array_equal(scene.bounds, alone.bounds)  # the wall moves no axis
    assert np.diff(scene.bounds, axis=1).max() < 0.3 * 600  # mm: the robot's size
    (wall,) = scene.obstacles
    vertices = np.array(wall["vertices"])
    assert (vertices >= scene.bounds[:, 0] - 1e-4).all()  # to the 4 decimals sent
    assert (vertices <= scene.bounds[:, 1] + 1e-4).all()
    np.testing.assert_allclose(vertices[:, 0], -45.0)  # still the wall's plane [mm]
    # the part inside covers the box's whole y-z face: area of the clipped triangles
    a, b, c = (vertices[np.array(wall["triangles"])[:, k]] for k in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    span = np.diff(scene.bounds, axis=1).ravel()
    np.testing.assert_allclose(area, span[1] * span[2], rtol=1e-6)


def test_an_obstacle_outside_the_robots_space_is_said_not_drawn(paper_model, trajectory):
    class Far(Wall):
        def surface(self):
            vertices, triangles = super().surface()
            return vertices + [2.0, 0.0, 0.0], triangles  # 2 m away

    labels = ["a"] * trajectory.t.size
    with pytest.warns(UserWarning, match="obstacle 2 lies wholly outside .* not drawn"):
        scene = build_scene(paper_model, trajectory.q, labels, rings=4, obstacles=[Wall(), Far()])
    assert len(scene.obstacles) == 1


def test_clipping_a_mesh_keeps_what_is_inside_and_drops_what_is_not():
    from softcurve.figures.scene import clip_mesh

    vertices = np.array([[0.0, 0, 0], [2.0, 0, 0], [0.0, 2, 0]])
    points, faces = clip_mesh(vertices, [[0, 1, 2]], [0.0, 0, -1], [1.0, 1, 1])
    a, b, c = (points[faces[:, k]] for k in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    np.testing.assert_allclose(area, 1.0)  # the unit square of the triangle x + y <= 2
    inside, _ = clip_mesh(vertices * 0.25, [[0, 1, 2]], [0.0, 0, -1], [1.0, 1, 1])
    np.testing.assert_allclose(inside, vertices * 0.25)  # wholly inside: unchanged
    outside, faces = clip_mesh(vertices + 5.0, [[0, 1, 2]], [0.0, 0, -1], [1.0, 1, 1])
    assert outside.shape == (0, 3) and faces.shape == (0, 3)


def test_one_self_contained_file(trajectory, tmp_path):
    path = trajectory.to_html(tmp_path / "robot.html")
    text = path.read_text()
    assert not re.search(r"<script[^>]+src=|<link\b|@import", text)  # every script embedded
    assert text.count("<html") == 1 and "Plotly.newPlot" in text
    assert [p.name for p in tmp_path.iterdir()] == ["robot.html"]  # written whole
    assert '"tendons":[]' in text


def test_tendons_and_obstacles_are_drawn(pulled, tmp_path):
    text = pulled.to_html(tmp_path / "tendons.html", obstacles=[Box()]).read_text()
    assert text.count('"azimuth"') == 3
    assert '"obstacles":[{"vertices"' in text
    with pytest.raises(ParameterError, match=r"obstacles\[0\]"):
        pulled.to_html(tmp_path / "bad.html", obstacles=[object()])


def test_the_models_environment_is_drawn(tmp_path):
    """Each obstacle of ``Model(robot, environment=)`` becomes one mesh in the page, its
    vertices on the obstacle's surface."""
    import json

    from softcurve.figures.obstacles import environment_meshes

    sphere = sc.Sphere(center=[-0.05, 0.0, 0.05], radius=0.01)
    capsule = sc.Capsule(a=[0.0, 0.05, 0.0], b=[0.0, 0.05, 0.08], radius=0.005)
    plane = sc.Plane(point=[0.04, 0.0, 0.0], normal=[-1.0, 0.0, 0.0])
    environment = sc.Environment([plane, sphere, capsule], sc.ContactLaw(stiffness=1e6))
    model = sc.Model(sc.presets.ifac2020(), environment=environment, compile=False)
    sphere_mesh, capsule_mesh = environment_meshes(model, 0.1)[1:]
    vertices, triangles = sphere_mesh.surface()
    assert np.allclose(np.linalg.norm(vertices - sphere.center, axis=1), sphere.radius)
    assert triangles.max() < len(vertices) and triangles.shape[1] == 3
    vertices, _ = capsule_mesh.surface()
    along = np.clip((vertices - capsule.a) @ (capsule.b - capsule.a) / 0.08**2, 0, 1)
    nearest = capsule.a + along[:, None] * (capsule.b - capsule.a)
    assert np.allclose(np.linalg.norm(vertices - nearest, axis=1), capsule.radius)
    run = sc.simulate(model, [0.064, 5.0, 0.0], np.zeros(3), t_final=0.05)
    text = run.to_html(tmp_path / "walls.html", obstacles=[Box()]).read_text()
    scene = json.loads(re.search(r'"obstacles":(\[.*?\]),"baseAxes"', text).group(1))
    assert len(scene) == 4  # three of the environment, the Box given by hand
    # obstacles are given in the base frame and drawn, like the robot, in the world frame
    flipped = sc.presets.ifac2020().replace(base_rotation=np.diag([1.0, -1.0, -1.0]))
    model = sc.Model(flipped, environment=environment, compile=False)
    vertices, _ = environment_meshes(model, 0.1)[1].surface()
    center = np.diag([1.0, -1.0, -1.0]) @ sphere.center
    assert np.allclose(np.linalg.norm(vertices - center, axis=1), sphere.radius)
    # and on a moved base, moved with it
    moved = flipped.replace(base_position=[0.3, -0.1, 0.2])
    model = sc.Model(moved, environment=environment, compile=False)
    vertices, _ = environment_meshes(model, 0.1)[1].surface()
    center = center + [0.3, -0.1, 0.2]
    assert np.allclose(np.linalg.norm(vertices - center, axis=1), sphere.radius)


def test_batch_members_and_equilibria(paper_model, tendons, tmp_path):
    batch = sc.simulate_batch(
        paper_model, [[0.064, 5.0, 0.0], [0.064, -5.0, 0.0]], np.zeros(3), t_final=0.05
    )
    assert batch.member(1).to_html(tmp_path / "member.html").stat().st_size > 0
    table = sc.equilibria(paper_model, starts=2, actuator=tendons, inputs=[5.0, 0.0, 0.0])
    assert '"azimuth"' in table.to_html(tmp_path / "table.html").read_text()
    assert table[0].to_html(tmp_path / "one.html", paper_model).exists()


def test_equilibria_command_writes_the_viewer(tmp_path, capsys):
    from softcurve.cli import main

    target = tmp_path / "views" / "equilibria.html"
    assert main(["equilibria", "--starts", "2", "--html", str(target)]) == 0
    assert f"viewer: {target}" in capsys.readouterr().out
    assert "<script" in target.read_text() and "https://" not in target.read_text()[:2000]
    assert main(["equilibria", "--starts", "2", "--html", str(tmp_path)]) == 2  # a folder
    assert "--html" in capsys.readouterr().err


def test_viewer_refuses_other_suffixes(trajectory, tmp_path):
    with pytest.raises(ParameterError, match=r"\.html"):
        trajectory.to_html(tmp_path / "robot.png")


def _robot_pixels(png: bytes) -> np.ndarray:
    """Where the first segment's blue (#1f77b4, shaded) is, as a boolean image."""
    from matplotlib.image import imread

    rgb = imread(io.BytesIO(png), format="png")[..., :3]
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return (b > 0.35) & (b - r > 0.2) & (b > g + 0.05)


REQUIRE_BROWSER = "SOFTCURVE_REQUIRE_BROWSER"
"""Set to 1 (as .ci/run does) to fail, not skip, the browser test without a browser."""


@pytest.mark.skipif(
    find_browser() is None and not os.environ.get(REQUIRE_BROWSER),
    reason="no Chromium installed (apt install chromium)",
)
def test_viewer_in_headless_chromium(trajectory, tmp_path):
    assert find_browser() is not None, f"{REQUIRE_BROWSER} is set but no Chromium is installed"
    path = trajectory.to_html(tmp_path / "robot.html")
    tip = trajectory.tip
    later = int(np.argmax(np.linalg.norm(tip[frame_indices(trajectory.t, 25)] - tip[0], axis=1)))
    shots = []
    with Chromium(find_browser()) as browser:
        browser.open(path.as_uri() + "#frame=0")
        browser.wait_for('document.body.dataset.frame === "0"')
        for frame in (0, later):
            drawn = browser.evaluate(
                f"window.softcurveViewer.show({frame}).then(() => new Promise("
                "r => requestAnimationFrame(() => requestAnimationFrame(r))))"
                ".then(() => document.body.dataset.frame)"
            )
            assert drawn == str(frame)
            shots.append(browser.screenshot())
        label = browser.evaluate("document.getElementById('label').textContent")
        browser.evaluate("window.softcurveViewer.show(0)")
        browser.evaluate("document.getElementById('play').click()")  # plays at real time
        browser.wait_for("Number(document.body.dataset.frame) > 0")
        browser.evaluate("window.softcurveViewer.pause()")
        errors = list(browser.errors)
    assert not errors, f"console errors in the viewer: {errors}"
    assert label == f"t = {trajectory.t[frame_indices(trajectory.t, 25)[later]]:.3f} s"
    before, after = (_robot_pixels(png) for png in shots)
    assert before.sum() > 2000 and after.sum() > 2000, "the robot's tube is not drawn"
    changed = (before ^ after).sum() / (before | after).sum()
    assert changed > 0.1, f"the robot did not move between the frames ({changed:.1%} changed)"
    if os.environ.get(UPDATE_SCREENSHOTS) == "1":
        for name, png in zip(("viewer_t0.png", "viewer_t1.png"), shots, strict=True):
            (FIGURES / name).write_bytes(png)


def test_ten_seconds_stay_under_ten_megabytes(paper_model, tmp_path):
    t = np.arange(0.0, 10.0 + 5e-4, 1e-3)  # the paper case's output grid
    q = np.column_stack([0.064 + 0 * t, 25.0 * np.cos(8 * t), 25.0 * np.sin(8 * t)])
    trajectory = sc.Trajectory(t, q, np.zeros_like(q), np.empty((t.size, 0)), model=paper_model)
    size = trajectory.to_html(tmp_path / "ten.html").stat().st_size
    assert size < 10e6, f"{size / 1e6:.1f} MB"


@pytest.fixture(scope="module")
def gripper_scene():
    """A six-strain segment bent and twisted (2 rad), carrying a gripper whose tip is off
    its base's axis, at rest and deformed."""
    from tests.test_kinds import six_strain_gripper_robot, twisted

    robot = six_strain_gripper_robot()
    model = sc.Model(robot, compile=False)
    q = np.array([robot.rest_configuration(), twisted(robot, twist=20.0, bend=6.0)])
    return model, q, build_scene(model, q, ["rest", "twisted"], rings=9)


def test_a_rigid_body_is_a_cylinder_from_its_base_to_its_tip(gripper_scene):
    model, q, scene = gripper_scene
    assert scene.kinds == ("soft", "rigid") and scene.stripes
    rigid = scene.rings[:, 9:]
    for f in range(2):
        base, tip = model.pose(q[f], 0.5).position, model.pose(q[f], 1.0).position
        axis = (tip - base) / np.linalg.norm(tip - base)
        np.testing.assert_allclose(rigid[f, [0, -1], :3], 1e3 * np.array([base, tip]), atol=1e-9)
        np.testing.assert_allclose(rigid[f, :, 3:6] @ axis, 0.0, atol=1e-12)  # across it
        np.testing.assert_allclose(rigid[f, :, 6:9] @ axis, 0.0, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(rigid[f, :, 3:6], axis=1), 1.0, rtol=1e-12)
    soft = ring_frames(model, q, 9)[:, :9]
    np.testing.assert_allclose(scene.rings[:, :9], soft, atol=0)  # the soft segment's own
    payload = scene.payload()
    assert payload["kinds"] == ["soft", "rigid"] and payload["stripes"] is True
    paper = sc.Model(sc.presets.ifac2020(), compile=False)
    assert not build_scene(paper, [[0.064, 5.0, 0.0]], ["a"]).stripes


@pytest.mark.skipif(
    find_browser() is None and not os.environ.get(REQUIRE_BROWSER),
    reason="no Chromium installed (apt install chromium)",
)
def test_the_viewer_draws_the_rigid_body_and_the_twist_in_chromium(gripper_scene, tmp_path):
    """The page in a browser: the gripper a grey trace, and a stripe on the twisted
    segment's surface along its material x axis (which turns with the twist:
    tests/test_figures.py measures the turn)."""
    import json

    from matplotlib.image import imread

    from softcurve.figures.viewer import write_page

    model, q, scene = gripper_scene
    path = write_page(scene, tmp_path / "gripper.html")
    with Chromium(find_browser()) as browser:
        browser.open(path.as_uri() + "#frame=1")
        browser.wait_for('document.body.dataset.frame === "1"')
        traces = json.loads(browser.evaluate(
            "JSON.stringify(document.getElementById('plot').data.map(t => ({name: t.name, "
            "color: t.color || (t.line && t.line.color), x: t.x, y: t.y, z: t.z})))"
        ))  # fmt: skip
        png = browser.screenshot()
        rigid = [t["name"] for t in traces].index("rigid body 2")
        browser.evaluate(
            f"Plotly.restyle('plot', {{visible: false}}, [{rigid}]).then(() => new Promise("
            "r => requestAnimationFrame(() => requestAnimationFrame(r))))"
        )
        hidden = browser.screenshot()  # the same view without the gripper
        errors = list(browser.errors)
    assert not errors, f"console errors in the viewer: {errors}"
    named = {t["name"]: t for t in traces}
    assert named["segment 1"]["color"] == "#1f77b4" and named["rigid body 2"]["color"] == "#555555"
    stripe = np.array([named["stripe (twist)"][k] for k in "xyz"]).T
    rings = scene.rings[1, :9]
    radius = 1e3 * model.robot.segments[0].radius
    expected = rings[:, :3] + 1.02 * radius * rings[:, 3:6]
    np.testing.assert_allclose(stripe, expected, atol=1e-3)  # mm, float32 in the page

    def grey(image):  # shaded #555555: channels alike, darker than the page
        rgb = imread(io.BytesIO(image), format="png")[..., :3]
        return (
            (np.ptp(rgb, axis=-1) < 0.04) & (rgb.mean(axis=-1) > 0.15) & (rgb.mean(axis=-1) < 0.6)
        )

    gripper = (grey(png) & ~grey(hidden)).sum()
    assert gripper > 200, f"the rigid body is not drawn ({gripper} grey pixels)"
    assert _robot_pixels(png).sum() > 1000, "the soft segment is not drawn"
