"""Wall landmarks: a map of fixed ArUco markers, and the student's pose from the ones it sees.

A :class:`LandmarkMap` lists fixed markers (id, size, pose in the world); an arena ships its own
(``models/arena/landmarks.toml`` for the simulated one, read with :func:`read_landmark_map`). Ids
must not collide with the robots' plates (``perception.layout``).

:class:`LandmarkLocator`, configured once (map, head-camera intrinsics, head mount, detector
settings), finds the map's markers in a head-camera image (:meth:`~LandmarkLocator.detect`) and
fits the base's planar pose to all their corners at once (:meth:`~LandmarkLocator.locate`), through
the pan-tilt kinematics of ``perception.pantilt``: the camera sits at ``HeadMount.position_m`` in
the robot frame, turned by the measured pan and tilt; the robot stands level.

The fit is the robot-pose fit of ``perception.pose`` turned inside out: seen from the robot, the
world is a rigid planar body at the inverse pose, watched by a camera fixed in the robot frame. So
``fit_planar_pose`` (Levenberg-Marquardt over x, y, yaw, analytic Jacobian) fits the inverse pose,
which is inverted with its covariance. Without a prior pose, starts come from each of the two
largest markers' IPPE solutions (both flips), and the fit with the smallest error wins.

Frames: world x east, y north, z up (metres); yaw counter-clockwise from +x (radians).
Marker frame: ``perception.layout``'s (x right, y up as printed, z out of the face).
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import sys

import cv2
import numpy as np

from perception.camera import PinholeCamera
from perception.layout import DICTIONARY_NAME, QUIET_ZONE_M, default_layout
from perception.markers import DetectorConfig, MarkerDetector
from perception.pantilt import HeadMount, PanTiltLimits, head_camera, head_camera_rotation
from perception.pose import check_planar_pose, fit_planar_pose, quad_area_px, wrap_radians
from perception.wallframe import check_finite

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

_MARKER_KEYS = ("id", "size_m", "position_m", "normal", "up")


@dataclasses.dataclass(frozen=True, eq=False)
class LandmarkMarker:
    """One fixed marker.

    Attributes:
      marker_id: its id in ``perception.layout.DICTIONARY_NAME``.
      size_m: side of its black square, metres.
      position_m: its centre in the world, metres, shape (3,).
      rotation: world-from-marker rotation, shape (3, 3): columns the marker's x (right), y (up as
        printed) and z (out of its face, into the room) in the world frame.
    """

    marker_id: int
    size_m: float
    position_m: np.ndarray
    rotation: np.ndarray

    @classmethod
    def facing(cls, marker_id: int, size_m: float, position_m, normal, up=(0.0, 0.0, 1.0)):
        """Returns a marker centred at ``position_m`` whose face points along ``normal`` with its
        printed top towards ``up`` (world vectors; ``up`` is made perpendicular to ``normal``)."""
        if isinstance(marker_id, bool) or not isinstance(marker_id, (int, np.integer)):
            raise ValueError(f"marker id must be an integer, got {marker_id!r}")
        if not (isinstance(size_m, (int, float)) and math.isfinite(size_m) and size_m > 0):
            raise ValueError(f"marker {marker_id}: size_m must be > 0 metres, got {size_m!r}")
        vectors = {}
        for name, value in (("position_m", position_m), ("normal", normal), ("up", up)):
            vectors[name] = np.asarray(value, dtype=float)
            if vectors[name].shape != (3,) or not np.all(np.isfinite(vectors[name])):
                raise ValueError(f"marker {marker_id}: {name} must be 3 finite numbers")
        z = vectors["normal"] / (np.linalg.norm(vectors["normal"]) or np.nan)
        y = vectors["up"] - (vectors["up"] @ z) * z
        if not np.all(np.isfinite(z)) or np.linalg.norm(y) < 1e-6:
            raise ValueError(
                f"marker {marker_id}: normal must be non-zero and not parallel to up, "
                f"got normal {tuple(normal)}, up {tuple(up)}"
            )
        y /= np.linalg.norm(y)
        rotation = np.column_stack([np.cross(y, z), y, z])
        position = vectors["position_m"].copy()
        for array in (position, rotation):
            array.setflags(write=False)
        return cls(int(marker_id), float(size_m), position, rotation)

    def corners_world(self) -> np.ndarray:
        """Returns the four corners in the world, shape (4, 3), in ArUco order (TL, TR, BR, BL)."""
        h = 0.5 * self.size_m
        local = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
        return local @ self.rotation.T + self.position_m


class LandmarkMap:
    """The fixed markers of one arena, by id.

    Args:
      markers: the markers; ids unique, in the robots' dictionary, and not a robot plate's id.
      quiet_zone_m: white margin printed round each marker's black square, metres.
    """

    def __init__(self, markers, quiet_zone_m: float = QUIET_ZONE_M):
        robot_ids = {p.marker_id for p in default_layout()}
        n_ids = cv2.aruco.getPredefinedDictionary(
            getattr(cv2.aruco, DICTIONARY_NAME)
        ).bytesList.shape[0]
        by_id = {}
        for marker in markers:
            if marker.marker_id in by_id:
                raise ValueError(f"landmark id {marker.marker_id} appears twice in the map")
            if marker.marker_id in robot_ids:
                raise ValueError(
                    f"landmark id {marker.marker_id} is a robot plate's id; robot ids: "
                    f"{sorted(robot_ids)}"
                )
            if not 0 <= marker.marker_id < n_ids:
                raise ValueError(
                    f"landmark id {marker.marker_id} is outside {DICTIONARY_NAME} "
                    f"(allowed 0-{n_ids - 1})"
                )
            by_id[marker.marker_id] = marker
        if not (math.isfinite(quiet_zone_m) and quiet_zone_m >= 0):
            raise ValueError(f"quiet_zone_m must be >= 0 metres, got {quiet_zone_m!r}")
        self.markers = tuple(by_id[i] for i in sorted(by_id))
        self.quiet_zone_m = float(quiet_zone_m)
        self._by_id = by_id
        self._centres = np.array([m.position_m for m in self.markers]).reshape(-1, 3)
        self._normals = np.array([m.rotation[:, 2] for m in self.markers]).reshape(-1, 3)
        self._corners = np.array([m.corners_world() for m in self.markers]).reshape(-1, 4, 3)

    def __len__(self) -> int:
        return len(self.markers)

    def __contains__(self, marker_id) -> bool:
        return marker_id in self._by_id

    def __getitem__(self, marker_id: int) -> LandmarkMarker:
        if marker_id not in self._by_id:
            raise ValueError(f"unknown landmark id {marker_id!r}; allowed: {sorted(self._by_id)}")
        return self._by_id[marker_id]

    def select(self, found) -> list[tuple[int, np.ndarray]]:
        """Returns this map's markers among ``(marker_id, corners_px (4, 2))`` detections of one
        image, ids found more than once dropped (one of them is false), sorted by id; ValueError
        for corners that are not 4 finite pixels."""
        ids = [int(i) for i, _ in found]
        out = []
        for i, corners in found:
            if int(i) not in self or ids.count(int(i)) != 1:
                continue
            corners = np.asarray(corners, dtype=float)
            if corners.shape != (4, 2) or not np.all(np.isfinite(corners)):
                raise ValueError(
                    f"marker {i}: corners must be 4 finite pixels, shape (4, 2), "
                    f"got shape {corners.shape}"
                )
            out.append((int(i), corners))
        return sorted(out, key=lambda m: m[0])

    @property
    def ids(self) -> tuple[int, ...]:
        """Returns the ids, sorted."""
        return tuple(m.marker_id for m in self.markers)

    def visible(
        self,
        camera: PinholeCamera,
        *,
        margin_px: float = 2.0,
        max_view_angle_deg: float = 65.0,
        min_side_px: float = 12.0,
    ) -> list[tuple[int, np.ndarray]]:
        """Returns ``(marker_id, corners_px (4, 2))`` of the markers ``camera`` should see: all
        corners at least ``margin_px`` inside the image, the face turned at most
        ``max_view_angle_deg`` from the line of sight, every side at least ``min_side_px`` long.
        Exact projections, no occlusion (the robots and the table are not modelled)."""
        limit = math.cos(math.radians(max_view_angle_deg))
        sight = self._centres - camera.position_world
        distance = np.linalg.norm(sight, axis=1)
        facing = -np.einsum("ij,ij->i", sight, self._normals) >= limit * distance
        if not facing.any():
            return []
        index = np.flatnonzero(facing)
        corners = camera.project(self._corners[index].reshape(-1, 3)).reshape(-1, 4, 2)
        inside = camera.in_image(corners.reshape(-1, 2), margin_px).reshape(-1, 4).all(axis=1)
        sides = np.linalg.norm(corners - np.roll(corners, -1, axis=1), axis=2).min(axis=1)
        keep = inside & (sides >= min_side_px)
        return [(self.markers[i].marker_id, corners[k]) for k, i in enumerate(index) if keep[k]]


def read_landmark_map(path) -> LandmarkMap:
    """Reads a landmark map from TOML; ValueError naming the file and the entry for anything wrong.

    Format (metres, world frame)::

        dictionary = "DICT_4X4_50"     # must be perception.layout.DICTIONARY_NAME
        quiet_zone_m = 0.03            # optional
        [[marker]]
        id = 20
        size_m = 0.30
        position_m = [-1.6, 1.996, 0.65]   # the centre of the printed face
        normal = [0.0, -1.0, 0.0]          # out of the face, into the room
        up = [0.0, 0.0, 1.0]               # optional: the printed top's direction
    """
    path = pathlib.Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except OSError as error:
        raise ValueError(f"cannot read landmark map {path}: {error.strerror or error}") from None
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"landmark map {path} is not valid TOML: {error}") from None
    unknown = sorted(set(data) - {"dictionary", "quiet_zone_m", "marker"})
    if unknown:
        raise ValueError(
            f"landmark map {path}: unknown key '{unknown[0]}'; allowed: dictionary, "
            "quiet_zone_m, [[marker]]"
        )
    if data.get("dictionary", DICTIONARY_NAME) != DICTIONARY_NAME:
        raise ValueError(
            f"landmark map {path}: dictionary must be {DICTIONARY_NAME!r}, "
            f"got {data['dictionary']!r}"
        )
    markers = []
    for k, entry in enumerate(data.get("marker", [])):
        extra = sorted(set(entry) - set(_MARKER_KEYS))
        missing = [key for key in _MARKER_KEYS[:4] if key not in entry]
        if extra or missing:
            raise ValueError(
                f"landmark map {path}: marker {k}: "
                + (f"unknown key '{extra[0]}'" if extra else f"missing '{missing[0]}'")
                + f"; keys: {', '.join(_MARKER_KEYS)} (up optional)"
            )
        try:
            markers.append(
                LandmarkMarker.facing(
                    entry["id"],
                    entry["size_m"],
                    entry["position_m"],
                    entry["normal"],
                    entry.get("up", (0.0, 0.0, 1.0)),
                )
            )
        except (ValueError, TypeError) as error:
            raise ValueError(f"landmark map {path}: marker {k}: {error}") from None
    try:
        return LandmarkMap(markers, float(data.get("quiet_zone_m", QUIET_ZONE_M)))
    except ValueError as error:
        raise ValueError(f"landmark map {path}: {error}") from None


@dataclasses.dataclass(frozen=True, eq=False)
class LandmarkFix:
    """The base's pose from one image's landmarks.

    Attributes:
      pose: ``(x_m, y_m, yaw_rad)`` of the robot frame, world frame, shape (3,).
      covariance: of ``pose``, shape (3, 3) (m^2, m rad, rad^2), from the fit's Jacobian with
        independent noise on each corner coordinate of ``corner_sigma_px``, or of the residuals'
        standard deviation when that is over 1.5 times larger.
      marker_ids: ids of the landmarks used, sorted.
      rms_error_px: RMS corner reprojection error after the fit, pixels.
    """

    pose: np.ndarray
    covariance: np.ndarray
    marker_ids: tuple[int, ...]
    rms_error_px: float


@dataclasses.dataclass(frozen=True)
class LocatorConfig:
    """How a landmark fix is made.

    Attributes:
      corner_sigma_px: standard deviation of a detected corner's u and v, pixels; a fit whose
        residuals show over 1.5 times more uses theirs (docs/perception.md, "Self-localisation").
      max_rms_error_px: fits that miss the corners by more (RMS) are refused (a wrong start or a
        false detection).
      min_markers: fewest landmarks a fix uses; 1 works from a prior pose, a start from nothing
        asks for :attr:`min_markers_global` (one small marker's flip is ambiguous).
      min_markers_global: fewest landmarks for a fix without a prior pose.
      tilt_search_deg, tilt_step_deg, tilt_votes: the head's tilt zero offset is found from the
        landmarks, not believed: on each of the first ``tilt_votes`` frames with at least
        ``min_markers_global`` landmarks the tilt correction of least corner error is searched
        within +- ``tilt_search_deg`` on a ``tilt_step_deg`` grid (ties to the smallest), and
        every fit uses the median of those found (0: the tilt reading is believed). A tilt error
        turns into a range error, because the landmarks hang near the camera's height
        (docs/transfer.md, "The head camera with the realistic preset").
    """

    corner_sigma_px: float = 0.5
    max_rms_error_px: float = 2.0
    min_markers: int = 1
    min_markers_global: int = 2
    tilt_search_deg: float = 3.0
    tilt_step_deg: float = 0.1
    tilt_votes: int = 20

    def __post_init__(self):
        if not (math.isfinite(self.corner_sigma_px) and self.corner_sigma_px > 0):
            raise ValueError(f"corner_sigma_px must be > 0 pixels, got {self.corner_sigma_px!r}")
        if not (math.isfinite(self.max_rms_error_px) and self.max_rms_error_px > 0):
            raise ValueError(f"max_rms_error_px must be > 0 pixels, got {self.max_rms_error_px!r}")
        for name in ("min_markers", "min_markers_global", "tilt_votes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if not (math.isfinite(self.tilt_search_deg) and 0 <= self.tilt_search_deg <= 10):
            raise ValueError(
                f"tilt_search_deg must be within [0, 10] degrees, got {self.tilt_search_deg!r}"
            )
        if not (math.isfinite(self.tilt_step_deg) and self.tilt_step_deg > 0):
            raise ValueError(f"tilt_step_deg must be > 0 degrees, got {self.tilt_step_deg!r}")


def invert_planar(pose) -> np.ndarray:
    """Returns the inverse of a planar pose ``(x, y, yaw)``: world-from-robot becomes
    robot-from-world."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([-(c * x + s * y), s * x - c * y, float(wrap_radians(-yaw))])


def _invert_jacobian(inverse) -> np.ndarray:
    """Returns d(pose)/d(inverse pose), shape (3, 3), at ``inverse = invert_planar(pose)``."""
    xi, yi, yawi = inverse
    c, s = math.cos(yawi), math.sin(yawi)
    # pose = invert_planar(inverse): x = -(c xi + s yi), y = s xi - c yi, yaw = -yawi.
    return np.array([[-c, -s, s * xi - c * yi], [s, -c, c * xi + s * yi], [0.0, 0.0, -1.0]])


class LandmarkLocator:
    """Finds the map's markers in head-camera images and fits the base's pose to them.

    Args:
      landmark_map: the arena's landmarks.
      intrinsics: the head camera's calibration (its pose is ignored).
      mount: where the head's optical centre sits on the robot.
      config: fit settings.
      detector_config: marker detection settings (``perception.markers``).
    """

    def __init__(
        self,
        landmark_map: LandmarkMap,
        intrinsics: PinholeCamera,
        *,
        mount: HeadMount = HeadMount(),
        config: LocatorConfig = LocatorConfig(),
        detector_config: DetectorConfig = DetectorConfig(),
    ):
        if not len(landmark_map):
            raise ValueError("the landmark map is empty")
        self.map = landmark_map
        self.intrinsics = intrinsics
        self.mount = mount
        self.config = config
        self.detector = MarkerDetector(detector_config)
        self._corners = {m.marker_id: m.corners_world() for m in landmark_map.markers}
        steps = int(round(config.tilt_search_deg / config.tilt_step_deg))
        grid = np.arange(-steps, steps + 1) * config.tilt_step_deg
        self._tilt_grid = grid[np.argsort(np.abs(grid), kind="stable")]  # the smallest first
        #: The correction added to the tilt readings (degrees): the median of ``tilt_votes``.
        self.tilt_correction_deg = 0.0
        self.tilt_votes: list[float] = []

    def detect(self, image) -> list[tuple[int, np.ndarray]]:
        """Returns ``(marker_id, corners_px (4, 2))`` of each map marker found once in ``image``
        (an id found twice is dropped: one of the two is false)."""
        return self.select(self.detector.detect_all_corners(image))

    def select(self, found) -> list[tuple[int, np.ndarray]]:
        """Returns the map's markers among ``(marker_id, corners_px)`` detections (e.g. a shared
        pass, ``self.detector.detect_all_corners``): :meth:`LandmarkMap.select`."""
        return self.map.select(found)

    def robot_camera(self, pan_deg: float, tilt_deg: float) -> PinholeCamera:
        """Returns the head camera posed in the robot frame (the robot at the world origin)."""
        return self.intrinsics.with_pose(
            head_camera_rotation(0.0, pan_deg, tilt_deg), np.asarray(self.mount.position_m, float)
        )

    def locate(
        self, found, pan_deg: float, tilt_deg: float, prior=None, min_markers: int | None = None
    ) -> LandmarkFix | None:
        """Returns the base's pose fitted to all the landmarks' corners, or None.

        Args:
          found: ``(marker_id, corners_px (4, 2))`` of map markers (:meth:`detect`), corners in
            ArUco order (TL, TR, BR, BL).
          pan_deg, tilt_deg: the head's measured angles when the image was taken.
          prior: a predicted ``(x_m, y_m, yaw_rad)`` to start from; None starts from each of the two
            largest markers' IPPE poses (both flips) and needs ``min_markers_global`` markers.
          min_markers: fewest landmarks to fit; default ``min_markers`` with a prior, else
            ``min_markers_global``.

        None when too few markers are seen or no fit reaches ``max_rms_error_px``.
        """
        check_finite(pan_deg=pan_deg, tilt_deg=tilt_deg)
        found = self.select(found)
        needed = min_markers
        if needed is None:
            needed = (
                self.config.min_markers if prior is not None else self.config.min_markers_global
            )
        if len(found) < needed:
            return None
        if prior is not None:
            prior = check_planar_pose(prior, "prior")
        tilt_deg = tilt_deg + self._tilt_correction(found, pan_deg, tilt_deg, prior)
        best = self._best_fit(found, pan_deg, tilt_deg, prior)
        if best is None:
            return None
        cost, inverse, jacobian = best
        n_corners = 4 * len(found)
        rms = math.sqrt(cost / n_corners)
        if rms > self.config.max_rms_error_px:
            return None
        # Per-axis corner noise: the configured one, unless the residuals' own estimate (2N values,
        # 3 parameters fitted) says the corners are clearly noisier (a model error).
        sigma = self.config.corner_sigma_px
        residual_sigma = math.sqrt(cost / max(2 * n_corners - 3, 1))
        if residual_sigma > 1.5 * sigma:
            sigma = residual_sigma
        try:
            covariance_inverse = sigma**2 * np.linalg.inv(jacobian.T @ jacobian)
        except np.linalg.LinAlgError:
            return None
        d_pose = _invert_jacobian(inverse)
        covariance = d_pose @ covariance_inverse @ d_pose.T
        return LandmarkFix(
            invert_planar(inverse),
            0.5 * (covariance + covariance.T),
            tuple(i for i, _ in found),
            rms,
        )

    def _best_fit(self, found, pan_deg: float, tilt_deg: float, prior):
        """Returns ``(cost px^2, inverse pose, jacobian)`` of the least-cost fit to the corners
        from the prior (or from every IPPE start), or None when no start gives one."""
        camera = self.robot_camera(pan_deg, tilt_deg)
        world = np.concatenate([self._corners[i] for i, _ in found])
        observed = np.concatenate([c for _, c in found])
        if prior is not None:
            starts = [invert_planar(prior)]
        else:
            starts = self._ippe_starts(found, camera)
        best = None
        for start in starts:
            try:
                params, residuals, jacobian = fit_planar_pose(start, world, observed, camera)
            except ValueError:  # the start puts a corner behind the camera
                continue
            cost = float(residuals @ residuals)
            if np.isfinite(cost) and (best is None or cost < best[0]):
                best = (cost, params, jacobian)
        return best

    def _tilt_correction(self, found, pan_deg: float, tilt_deg: float, prior) -> float:
        """Returns the correction (degrees) the fits add to the tilt reading, after voting with
        this frame when it is one of the first ``tilt_votes`` with enough landmarks."""
        config = self.config
        if (
            config.tilt_search_deg > 0
            and len(found) >= config.min_markers_global
            and len(self.tilt_votes) < config.tilt_votes
        ):
            costs = []
            for correction in self._tilt_grid:
                fit = self._best_fit(found, pan_deg, tilt_deg + correction, prior)
                costs.append(math.inf if fit is None else fit[0])
            if math.isfinite(min(costs)):
                self.tilt_votes.append(float(self._tilt_grid[int(np.argmin(costs))]))
                self.tilt_correction_deg = float(np.median(self.tilt_votes))
        return self.tilt_correction_deg

    def _ippe_starts(self, found, camera: PinholeCamera) -> list[np.ndarray]:
        """Returns inverse-pose starts from the two largest markers' IPPE solutions."""
        starts = []
        distortion = camera.distortion if camera.distortion.size else None
        mount = np.asarray(self.mount.position_m, dtype=float)
        rotation_rc = camera.rotation_world_from_camera  # robot-from-camera
        for marker_id, corners in sorted(found, key=lambda m: -quad_area_px(m[1]))[:2]:
            marker = self.map[marker_id]
            h = 0.5 * marker.size_m
            square = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
            n, rvecs, tvecs, _ = cv2.solvePnPGeneric(
                square,
                np.ascontiguousarray(corners),
                camera.matrix,
                distortion,
                flags=cv2.SOLVEPNP_IPPE_SQUARE,
            )
            for k in range(n):
                rotation_cm, _ = cv2.Rodrigues(rvecs[k])
                rotation_wc = marker.rotation @ rotation_cm.T
                position_wc = marker.position_m - rotation_wc @ np.ravel(tvecs[k])
                rotation_wr = rotation_wc @ rotation_rc.T
                yaw = math.atan2(rotation_wr[1, 0], rotation_wr[0, 0])
                c, s = math.cos(yaw), math.sin(yaw)
                x = position_wc[0] - (c * mount[0] - s * mount[1])
                y = position_wc[1] - (s * mount[0] + c * mount[1])
                starts.append(invert_planar((x, y, yaw)))
        return starts


def landmark_view(
    landmark_map: LandmarkMap,
    intrinsics: PinholeCamera,
    pose,
    tilts_deg=(-10.0, -20.0, -30.0),
    *,
    limits: PanTiltLimits = PanTiltLimits(),
    mount: HeadMount = HeadMount(),
    step_deg: float = 7.0,
) -> tuple[float, float, int]:
    """Returns ``(pan_deg, tilt_deg, n)``: the head angles, pan within the limits on a
    ``step_deg`` grid and tilt one of ``tilts_deg``, that should show the most landmarks
    (``LandmarkMap.visible``) from ``pose`` (x_m, y_m, yaw_rad), and how many; ties go to the pan
    nearest straight ahead, then to the first tilt. Near walls need the lower tilt (the landmarks
    hang low), far ones the higher."""
    check_planar_pose(pose, "pose")
    if not (math.isfinite(step_deg) and step_deg > 0):
        raise ValueError(f"step_deg must be > 0 degrees, got {step_deg!r}")
    tilts = tuple(float(t) for t in tilts_deg)
    if not tilts or not all(limits.tilt_min_deg <= t <= limits.tilt_max_deg for t in tilts):
        raise ValueError(
            f"tilts_deg must be one or more tilts within [{limits.tilt_min_deg}, "
            f"{limits.tilt_max_deg}] degrees, got {tilts_deg!r}"
        )
    pans = np.arange(limits.pan_min_deg, limits.pan_max_deg + 1e-9, step_deg)
    best = (0, 0.0, tilts[0])
    for pan in sorted(pans, key=abs):
        for tilt in tilts:
            camera = head_camera(intrinsics, pose, float(pan), tilt, mount)
            n = len(landmark_map.visible(camera))
            if n > best[0]:
                best = (n, float(pan), tilt)
    return best[1], best[2], best[0]
