"""A pinhole camera with optional lens distortion: intrinsics, extrinsics and projection.

Camera frame (OpenCV's convention): x to the right of the image, y down the image, z forward along
the optical axis; metres. Pixel coordinates are OpenCV's: ``(u, v)`` with the centre of the top-left
pixel at ``(0, 0)``.

World frame: the arena's (x east, y north, z up; metres). Extrinsics are the camera's pose in the
world: ``rotation_world_from_camera`` (its columns are the camera's x, y, z axes in world
coordinates) and ``position_world`` (the optical centre).

This module reads no simulator: ``peoplebot_sim`` converts a MuJoCo camera (which looks along its
-z with y up) to OpenCV axes and calls :meth:`PinholeCamera.from_fovy`.
"""

from __future__ import annotations

import copy
import dataclasses

import cv2
import numpy as np

#: Numbers of distortion coefficients OpenCV accepts.
DISTORTION_LENGTHS = (0, 4, 5, 8, 12, 14)
_IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def _readonly(array: np.ndarray) -> np.ndarray:
    array = np.array(array, dtype=float)
    array.setflags(write=False)
    return array


def _check_pixels(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value <= 0:
        raise ValueError(f"{name} must be a positive integer number of pixels, got {value!r}")


def check_rotation(rotation, name: str = "rotation") -> np.ndarray:
    """Returns ``rotation`` as a float (3, 3) array; raises ValueError unless it is a proper
    rotation."""
    rotation = np.asarray(rotation, dtype=float)
    if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)):
        raise ValueError(f"{name} must be a finite 3x3 matrix, got shape {rotation.shape}")
    (a, b, c), (d, e, f), (g, h, i) = rotation.tolist()
    determinant = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    if np.abs(rotation.T @ rotation - _IDENTITY).max() > 1e-6 or determinant < 0:
        raise ValueError(f"{name} must be orthonormal with determinant +1, got\n{rotation}")
    return rotation


