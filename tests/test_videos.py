"""What people watch, in parts: the overlays (``imitation.overlay``), the follow camera
(``peoplebot_sim.viewpoints``), Fig. 4's drawings on constructed traces (``imitation.tracefigures``)
and the demo's help. The videos themselves are tested on the tiny run in
``test_experiment_pipeline.py``."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import math

import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest

from imitation import overlay, tracefigures, trials
from imitation.cli import build_parser
from imitation.performance import SuccessConfig
from peoplebot_sim.cameras import free_camera_model
from peoplebot_sim.task import load
from peoplebot_sim.viewpoints import FollowCamera
from perception.camera import PinholeCamera, look_at_rotation


@pytest.mark.parametrize("size", [(480, 640), (240, 320)])
def test_overlays_draw_at_every_size(size):
    frame = np.full((*size, 3), 128, np.uint8)
    out = overlay.annotate(
        frame,
        "pick",
        "turn_left",
        "t = 3.0 s",
        np.array([0.1, 0, 0.5, 0.9]),
        title="student",
        note="body movement only",
    )
    assert out.shape == frame.shape and np.any(out != frame)
    assert np.array_equal(frame, np.full((*size, 3), 128, np.uint8))  # the input is kept
    ended = overlay.verdict(out, False, "never inside the docking tolerance " * 3)
    assert ended.shape == frame.shape and np.any(ended != out)
    small = np.zeros((size[0] // 3, size[1] // 3, 3), np.uint8)
    assert overlay.inset(frame, small, "table close-up").shape == frame.shape
    with pytest.raises(ValueError, match="does not fit"):
        overlay.inset(frame, np.zeros((size[0], size[1], 3), np.uint8))


def test_the_follow_camera_looks_ahead_of_the_robot_and_turns_smoothly():
    camera = FollowCamera(smoothing_s=1.0)
    first = camera.update((0.5, -0.2, 0.0), 0.1)
    assert first.lookat[0] == pytest.approx(0.5 + camera.ahead_m)
    assert first.azimuth == pytest.approx(camera.side_deg)
    after = [camera.update((0.5, -0.2, math.pi / 2), 0.1).azimuth for _ in range(60)]
    assert np.all(np.diff(after) > 0)  # turns towards the new heading, step by step
    assert after[0] < 90 + camera.side_deg - 60 and after[-1] == pytest.approx(120, abs=0.5)


def _traces(n=30, k=2):
    t = np.linspace(0, 1, n)
    path = np.column_stack([0.3 * t, 0.6 + t, np.full(n, math.pi / 2)])
    out = {}
    for policy in ("teacher", "student", "student_hierarchical"):
        for word in ("go", "pick", "lift"):
            out[f"fig4_{policy}_{word}"] = path
            out[f"fig4_{policy}_{word}_success"] = np.asarray(policy == "teacher")
            paths = np.stack([path] * k)
            paths[0, n // 2 :] = np.nan
            out[f"random_{policy}_{word}"] = paths
            out[f"random_{policy}_{word}_success"] = np.array([True, False])
    return out


def test_fig4_drawings_on_constructed_traces(tmp_path):
    policies = ("teacher", "student", "student_hierarchical")
    dock = (0.0, 1.2, math.pi / 2)
    success = SuccessConfig()
    tolerance = (success.dock_position_tol_m, success.dock_heading_tol_deg)
    start = (0, 0.6, math.pi / 2)
    for draw, name in (
        (lambda p: tracefigures.fig4_all(_traces(), p, start, policies, dock, tolerance), "a"),
        (lambda p: tracefigures.fig4_random_starts(_traces(), p, policies, dock, tolerance), "b"),
    ):
        image = imageio.imread(draw(tmp_path / f"{name}.png"))
        assert image.shape[0] > 900 and image.shape[1] > 900 and image.std() > 5


def test_every_demo_flag_has_help_and_its_default_shown():
    text = " ".join(
        build_parser()._subparsers._group_actions[0].choices["demo"].format_help().split()
    )
    for flag in (
        "--seconds",
        "--width",
        "--height",
        "--seed",
        "--camera",
        "--speedup",
        "--out",
        "--no-video",
        "--no-shadows",
        "--mcap",
        "--quiet",
    ):
        after = text.split(f" {flag}", 2)[-1]
        assert "(default:" in after.split(" --")[0], flag
    assert "follow" in text


def _magenta(image: np.ndarray, pixel, radius: int = 2) -> bool:
    """Returns True when a pixel within ``radius`` of ``pixel`` (u, v) has the estimate's colour."""
    u, v = (int(round(c)) for c in pixel)
    patch = image[max(v - radius, 0) : v + radius + 1, max(u - radius, 0) : u + radius + 1]
    target = np.array(overlay.ESTIMATE_COLOUR)
    return bool(np.any(np.all(np.abs(patch.astype(int) - target) <= 40, axis=-1)))


