"""A synthetic teacher stream with known structure, for tests, benchmarks and sanity checks.

A point robot in a square arena loops through the paper's behaviours with simple kinematics (no
physics, no vision): 'go' wanders, turning away from walls; when it comes near the target at the
middle of the top wall facing it (-45 < phi < 45 deg) it switches to 'pick', docks in front of the
target (turning towards it, driving, then alternating turns to align), and 'lift' backs away from
the table and turns to face the arena before the next 'go'. Poses are reported in the wall frame of
``perception.wallframe`` (x, y in metres from / along the nearest wall, phi in degrees, 0 facing
it).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from associator import encoding

_FORWARD, _BACKWARD, _RIGHT, _LEFT = range(4)
_GO, _PICK, _LIFT = range(3)


class Stream(NamedTuple):
    """A teacher stream of ``n`` steps: wall-frame ``x``, ``y`` (m), ``phi`` (deg), shape (n,) each;
    ``directive`` (n,) indices into ``DIRECTIVES``; ``word`` (n,) indices into ``WORDS``;
    ``motor_changed`` (n,) bool; ``arena_side_m`` the inner side of the square arena, metres."""

    x: np.ndarray
    y: np.ndarray
    phi: np.ndarray
    directive: np.ndarray
    word: np.ndarray
    motor_changed: np.ndarray
    arena_side_m: float


def _wall_frame(px: float, py: float, yaw_deg: float, half: float):
    """Returns (x, y, phi) of a world pose relative to its nearest wall."""
    if abs(py) >= abs(px):
        if py >= 0:  # top wall, facing +y
            return half - py, px, yaw_deg - 90.0
        return half + py, -px, yaw_deg + 90.0  # bottom
    if px >= 0:  # right wall, facing +x
        return half - px, -py, yaw_deg
    return half + px, py, yaw_deg - 180.0  # left


def _wrap(angle_deg: float) -> float:
    return (angle_deg + 180.0) % 360.0 - 180.0


def teacher_stream(
    n_steps: int, rng=None, arena_side_m: float = 4.0, step_m: float = 0.03, turn_deg: float = 6.0
) -> Stream:
    """Returns ``n_steps`` of the teacher looping through go, pick and lift.

    Args:
      n_steps: number of samples.
      rng: seed, generator or None.
      arena_side_m: inner side of the square arena in metres.
      step_m: distance driven per forward or backward step, metres.
      turn_deg: rotation per turning step, degrees.
    """
    rng = np.random.default_rng(rng)
    half = 0.5 * arena_side_m
    out = np.empty((n_steps, 5))
    px, py, yaw = 0.0, 0.0, float(rng.uniform(-180, 180))
    behaviour, turning, lift_back = _GO, 0, 0
    away_deg = 120.0
    for t in range(n_steps):
        x, y, phi = _wall_frame(px, py, yaw, half)
        phi = _wrap(phi)
        if behaviour == _GO:
            if py > 0 and abs(py) >= abs(px) and x < 1.6 and abs(y) < 0.8 and abs(phi) < 45:
                behaviour = _PICK
            elif turning:
                if abs(phi) >= away_deg or x > 0.6:
                    turning = 0
            elif x < 0.35 and abs(phi) < 90:
                turning = _LEFT if phi > 0 else _RIGHT
                away_deg = float(rng.uniform(100, 170))
        if behaviour == _PICK:
            # Dock at the table: 0.25 m in front of the middle of the top wall, facing it.
            dx, dy = -px, (half - 0.25) - py
            if math.hypot(dx, dy) > 0.06:
                error = _wrap(math.degrees(math.atan2(dy, dx)) - yaw)
                directive = _FORWARD if abs(error) < 12 else (_LEFT if error > 0 else _RIGHT)
            else:
                error = _wrap(90.0 - yaw)
                if abs(error) < 3.5:
                    behaviour, lift_back = _LIFT, int(rng.integers(20, 35))
                    directive = _BACKWARD
                else:
                    # Settling on the heading overshoots, so left and right turns alternate.
                    directive = _LEFT if error > 0 else _RIGHT
        if behaviour == _LIFT:
            if lift_back > 0:
                lift_back -= 1
                directive = _BACKWARD
            elif abs(phi) < 160:
                directive = _LEFT
            else:
                behaviour, turning = _GO, 0
        if behaviour == _GO:
            directive = turning if turning else _FORWARD
            if not turning and rng.random() < 0.02:
                yaw += float(rng.normal(0, 20))  # A wander, so go visits the whole arena.
        out[t] = (x, y, phi, directive, behaviour)
        if directive == _FORWARD:
            px += step_m * math.cos(math.radians(yaw))
            py += step_m * math.sin(math.radians(yaw))
        elif directive == _BACKWARD:
            px -= step_m * math.cos(math.radians(yaw))
            py -= step_m * math.sin(math.radians(yaw))
        elif directive == _LEFT:
            yaw += turn_deg
        else:
            yaw -= turn_deg
        yaw = _wrap(yaw)
        limit = half - 0.05
        px, py = min(max(px, -limit), limit), min(max(py, -limit), limit)
    directive = out[:, 3].astype(np.int64)
    changed = np.zeros(n_steps, dtype=bool)
    changed[1:] = directive[1:] != directive[:-1]
    return Stream(
        x=np.clip(out[:, 0], 0.0, half),
        y=np.clip(out[:, 1], -half, half),
        phi=out[:, 2],
        directive=directive,
        word=out[:, 4].astype(np.int64),
        motor_changed=changed,
        arena_side_m=float(arena_side_m),
    )


def encode_stream(stream: Stream, vision_encoder: encoding.VisionEncoder | None = None):
    """Returns ``(vision (n, 96), language (n, 80), motor (n, 4), motor_changed (n,))``; the vision
    encoder defaults to one for the stream's arena."""
    if vision_encoder is None:
        vision_encoder = encoding.VisionEncoder.from_arena_side(stream.arena_side_m)
    vision = vision_encoder.encode_batch(stream.x, stream.y, stream.phi)
    word_codes = np.stack([encoding.encode_word(w) for w in encoding.WORDS])
    language = word_codes[stream.word]
    motor = encoding.encode_motor_batch(stream.directive)
    return vision, language, motor, stream.motor_changed.copy()
