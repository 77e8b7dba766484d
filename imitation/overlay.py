"""Text and pictures drawn on video frames (RGB): the word, the directive, a title and caption, the
graded motor output, a note line, an inset picture, the verdict at a trial's end and the student's
own-pose estimate with its uncertainty on the floor. Sizes scale with the frame's width and are
legible from 640x480 down to 320x240."""

from __future__ import annotations

import cv2
import numpy as np

from associator.encoding import DIRECTIVES
from perception.camera import PinholeCamera
from perception.localisation import CHI2_2DOF_95

_WORD_COLOURS = {"go": (60, 170, 75), "pick": (230, 140, 30), "lift": (70, 110, 230)}
_FONT = cv2.FONT_HERSHEY_SIMPLEX
#: The motor bars' labels, in the associator's directive order.
_MOTOR_LABELS = {"forward": "fwd", "backward": "back", "turn_right": "right", "turn_left": "left"}
#: The own-pose estimate's colour (RGB): magenta, unlike anything in the arena.
ESTIMATE_COLOUR = (255, 0, 255)
#: The two-sided normal quantile for 95% (the heading wedge).
_NORMAL_95 = 1.960
#: The heading wedge's radius on the floor, metres (about the PeopleBot's length).
_WEDGE_M = 0.5


def _scale(frame: np.ndarray) -> float:
    return max(frame.shape[1] / 640.0, 0.5)


def _text(out, text, origin, size, colour, thick=1) -> None:
    cv2.putText(out, text, origin, _FONT, size, colour, thick, cv2.LINE_AA)


def _shade(out, x0, y0, x1, y1, alpha=0.65) -> None:
    """Darkens a rectangle of ``out`` in place (a translucent panel behind text)."""
    h, w = out.shape[:2]
    x0, x1, y0, y1 = max(0, x0), min(w, x1), max(0, y0), min(h, y1)
    if x1 > x0 and y1 > y0:
        out[y0:y1, x0:x1] = (out[y0:y1, x0:x1] * (1 - alpha) + 15 * alpha).astype(np.uint8)


def annotate(
    frame: np.ndarray,
    word: str | None,
    directive: str | None,
    caption: str = "",
    motor: np.ndarray | None = None,
    *,
    title: str = "",
    note: str = "",
) -> np.ndarray:
    """Returns a copy of an RGB frame with a top bar (``title`` and ``caption`` on the first line,
    the word and the directive on the second), ``motor`` (4 graded activations, the associator's
    directive order) as labelled bars at the bottom left, and ``note`` as a line at the bottom."""
    out = np.ascontiguousarray(frame).copy()
    h, w = out.shape[:2]
    s = _scale(out)
    thick = max(1, int(round(2 * s)))
    two_rows = bool(title)
    bar_h = int((62 if two_rows else 40) * s) + 4
    cv2.rectangle(out, (0, 0), (w, bar_h), (20, 20, 20), -1)
    x, row2 = int(10 * s), int((54 if two_rows else 30) * s)
    if title:
        _text(out, title, (x, int(22 * s)), 0.62 * s, (255, 255, 255), thick if s >= 1 else 1)
    if caption:
        size = cv2.getTextSize(caption, _FONT, 0.58 * s, 1)[0]
        y = int(22 * s) if two_rows else int(28 * s)
        _text(out, caption, (w - size[0] - int(10 * s), y), 0.58 * s, (215, 215, 215))
    if word is not None:
        label = f"'{word}'"
        _text(out, label, (x, row2), 0.85 * s, _WORD_COLOURS.get(word, (255, 255, 255)), thick + 1)
        x += cv2.getTextSize(label, _FONT, 0.85 * s, thick + 1)[0][0] + int(18 * s)
    if directive is not None:
        _text(out, directive.replace("_", " "), (x, row2), 0.75 * s, (240, 240, 240), thick)
    right = 0
    if motor is not None:
        right = _motor_bars(out, motor, s)
    if note:
        size = cv2.getTextSize(note, _FONT, 0.5 * s, 1)[0]
        x0 = right + int(8 * s)
        y1 = h - int(6 * s)
        _shade(out, x0 - int(4 * s), y1 - size[1] - int(8 * s), x0 + size[0] + int(6 * s), h)
        _text(out, note, (x0, y1 - int(3 * s)), 0.5 * s, (255, 235, 160))
    return out