def test_own_pose_estimate_draws_the_95_percent_ellipse_around_the_projected_estimate():
    """On a grey frame seen from straight above: the dot at the estimate's projection, the 95%
    ellipse through the ends of its axes (sqrt(5.991) sigma along each), nothing at twice that;
    without a covariance no ellipse; the heading wedge covers +-1.96 sigma of the heading."""
    position = np.array([0.0, 0.0, 4.0])
    camera = PinholeCamera.from_fovy(
        320, 240, 45.0, look_at_rotation(position, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)), position
    )
    frame = np.full((240, 320, 3), 128, np.uint8)
    pose = (0.3, -0.2, 0.0)
    covariance = np.diag([0.2**2, 0.1**2, math.radians(20.0) ** 2])
    out = overlay.own_pose_estimate(frame, camera, pose, covariance, floor_z_m=0.0)
    assert np.array_equal(frame, np.full((240, 320, 3), 128, np.uint8))  # the input is kept

    def px(x, y):
        return camera.project([(x, y, 0.0)])[0]

    k = math.sqrt(5.991)
    assert _magenta(out, px(0.3, -0.2))
    ends = [(0.3 + k * 0.2, -0.2), (0.3 - k * 0.2, -0.2), (0.3, -0.2 + k * 0.1)]
    ends.append((0.3, -0.2 - k * 0.1))
    assert all(_magenta(out, px(*end)) for end in ends)
    assert not _magenta(out, px(0.3, -0.2 - 2 * k * 0.1))
    # The wedge: tinted inside +-1.96 sigma (39 deg) of the heading, not at 60 deg.
    inside, outside = math.radians(30.0), math.radians(60.0)
    tint = out[
        tuple(
            np.round(px(0.3 + 0.4 * math.cos(inside), -0.2 + 0.4 * math.sin(inside)))[::-1].astype(
                int
            )
        )
    ]
    plain = out[
        tuple(
            np.round(px(0.3 + 0.4 * math.cos(outside), -0.2 + 0.4 * math.sin(outside)))[
                ::-1
            ].astype(int)
        )
    ]
    assert tint[1] < 110 and tint[0] > 140 and np.array_equal(plain, [128, 128, 128])
    bare = overlay.own_pose_estimate(frame, camera, pose, None, floor_z_m=0.0)
    assert _magenta(bare, px(0.3, -0.2)) and not any(_magenta(bare, px(*e)) for e in ends[2:])
    assert np.array_equal(overlay.own_pose_estimate(frame, camera, None), frame)
    with pytest.raises(ValueError, match="must agree"):
        overlay.own_pose_estimate(frame[:100], camera, pose, covariance)
    with pytest.raises(ValueError, match="3x3"):
        overlay.own_pose_estimate(frame, camera, pose, np.eye(2))


def test_free_camera_model_is_where_mujoco_renders_from():
    """The follow camera's pinhole model has the position and viewing direction MuJoCo's renderer
    computes for it (``mjv_updateScene``'s two eyes, averaged as a mono render does)."""
    env = load(seed=0)
    physics = env.physics
    view = FollowCamera().update((0.4, -0.3, 0.7), 0.1)
    model = free_camera_model(physics, view, 64, 48)
    renderer = mujoco.Renderer(physics.model.ptr, 48, 64)
    try:
        renderer.update_scene(physics.data.ptr, view)
        gl = mujoco.mjv_averageCamera(renderer.scene.camera[0], renderer.scene.camera[1])
        np.testing.assert_allclose(model.position_world, gl.pos, atol=1e-4)
        np.testing.assert_allclose(model.rotation_world_from_camera[:, 2], gl.forward, atol=1e-4)
        np.testing.assert_allclose(-model.rotation_world_from_camera[:, 1], gl.up, atol=1e-4)
    finally:
        renderer.close()
        env.close()
    with pytest.raises(ValueError, match="free"):
        free_camera_model(physics, "overhead", 64, 48)


def test_ellipse_semi_major_axes_skip_steps_without_a_covariance():
    covariances = np.stack([np.diag([0.04, 0.01, 0.1]), np.full((3, 3), np.nan)])
    np.testing.assert_allclose(trials.ellipse95_semi_major_m(covariances), [0.2 * math.sqrt(5.991)])
    assert trials.ellipse95_semi_major_m(None).size == 0
