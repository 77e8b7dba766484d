"""Text drawn on video frames: the current word and motor directive, and a caption."""

from __future__ import annotations

import cv2
import numpy as np

_WORD_COLOURS = {"go": (60, 170, 75), "pick": (230, 140, 30), "lift": (70, 110, 230)}


def annotate(
    frame: np.ndarray,
    word: str | None,
    directive: str | None,
    caption: str = "",
    motor: np.ndarray | None = None,
) -> np.ndarray:
    """Returns a copy of an RGB frame with the word, the directive and an optional caption drawn on
    it; ``motor`` (4 graded activations, the associator's order) adds a small bar chart."""
    out = np.ascontiguousarray(frame).copy()
    h, w = out.shape[:2]
    scale = max(w / 640.0, 0.45)
    thick = max(1, int(round(2 * scale)))
    box_h = int(40 * scale) + 6
    cv2.rectangle(out, (0, 0), (w, box_h), (20, 20, 20), -1)
    x = int(10 * scale)
    if word is not None:
        colour = _WORD_COLOURS.get(word, (255, 255, 255))
        cv2.putText(
            out,
            f"'{word}'",
            (x, int(30 * scale)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.9 * scale,
            colour,
            thick + 1,
            cv2.LINE_AA,
        )
        x += int(130 * scale)
    if directive is not None:
        cv2.putText(
            out,
            directive.replace("_", " "),
            (x, int(30 * scale)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.8 * scale,
            (240, 240, 240),
            thick,
            cv2.LINE_AA,
        )
    if caption:
        size = cv2.getTextSize(caption, cv2.FONT_HERSHEY_SIMPLEX, 0.55 * scale, 1)[0]
        cv2.putText(
            out,
            caption,
            (w - size[0] - int(10 * scale), int(28 * scale)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.55 * scale,
            (200, 200, 200),
            1,
            cv2.LINE_AA,
        )
    if motor is not None:
        motor = np.clip(np.asarray(motor, dtype=float), 0, None)
        top = motor.max() if motor.max() > 0 else 1.0
        labels = ("F", "B", "R", "L")
        bar_w, bar_h = int(18 * scale), int(50 * scale)
        x0, y0 = int(10 * scale), h - int(12 * scale)
        for i, (value, label) in enumerate(zip(motor, labels, strict=True)):
            left = x0 + i * (bar_w + 6)
            cv2.rectangle(out, (left, y0 - bar_h), (left + bar_w, y0), (40, 40, 40), 1)
            cv2.rectangle(
                out, (left, y0 - int(bar_h * value / top)), (left + bar_w, y0), (240, 200, 40), -1
            )
            cv2.putText(
                out,
                label,
                (left + 3, y0 + int(11 * scale)),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.4 * scale,
                (20, 20, 20),
                1,
                cv2.LINE_AA,
            )
    return out