def _motor_bars(out: np.ndarray, motor, s: float) -> int:
    """Draws the graded motor activations as bars with their directives' names; returns the
    panel's right edge (pixels)."""
    h = out.shape[0]
    motor = np.clip(np.asarray(motor, dtype=float), 0, None)
    top = motor.max() if motor.max() > 0 else 1.0
    bar_w, bar_h, gap = int(30 * s), int(48 * s), int(10 * s)
    label_h = int(16 * s)
    x0, y0 = int(10 * s), h - label_h - int(8 * s)
    right = x0 + len(motor) * (bar_w + gap)
    _shade(out, 0, y0 - bar_h - int(24 * s), right + int(2 * s), h)
    _text(out, "motor output", (x0, y0 - bar_h - int(8 * s)), 0.45 * s, (230, 230, 230))
    for i, (value, name) in enumerate(zip(motor, DIRECTIVES, strict=True)):
        left = x0 + i * (bar_w + gap)
        cv2.rectangle(out, (left, y0 - bar_h), (left + bar_w, y0), (90, 90, 90), 1)
        cv2.rectangle(
            out, (left, y0 - int(bar_h * value / top)), (left + bar_w, y0), (240, 200, 40), -1
        )
        _text(out, _MOTOR_LABELS[name], (left, y0 + label_h - 2), 0.42 * s, (240, 240, 240))
    return right


def inset(frame: np.ndarray, picture: np.ndarray, caption: str = "") -> np.ndarray:
    """Returns a copy of ``frame`` with ``picture`` (RGB, smaller) at its top right below the top
    bar, framed in white, with ``caption`` under it."""
    out = np.ascontiguousarray(frame).copy()
    h, w = out.shape[:2]
    s = _scale(out)
    ph, pw = picture.shape[:2]
    x1, y0 = w - int(8 * s), int(70 * s)
    x0, y1 = x1 - pw, y0 + ph
    if x0 < 0 or y1 > h:
        raise ValueError(f"an inset of {pw}x{ph} does not fit a {w}x{h} frame")
    out[y0:y1, x0:x1] = picture
    cv2.rectangle(out, (x0 - 2, y0 - 2), (x1 + 1, y1 + 1), (255, 255, 255), 2)
    if caption:
        _shade(out, x0 - 2, y1 + 2, x1 + 2, y1 + int(20 * s))
        _text(out, caption, (x0 + 4, y1 + int(15 * s)), 0.45 * s, (255, 255, 255))
    return out