def look_at_rotation(position_world, target_world, up_world=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Returns ``rotation_world_from_camera`` for a camera at ``position_world`` looking at
    ``target_world``.

    The image's "up" (camera -y) is as close to ``up_world`` as possible; for a camera looking
    straight down, pass an ``up_world`` in the floor plane (e.g. world +y, so that north is at the
    image's top). Shapes (3,), metres, world frame.
    """
    points = {}
    for name, value in (
        ("position_world", position_world),
        ("target_world", target_world),
        ("up_world", up_world),
    ):
        points[name] = np.asarray(value, dtype=float)
        if points[name].shape != (3,) or not np.all(np.isfinite(points[name])):
            raise ValueError(f"{name} must be three finite numbers, got {value!r}")
    forward = points["target_world"] - points["position_world"]
    norm = np.linalg.norm(forward)
    if not np.isfinite(norm) or norm < 1e-12:
        raise ValueError("target_world must differ from position_world and both must be finite")
    z = forward / norm
    up = points["up_world"]
    x = np.cross(z, up)  # camera x (right) = forward x up
    if np.linalg.norm(x) < 1e-9:
        raise ValueError(
            f"up_world {tuple(up)} is parallel to the viewing direction; choose another"
        )
    x /= np.linalg.norm(x)
    y = np.cross(z, x)  # down
    return np.column_stack([x, y, z])


@dataclasses.dataclass(frozen=True, eq=False)
class PinholeCamera:
    """A calibrated camera and its pose in the world.

    Attributes:
      matrix: intrinsic matrix K, shape (3, 3): ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, pixels.
      distortion: OpenCV distortion coefficients ``(k1, k2, p1, p2[, k3[, ...]])``, shape (n,) with
        n one of ``DISTORTION_LENGTHS``; empty or zeros for an ideal (rendered) camera.
      image_size: ``(width, height)`` in pixels.
      rotation_world_from_camera: shape (3, 3), OpenCV camera axes expressed in the world frame.
      position_world: optical centre in metres, world frame, shape (3,).
    """

    matrix: np.ndarray
    distortion: np.ndarray
    image_size: tuple[int, int]
    rotation_world_from_camera: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(3))
    position_world: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        k = np.asarray(self.matrix, dtype=float)
        if k.shape != (3, 3) or not np.all(np.isfinite(k)):
            raise ValueError(f"matrix must be a finite 3x3 intrinsic matrix, got shape {k.shape}")
        if k[0, 0] <= 0 or k[1, 1] <= 0:
            raise ValueError(f"focal lengths fx, fy must be > 0 pixels, got {k[0, 0]}, {k[1, 1]}")
        if not np.allclose(k[2], (0.0, 0.0, 1.0)) or k[1, 0] != 0:
            raise ValueError(
                f"matrix must have the form [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got\n{k}"
            )
        d = np.asarray(self.distortion, dtype=float).ravel()
        if d.size not in DISTORTION_LENGTHS or not np.all(np.isfinite(d)):
            raise ValueError(
                f"distortion must hold a finite number of coefficients, one of "
                f"{DISTORTION_LENGTHS}, "
                f"got {d.size} values {d.tolist()}"
            )
        size = tuple(self.image_size)
        if len(size) != 2 or not all(
            isinstance(s, (int, np.integer)) and not isinstance(s, bool) and s > 0 for s in size
        ):
            raise ValueError(f"image_size must be (width, height), positive integers, got {size!r}")
        rotation = check_rotation(self.rotation_world_from_camera, "rotation_world_from_camera")
        position = np.asarray(self.position_world, dtype=float)
        if position.shape != (3,) or not np.all(np.isfinite(position)):
            raise ValueError(f"position_world must be 3 finite metres, got {self.position_world!r}")
        object.__setattr__(self, "matrix", _readonly(k))
        object.__setattr__(self, "distortion", _readonly(d))
        object.__setattr__(self, "image_size", (int(size[0]), int(size[1])))
        object.__setattr__(self, "rotation_world_from_camera", _readonly(rotation))
        object.__setattr__(self, "position_world", _readonly(position))

    @classmethod
    def from_fovy(
        cls,
        width: int,
        height: int,
        fovy_deg: float,
        rotation_world_from_camera=_IDENTITY,
        position_world=(0.0, 0.0, 0.0),
    ) -> PinholeCamera:
        """Returns an ideal camera from the image size and vertical field of view (MuJoCo's
        ``fovy``).

        ``fx = fy = (height / 2) / tan(fovy / 2)``; the principal point is the image centre in
        OpenCV's pixel-centre convention, ``((width - 1) / 2, (height - 1) / 2)``. No distortion.
        """
        if not np.isfinite(fovy_deg) or not 0.0 < fovy_deg < 180.0:
            raise ValueError(f"fovy_deg must be in (0, 180) degrees, got {fovy_deg!r}")
        _check_pixels("width", width)
        _check_pixels("height", height)
        f = 0.5 * height / np.tan(0.5 * np.radians(fovy_deg))
        k = np.array([[f, 0.0, 0.5 * (width - 1)], [0.0, f, 0.5 * (height - 1)], [0.0, 0.0, 1.0]])
        return cls(
            k, np.zeros(0), (int(width), int(height)), rotation_world_from_camera, position_world
        )

    @classmethod
    def from_fovx(
        cls,
        width: int,
        height: int,
        fovx_deg: float,
        rotation_world_from_camera=_IDENTITY,
        position_world=(0.0, 0.0, 0.0),
    ) -> PinholeCamera:
        """Returns an ideal camera with square pixels from its horizontal field of view."""
        if not np.isfinite(fovx_deg) or not 0.0 < fovx_deg < 180.0:
            raise ValueError(f"fovx_deg must be in (0, 180) degrees, got {fovx_deg!r}")
        _check_pixels("width", width)
        _check_pixels("height", height)
        f = 0.5 * width / np.tan(0.5 * np.radians(fovx_deg))
        fovy_deg = float(np.degrees(2.0 * np.arctan(0.5 * height / f)))
        return cls.from_fovy(width, height, fovy_deg, rotation_world_from_camera, position_world)

    def with_pose(self, rotation_world_from_camera, position_world) -> PinholeCamera:
        """Returns the same camera (intrinsics) at another pose, e.g. a moving head camera.

        Only the new pose is validated (the intrinsics already were): this runs every frame."""
        rotation = check_rotation(rotation_world_from_camera, "rotation_world_from_camera")
        position = np.asarray(position_world, dtype=float)
        if position.shape != (3,) or not np.all(np.isfinite(position)):
            raise ValueError(f"position_world must be 3 finite metres, got {position_world!r}")
        moved = copy.copy(self)
        object.__setattr__(moved, "rotation_world_from_camera", _readonly(rotation))
        object.__setattr__(moved, "position_world", _readonly(position))
        return moved

    def with_focal_scale(self, scale: float) -> PinholeCamera:
        """Returns the same camera with both focal lengths (fx, fy, and the skew) times ``scale``;
        the principal point, distortion and pose kept."""
        if not (np.isfinite(scale) and scale > 0):
            raise ValueError(f"focal scale must be a finite number > 0, got {scale!r}")
        matrix = np.array(self.matrix, dtype=float)
        matrix[:2, :2] *= scale
        return dataclasses.replace(self, matrix=matrix)

    @property
    def width(self) -> int:
        """Returns the image width in pixels."""
        return self.image_size[0]

    @property
    def height(self) -> int:
        """Returns the image height in pixels."""
        return self.image_size[1]

    @property
    def fovy_deg(self) -> float:
        """Returns the vertical field of view in degrees (ignoring distortion)."""
        return float(np.degrees(2.0 * np.arctan(0.5 * self.height / self.matrix[1, 1])))

    @property
    def rotation_camera_from_world(self) -> np.ndarray:
        """Returns the world-to-camera rotation, shape (3, 3)."""
        return self.rotation_world_from_camera.T

    @property
    def translation_camera_from_world(self) -> np.ndarray:
        """Returns t with ``p_camera = R_camera_from_world @ p_world + t``, metres, shape (3,)."""
        return -self.rotation_world_from_camera.T @ self.position_world

    def world_to_camera(self, points_world) -> np.ndarray:
        """Returns points in the camera frame, shape (N, 3), from world points, shape (N, 3) or
        (3,)."""
        p = np.atleast_2d(np.asarray(points_world, dtype=float))
        return (p - self.position_world) @ self.rotation_world_from_camera

    def camera_to_world(self, points_camera) -> np.ndarray:
        """Returns world points, shape (N, 3), from camera-frame points, shape (N, 3) or (3,)."""
        p = np.atleast_2d(np.asarray(points_camera, dtype=float))
        return p @ self.rotation_world_from_camera.T + self.position_world

    def project_camera(self, points_camera) -> np.ndarray:
        """Returns pixels ``(u, v)``, shape (N, 2), of camera-frame points, shape (N, 3).

        Points at or behind the optical centre (z <= 0) get NaN.
        """
        p = np.atleast_2d(np.asarray(points_camera, dtype=float))
        if p.shape[-1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {p.shape}")
        out = np.full((len(p), 2), np.nan)
        front = p[:, 2] > 1e-9
        if np.any(front):
            pixels, _ = cv2.projectPoints(
                np.ascontiguousarray(p[front]),
                np.zeros(3),
                np.zeros(3),
                self.matrix,
                self.distortion if self.distortion.size else None,
            )
            out[front] = pixels.reshape(-1, 2)
        return out

    def project(self, points_world) -> np.ndarray:
        """Returns pixels ``(u, v)``, shape (N, 2), of world points, shape (N, 3); NaN behind the
        camera."""
        return self.project_camera(self.world_to_camera(points_world))

    def in_image(self, pixels, margin_px: float = 0.0) -> np.ndarray:
        """Returns a boolean mask, shape (N,), of pixels at least ``margin_px`` inside the image."""
        px = np.atleast_2d(np.asarray(pixels, dtype=float))
        with np.errstate(invalid="ignore"):
            return (
                (px[:, 0] >= -0.5 + margin_px)
                & (px[:, 0] <= self.width - 0.5 - margin_px)
                & (px[:, 1] >= -0.5 + margin_px)
                & (px[:, 1] <= self.height - 0.5 - margin_px)
            )

    def undistort_pixels(self, pixels) -> np.ndarray:
        """Returns normalised image coordinates ``(x/z, y/z)``, shape (N, 2), of pixels, shape (N,
        2)."""
        px = np.atleast_2d(np.asarray(pixels, dtype=float)).reshape(-1, 1, 2)
        normalised = cv2.undistortPoints(
            px, self.matrix, self.distortion if self.distortion.size else None
        )
        return normalised.reshape(-1, 2)

    def pixel_rays(self, pixels) -> np.ndarray:
        """Returns unit viewing directions in the world frame, shape (N, 3), through pixels (N, 2).

        Each ray starts at ``position_world``.
        """
        xy = self.undistort_pixels(pixels)
        d = np.column_stack([xy, np.ones(len(xy))])
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return d @ self.rotation_world_from_camera.T

    def intersect_plane_z(self, pixels, z_world: float = 0.0) -> np.ndarray:
        """Returns where the rays through ``pixels`` (N, 2) meet the plane ``z = z_world``, shape
        (N, 3).

        NaN where a ray is parallel to the plane or meets it behind the camera.
        """
        rays = self.pixel_rays(pixels)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (z_world - self.position_world[2]) / rays[:, 2]
        s = np.where(np.isfinite(s) & (s > 0), s, np.nan)
        return self.position_world + s[:, None] * rays
