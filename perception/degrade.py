"""Image degradations a real camera adds, as pure numpy/OpenCV functions on uint8 frames.

``ImageDegradation`` holds the levels (0: off) and applies them in the order a camera does:
exposure/gain, lens distortion, motion blur, sensor noise, then JPEG compression. Each takes and
returns an (H, W, 3) or (H, W) uint8 image and never changes its input; they run unchanged on a
real robot's frames (this module does not know the simulator).
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np


def exposure(image: np.ndarray, stops: float) -> np.ndarray:
    """Returns the image with its exposure changed by ``stops`` (a gain of 2**stops, clipped)."""
    if stops == 0:
        return image.copy()
    return np.clip(image.astype(np.float32) * 2.0**stops + 0.5, 0, 255).astype(np.uint8)


def pixel_noise(image: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Returns the image with Gaussian noise of ``sigma`` grey levels per pixel and channel."""
    if sigma == 0:
        return image.copy()
    noisy = image.astype(np.float32) + rng.normal(0.0, sigma, image.shape).astype(np.float32)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)


def motion_blur(image: np.ndarray, length_px: float, angle_deg: float = 0.0) -> np.ndarray:
    """Returns the image blurred along a line of ``length_px`` pixels at ``angle_deg`` (image x to
    the right, counter-clockwise), as a camera moving during its exposure sees it."""
    if length_px <= 1:
        return image.copy()
    size = int(math.ceil(length_px)) | 1
    kernel = np.zeros((size, size), np.float32)
    centre = size // 2
    c, s = math.cos(math.radians(angle_deg)), -math.sin(math.radians(angle_deg))
    for t in np.linspace(-(length_px - 1) / 2, (length_px - 1) / 2, 4 * size):
        kernel[int(round(centre + s * t)), int(round(centre + c * t))] = 1.0
    kernel /= kernel.sum()
    return cv2.filter2D(image, -1, kernel, borderType=cv2.BORDER_REPLICATE)


def jpeg(image: np.ndarray, quality: int) -> np.ndarray:
    """Returns the image after JPEG compression at ``quality`` (1-100) and decoding."""
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover
        raise ValueError("JPEG encoding failed")
    return cv2.imdecode(data, cv2.IMREAD_UNCHANGED)


def radial_distortion(image: np.ndarray, k1: float) -> np.ndarray:
    """Returns the image as a lens with radial distortion ``k1`` (on coordinates normalised by half
    the image diagonal) would show it: a pixel at normalised radius r in the ideal image appears at
    r (1 + k1 r^2). k1 < 0 is barrel distortion."""
    if k1 == 0:
        return image.copy()
    h, w = image.shape[:2]
    cx, cy, norm = (w - 1) / 2, (h - 1) / 2, math.hypot(w, h) / 2
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    xd, yd = (x - cx) / norm, (y - cy) / norm
    rd = np.sqrt(xd * xd + yd * yd)
    # Invert rd = r (1 + k1 r^2) for the ideal radius r with a few Newton steps.
    r = rd.copy()
    for _ in range(6):
        r -= (r * (1 + k1 * r * r) - rd) / (1 + 3 * k1 * r * r)
    scale = np.where(rd > 0, r / np.maximum(rd, 1e-12), 1.0).astype(np.float32)
    map_x = (xd * scale * norm + cx).astype(np.float32)
    map_y = (yd * scale * norm + cy).astype(np.float32)
    return cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


@dataclasses.dataclass(frozen=True)
class ImageDegradation:
    """A camera's image faults (0: off).

    Attributes:
      noise_sigma: Gaussian sensor noise, grey levels (0-255 scale).
      blur_px: motion blur length, pixels (along a direction drawn per frame).
      jpeg_quality: JPEG compression quality 1-100 (0: no compression).
      exposure_stops: exposure/gain change, stops (2**stops).
      distortion_k1: radial lens distortion the student does not model (normalised radius).
    """

    noise_sigma: float = 0.0
    blur_px: float = 0.0
    jpeg_quality: int = 0
    exposure_stops: float = 0.0
    distortion_k1: float = 0.0

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            key = field.name
            if isinstance(value, bool) or not (
                isinstance(value, (int, float)) and math.isfinite(value)
            ):
                raise ValueError(f"{key} must be a finite number, got {value!r}")
        for name in ("noise_sigma", "blur_px"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0 (0: off), got {getattr(self, name)}")
        if not isinstance(self.jpeg_quality, int) or not 0 <= self.jpeg_quality <= 100:
            raise ValueError(
                f"jpeg_quality must be an integer in [0, 100] (0: off), got {self.jpeg_quality!r}"
            )
        if not -0.5 <= self.distortion_k1 <= 0.5:
            raise ValueError(f"distortion_k1 must be in [-0.5, 0.5], got {self.distortion_k1}")

    @property
    def active(self) -> bool:
        """Returns whether any degradation is on."""
        return self != ImageDegradation()

    def apply(self, image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Returns the degraded frame (the input is not changed); ``rng`` draws the noise and the
        blur's direction."""
        out = exposure(image, self.exposure_stops)
        out = radial_distortion(out, self.distortion_k1)
        if self.blur_px > 1:
            out = motion_blur(out, self.blur_px, float(rng.uniform(0.0, 180.0)))
        out = pixel_noise(out, self.noise_sigma, rng)
        if self.jpeg_quality:
            out = jpeg(out, self.jpeg_quality)
        return out