def verdict(frame: np.ndarray, success: bool, reason: str) -> np.ndarray:
    """Returns a copy of ``frame`` with the trial's verdict in a banner across its middle: SUCCESS
    (green) or FAILURE (red) and the reason, wrapped to the frame's width."""
    out = np.ascontiguousarray(frame).copy()
    h, w = out.shape[:2]
    s = _scale(out)
    lines = _wrap(reason, 0.55 * s, w - int(40 * s))
    line_h = int(24 * s)
    top = h // 2 - int(40 * s)
    bottom = top + int(52 * s) + line_h * len(lines)
    _shade(out, 0, top, w, bottom, alpha=0.75)
    colour = (90, 220, 100) if success else (240, 80, 70)
    word = "SUCCESS" if success else "FAILURE"
    size = cv2.getTextSize(word, _FONT, 1.2 * s, max(2, int(3 * s)))[0]
    _text(out, word, ((w - size[0]) // 2, top + int(40 * s)), 1.2 * s, colour, max(2, int(3 * s)))
    for i, line in enumerate(lines):
        size = cv2.getTextSize(line, _FONT, 0.55 * s, 1)[0]
        y = top + int(40 * s) + line_h * (i + 1)
        _text(out, line, ((w - size[0]) // 2, y), 0.55 * s, (240, 240, 240))
    return out


def _wrap(text: str, size: float, width: int) -> list[str]:
    """Returns ``text`` broken into lines at most ``width`` pixels wide."""
    lines, line = [], ""
    for word in text.split():
        candidate = f"{line} {word}".strip()
        if line and cv2.getTextSize(candidate, _FONT, size, 1)[0][0] > width:
            lines.append(line)
            line = word
        else:
            line = candidate
    return [*lines, line] if line else lines


def own_pose_estimate(
    frame: np.ndarray,
    camera: PinholeCamera,
    pose,
    covariance=None,
    *,
    floor_z_m: float = 0.02,
) -> np.ndarray:
    """Returns a copy of ``frame`` with the student's own-pose estimate drawn on the floor as
    ``camera`` sees it: a dot at the estimated position, a line along the estimated heading and,
    from ``covariance``, the 95% position ellipse and a wedge spanning the heading's 95% interval
    (filled translucent), all in ``ESTIMATE_COLOUR``, with a label giving the ellipse's
    semi-major axis (cm) and the wedge's half-angle (deg).

    Args:
      frame: RGB image, shape (height, width, 3), the size of ``camera``'s image.
      camera: the posed camera the frame was rendered from.
      pose: ``(x_m, y_m, yaw_rad)``, world frame; None or NaN draws nothing.
      covariance: of ``pose``, shape (3, 3) (m^2, rad^2); None draws the pose alone.
      floor_z_m: the height the drawing lies at, metres (just above the floor).
    """
    out = np.ascontiguousarray(frame).copy()
    if out.shape[1::-1] != camera.image_size:
        raise ValueError(
            f"frame of {out.shape[1]}x{out.shape[0]} pixels, camera of "
            f"{camera.image_size[0]}x{camera.image_size[1]}: they must agree"
        )
    if pose is None or not np.all(np.isfinite(np.asarray(pose, dtype=float))):
        return out
    x, y, yaw = (float(v) for v in pose)
    s = _scale(out)
    thick = max(1, int(round(2 * s)))

    def pixels(points_xy) -> np.ndarray | None:
        points = np.column_stack([points_xy, np.full(len(points_xy), floor_z_m)])
        px = camera.project(points)
        if not np.all(np.isfinite(px)):
            return None
        return np.round(px).astype(np.int32)

    half_angle, label = 0.0, "own pose estimate"
    if covariance is not None:
        cov = np.asarray(covariance, dtype=float)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise ValueError(f"covariance must be a finite 3x3 matrix, got shape {cov.shape}")
        values, vectors = np.linalg.eigh(cov[:2, :2])
        axes = np.sqrt(CHI2_2DOF_95 * np.clip(values, 0.0, None))
        t = np.linspace(0.0, 2.0 * np.pi, 48, endpoint=False)
        ring = (vectors @ (axes[:, None] * np.vstack([np.cos(t), np.sin(t)]))).T + (x, y)
        half_angle = min(_NORMAL_95 * float(np.sqrt(max(cov[2, 2], 0.0))), np.pi)
        label += f" 95%: {100 * axes[-1]:.1f} cm, {np.degrees(half_angle):.1f} deg"
        arc = yaw + np.linspace(-half_angle, half_angle, 17)
        wedge = np.vstack(
            [(x, y), np.column_stack([x + _WEDGE_M * np.cos(arc), y + _WEDGE_M * np.sin(arc)])]
        )
        wedge_px = pixels(wedge)
        if wedge_px is not None:
            tinted = out.copy()
            cv2.fillPoly(tinted, [wedge_px], ESTIMATE_COLOUR, cv2.LINE_AA)
            out[:] = (0.65 * out + 0.35 * tinted).astype(np.uint8)
            cv2.polylines(out, [wedge_px], True, ESTIMATE_COLOUR, 1, cv2.LINE_AA)
        ring_px = pixels(ring)
        if ring_px is not None:
            cv2.polylines(out, [ring_px], True, ESTIMATE_COLOUR, thick, cv2.LINE_AA)
    heading = pixels(np.array([(x, y), (x + _WEDGE_M * np.cos(yaw), y + _WEDGE_M * np.sin(yaw))]))
    if heading is not None:
        cv2.line(out, tuple(heading[0]), tuple(heading[1]), ESTIMATE_COLOUR, thick, cv2.LINE_AA)
        cv2.circle(out, tuple(heading[0]), max(2, int(4 * s)), ESTIMATE_COLOUR, -1, cv2.LINE_AA)
        origin = (int(heading[0][0]) + int(8 * s), int(heading[0][1]) + int(18 * s))
        size = cv2.getTextSize(label, _FONT, 0.5 * s, 1)[0]
        _shade(out, origin[0] - 2, origin[1] - size[1] - 3, origin[0] + size[0] + 3, origin[1] + 4)
        _text(out, label, origin, 0.5 * s, ESTIMATE_COLOUR)
    return out
