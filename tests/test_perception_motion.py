"""Motor directive inference from tracked poses."""

import numpy as np
import pytest

from perception.motion import (
    DIRECTIVES,
    DirectiveConfig,
    directive_agreement,
    infer_directive,
    infer_directives,
)

STEP = {
    "forward": (0.35, 0.0),
    "backward": (-0.35, 0.0),
    "turn_left": (0.0, 60.0),
    "turn_right": (0.0, -60.0),
}


def simulate(directives, dt=0.1, noise_m=0.0, noise_deg=0.0, rng=None, yaw0=2.5):
    """Returns times and noisy poses of a unicycle following ``directives``, one per period."""
    rng = np.random.default_rng(rng)
    x, y, yaw = 0.0, 0.0, yaw0
    poses = [(x, y, yaw)]
    for d in directives:
        v, w = STEP[d]
        x += v * dt * np.cos(yaw + np.radians(w) * dt / 2)
        y += v * dt * np.sin(yaw + np.radians(w) * dt / 2)
        yaw = float(np.angle(np.exp(1j * (yaw + np.radians(w) * dt))))
        poses.append((x, y, yaw))
    poses = np.asarray(poses)
    poses[:, :2] += rng.normal(0, noise_m, (len(poses), 2)) if noise_m else 0.0
    poses[:, 2] += rng.normal(0, np.radians(noise_deg), len(poses)) if noise_deg else 0.0
    return dt * np.arange(len(poses)), poses


def test_single_steps_are_named_exactly():
    for name, _ in STEP.items():
        _, poses = simulate([name])
        assert infer_directive(poses[0], poses[1], 0.1) == name
    assert infer_directive((0, 0, 0), (0.001, 0, 0.001), 0.1) is None
    assert set(DIRECTIVES) == {"forward", "backward", "turn_left", "turn_right"}


def test_noisy_trajectory_agreement_and_confusion():
    rng = np.random.default_rng(4)
    true = list(rng.choice(DIRECTIVES, size=300))
    times, poses = simulate(true, noise_m=0.004, noise_deg=0.4, rng=rng)
    inferred = infer_directives(times, poses)[1:]
    agreement = directive_agreement(inferred, true)
    assert agreement.fraction > 0.95
    assert agreement.n_steps == 300 and agreement.confusion.sum() == 300
    assert agreement.confusion.shape == (5, 5) and agreement.labels[-1] == "none"
    assert agreement.as_dict()["fraction"] == agreement.fraction


def test_window_and_nan_handling():
    times, poses = simulate(["forward"] * 5)
    poses[3] = np.nan
    out = infer_directives(times, poses, DirectiveConfig(window=2))
    assert out[:2] == [None, None] and out[2] == "forward" and out[3] is None and out[5] is None


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="same length"):
        directive_agreement(["forward"], [])
    with pytest.raises(ValueError, match="unknown directive"):
        directive_agreement(["jump"], ["forward"])
    with pytest.raises(ValueError, match="dt_s"):
        infer_directive((0, 0, 0), (1, 0, 0), 0.0)
    with pytest.raises(ValueError, match="forward_speed_mps"):
        DirectiveConfig(forward_speed_mps=-1.0)
