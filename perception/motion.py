"""From successive tracked poses to the teacher's motor directive, and agreement with the truth.

Over an interval ``dt`` a robot moves from pose ``(x0, y0, yaw0)`` to ``(x1, y1, yaw1)``. Its speed
along its heading (the mean of the two yaws) is ``v = ((x1 - x0) cos(yaw_mid) + (y1 - y0)
sin(yaw_mid)) / dt`` and its turn rate ``w = wrap(yaw1 - yaw0) / dt``. Each is compared with its
nominal value (the simulator's forward speed and turn rate): the larger of ``|v| /
forward_speed_mps`` and ``|w| / turn_rate_radps`` decides between a translation (``forward`` if v >
0, else ``backward``) and a turn (``turn_left`` if w > 0, counter-clockwise, else ``turn_right``).
If both are below ``min_fraction`` of nominal the robot is standing still and the directive is None.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from associator.encoding import DIRECTIVES
from perception.drive import DriveSpeeds
from perception.pose import check_planar_pose, wrap_radians

#: Label used for "no directive inferred" in confusion matrices.
NO_DIRECTIVE = "none"


@dataclasses.dataclass(frozen=True)
class DirectiveConfig:
    """Thresholds for directive inference.

    Attributes:
      forward_speed_mps: nominal forward/backward speed, metres per second (default: the drive's).
      turn_rate_deg_s: nominal turn rate, degrees per second (default: the drive's).
      min_fraction: below this fraction of both nominal rates the robot counts as still (None).
      window: number of control periods spanned by each comparison (1 = consecutive poses); larger
        windows average out pose noise but lag directive changes.
    """

    forward_speed_mps: float = DriveSpeeds().linear_mps
    turn_rate_deg_s: float = DriveSpeeds().turn_deg_s
    min_fraction: float = 0.3
    window: int = 1

    def __post_init__(self):
        for name in ("forward_speed_mps", "turn_rate_deg_s", "min_fraction"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        if not isinstance(self.window, int) or self.window < 1:
            raise ValueError(f"window must be an integer >= 1, got {self.window!r}")


def body_rates(pose_before, pose_after, dt_s: float) -> tuple[float, float]:
    """Returns ``(v_mps, w_radps)``: speed along the mean heading and turn rate between two poses.

    Poses are ``(x_m, y_m, yaw_rad)`` in the world frame, finite (ValueError naming the pose
    otherwise; ``infer_directives`` is the one that takes lost, NaN poses); ``dt_s`` > 0 seconds.
    """
    if not np.isfinite(dt_s) or dt_s <= 0:
        raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s!r}")
    x0, y0, yaw0 = check_planar_pose(pose_before, "pose_before")
    x1, y1, yaw1 = check_planar_pose(pose_after, "pose_after")
    dyaw = float(wrap_radians(yaw1 - yaw0))
    mid = yaw0 + 0.5 * dyaw
    v = ((x1 - x0) * np.cos(mid) + (y1 - y0) * np.sin(mid)) / dt_s
    return float(v), dyaw / dt_s


def infer_directive(
    pose_before, pose_after, dt_s: float, config: DirectiveConfig = DirectiveConfig()
) -> str | None:
    """Returns the directive (one of ``DIRECTIVES``) that best explains the motion, or None if
    still."""
    v, w = body_rates(pose_before, pose_after, dt_s)
    translation = abs(v) / config.forward_speed_mps
    rotation = abs(w) / np.radians(config.turn_rate_deg_s)
    if max(translation, rotation) < config.min_fraction:
        return None
    if rotation > translation:
        return "turn_left" if w > 0 else "turn_right"
    return "forward" if v > 0 else "backward"


def infer_directives(
    times_s, poses, config: DirectiveConfig = DirectiveConfig()
) -> list[str | None]:
    """Returns one directive per pose: the motion from ``window`` poses earlier to this one.

    Args:
      times_s: shape (N,), increasing seconds.
      poses: shape (N, 3), ``(x_m, y_m, yaw_rad)``; a row of NaN (robot lost) gives None around it.

    The first ``window`` entries are None (no earlier pose).
    """
    times_s = np.asarray(times_s, dtype=float)
    poses = np.asarray(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3 or len(times_s) != len(poses):
        raise ValueError(
            f"poses must have shape (N, 3) with N = len(times_s) = {len(times_s)}, "
            f"got {poses.shape}"
        )
    out: list[str | None] = []
    k = config.window
    for i in range(len(poses)):
        if i < k or not (np.all(np.isfinite(poses[i])) and np.all(np.isfinite(poses[i - k]))):
            out.append(None)
            continue
        out.append(infer_directive(poses[i - k], poses[i], times_s[i] - times_s[i - k], config))
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class DirectiveAgreement:
    """Agreement of inferred directives with the true ones.

    Attributes:
      fraction: fraction of steps with a true directive where the inferred one equals it.
      n_steps: number of steps with a true directive.
      labels: row and column labels, ``DIRECTIVES`` then ``NO_DIRECTIVE``.
      confusion: counts, shape (5, 5); rows true, columns inferred.
    """

    fraction: float
    n_steps: int
    labels: tuple[str, ...]
    confusion: np.ndarray

    def as_dict(self) -> dict:
        """Returns a JSON-ready dict."""
        return {
            "fraction": self.fraction,
            "n_steps": self.n_steps,
            "labels": list(self.labels),
            "confusion": self.confusion.tolist(),
        }


def directive_agreement(inferred, true) -> DirectiveAgreement:
    """Returns how often ``inferred`` matches ``true`` (sequences of directives or None, same
    length).

    Steps whose true directive is None are left out of ``fraction`` but counted in the confusion
    matrix.
    """
    inferred, true = list(inferred), list(true)
    if len(inferred) != len(true):
        raise ValueError(
            f"inferred and true must have the same length, got {len(inferred)} and {len(true)}"
        )
    labels = (*DIRECTIVES, NO_DIRECTIVE)
    index = {label: i for i, label in enumerate(labels)}
    confusion = np.zeros((len(labels), len(labels)), dtype=int)
    for a, b in zip(true, inferred, strict=True):
        for value in (a, b):
            if value is not None and value not in index:
                raise ValueError(
                    f"unknown directive {value!r}; allowed: {', '.join(DIRECTIVES)} or None"
                )
        confusion[index[a or NO_DIRECTIVE], index[b or NO_DIRECTIVE]] += 1
    with_truth = confusion[: len(DIRECTIVES)]
    n = int(with_truth.sum())
    correct = int(np.trace(with_truth[:, : len(DIRECTIVES)]))
    return DirectiveAgreement(correct / n if n else float("nan"), n, labels, confusion)


def infer_directives_batch(
    poses, dt_s: float, config: DirectiveConfig = DirectiveConfig()
) -> np.ndarray:
    """Vectorised :func:`infer_directive` over consecutive poses (N, 3).

    Returns an array of N - 1 names: entry ``i`` explains the motion from pose ``i`` to ``i + 1``;
    ``NO_DIRECTIVE`` where the robot stood still or a pose is not finite.
    """
    poses = np.asarray(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3), got {poses.shape}")
    if not np.isfinite(dt_s) or dt_s <= 0:
        raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s!r}")
    before, after = poses[:-1], poses[1:]
    dyaw = wrap_radians(after[:, 2] - before[:, 2])
    mid = before[:, 2] + 0.5 * dyaw
    v = (after[:, 0] - before[:, 0]) * np.cos(mid) + (after[:, 1] - before[:, 1]) * np.sin(mid)
    v = v / dt_s
    w = dyaw / dt_s
    translation = np.abs(v) / config.forward_speed_mps
    rotation = np.abs(w) / np.radians(config.turn_rate_deg_s)
    names = np.where(
        rotation > translation,
        np.where(w > 0, "turn_left", "turn_right"),
        np.where(v > 0, "forward", "backward"),
    ).astype(object)
    still = (np.maximum(translation, rotation) < config.min_fraction) | ~np.isfinite(v + w)
    names[still] = NO_DIRECTIVE
    return names.astype(str)
