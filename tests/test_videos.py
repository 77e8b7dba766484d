"""What people watch, in parts: the overlays (``imitation.overlay``), the follow camera
(``peoplebot_sim.viewpoints``), Fig. 4's drawings on constructed traces (``imitation.tracefigures``)
and the demo's help. The videos themselves are tested on the tiny run in
``test_experiment_pipeline.py``."""

import math

import imageio.v2 as imageio
import numpy as np
import pytest

from imitation import overlay, tracefigures
from imitation.cli import build_parser
from imitation.performance import SuccessConfig
from peoplebot_sim.viewpoints import FollowCamera


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
