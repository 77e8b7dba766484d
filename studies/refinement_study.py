"""Measures ArUco corner refinement methods on synthetic warped markers (the numbers in docs/perception.md).

Run: ``python -m studies.refinement_study [--samples N] [--seed S]``. Prints a JSON list with,
per viewpoint, image noise and refinement method: the detection rate, the median corner error
(pixels), the median single-marker IPPE position (cm) and rotation (deg) errors, the median and
95th-percentile planar robot pose errors after the level-robot fit (cm, deg), and the mean detection
time (ms).

Viewpoints, at 320x240 as the simulator renders:
- ``overhead``: fovy 40 deg, 4.9 m above the floor looking straight down; top plates (0.30 m) only,
  about 20-27 pixels across; robots anywhere their top plate is fully in view.
- ``head``: horizontal FOV 45 deg, 1.2 m above the floor, aimed near the teacher at 1-3 m; side
  plates (0.24 m), about 30-95 pixels across.
"""

from __future__ import annotations

import argparse
import json
import time

import cv2
import numpy as np

from perception.camera import PinholeCamera, look_at_rotation
from perception.layout import default_layout
from perception.markers import DetectorConfig, MarkerDetector
from perception.pose import estimate_robot_pose, robot_to_world, wrap_radians
from perception.synthetic import render_markers, true_corners

METHODS = ("none", "subpix", "contour", "apriltag")


def _overhead_case(rng):
    rotation = look_at_rotation((0.0, 0.0, 4.9), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    camera = PinholeCamera.from_fovy(320, 240, 40.0, rotation, (0.0, 0.0, 4.9))
    pose = (rng.uniform(-1.6, 1.6), rng.uniform(-1.2, 1.2), rng.uniform(-np.pi, np.pi))
    return camera, pose, ("top",)


def _head_case(rng):
    distance = rng.uniform(1.0, 3.0)
    bearing = rng.uniform(-np.pi, np.pi)
    eye = np.array([0.0, 0.0, 1.2])
    target = np.array([distance * np.cos(bearing), distance * np.sin(bearing), 0.0])
    aim = target + np.array([rng.normal(0, 0.1), rng.normal(0, 0.1), 0.72])
    camera = PinholeCamera.from_fovx(320, 240, 45.0, look_at_rotation(eye, aim), eye)
    # The teacher shows the observer its back or a side, +-60 deg around facing away.
    yaw = bearing + rng.uniform(-np.pi / 3, np.pi / 3) + rng.choice([0.0, np.pi / 2, -np.pi / 2])
    return camera, (target[0], target[1], float(wrap_radians(yaw))), ("back", "left", "right")


def _rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    cos = np.clip((np.trace(a.T @ b) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.degrees(np.arccos(cos)))


def measure(viewpoint: str, noise_std: float, samples: int, seed: int) -> list[dict]:
    """Returns one result dict per refinement method for ``samples`` random scenes (same scenes
    each)."""
    layout = default_layout()
    by_id = {p.marker_id: p for p in layout}
    make = {"overhead": _overhead_case, "head": _head_case}[viewpoint]
    rng = np.random.default_rng(seed)
    scenes = []
    while len(scenes) < samples:
        camera, pose, faces = make(rng)
        visible = []
        for p in layout:
            if p.robot != "teacher" or p.face not in faces:
                continue
            rotation_wr, position_wr = robot_to_world(*pose)
            centre = rotation_wr @ p.position_m + position_wr
            normal = rotation_wr @ p.rotation[:, 2]
            facing = np.dot(camera.position_world - centre, normal) / np.linalg.norm(
                camera.position_world - centre
            )
            corners = true_corners(camera, pose, p)
            if facing > 0.2 and np.all(camera.in_image(corners, margin_px=6)):
                visible.append(p.marker_id)
        if not visible:
            continue
        image = render_markers(
            camera, {"teacher": pose}, layout, faces=faces, noise_std=noise_std, rng=rng
        )
        scenes.append((camera, pose, visible, image))

    results = []
    for method in METHODS:
        detector = MarkerDetector(DetectorConfig(corner_refinement=method), layout=layout)
        found = expected = 0
        corner_err, pos_err, rot_err, xy_err, yaw_err, sizes, seconds = [], [], [], [], [], [], 0.0
        for camera, pose, visible, image in scenes:
            start = time.perf_counter()
            detections = detector.detect(image, camera)
            seconds += time.perf_counter() - start
            detections = [d for d in detections if d.marker_id in visible]
            expected += len(visible)
            found += len(detections)
            rotation_wr, position_wr = robot_to_world(*pose)
            for d in detections:
                p = by_id[d.marker_id]
                truth = true_corners(camera, pose, p)
                corner_err.append(float(np.sqrt(np.mean(np.sum((d.corners_px - truth) ** 2, 1)))))
                sizes.append(np.sqrt(d.area_px()))
                centre_cam = camera.world_to_camera(rotation_wr @ p.position_m + position_wr)[0]
                rotation_cm = camera.rotation_camera_from_world @ rotation_wr @ p.rotation
                pos_err.append(100.0 * np.linalg.norm(d.position_camera_m - centre_cam))
                rot_err.append(_rotation_error_deg(d.rotation_camera_from_marker, rotation_cm))
            estimate = estimate_robot_pose(detections, camera, "teacher", layout=layout)
            if estimate is not None:
                xy_err.append(100.0 * np.hypot(estimate.x_m - pose[0], estimate.y_m - pose[1]))
                yaw_err.append(abs(np.degrees(wrap_radians(estimate.yaw_rad - pose[2]))))
        results.append(
            {
                "viewpoint": viewpoint,
                "noise_std": noise_std,
                "method": method,
                "detection_rate": found / max(expected, 1),
                "marker_side_px_median": float(np.median(sizes)) if sizes else None,
                "corner_error_px_median": float(np.median(corner_err)) if corner_err else None,
                "marker_position_error_cm_median": float(np.median(pos_err)) if pos_err else None,
                "marker_rotation_error_deg_median": float(np.median(rot_err)) if rot_err else None,
                "robot_position_error_cm_median": float(np.median(xy_err)) if xy_err else None,
                "robot_position_error_cm_p95": float(np.percentile(xy_err, 95)) if xy_err else None,
                "robot_heading_error_deg_median": float(np.median(yaw_err)) if yaw_err else None,
                "robot_heading_error_deg_p95": float(np.percentile(yaw_err, 95))
                if yaw_err
                else None,
                "detect_ms_mean": 1000.0 * seconds / len(scenes),
            }
        )
    return results


def main(argv=None) -> None:
    """Prints the measurement as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    rows = []
    for viewpoint in ("overhead", "head"):
        for noise in (0.0, 3.0):
            rows.extend(measure(viewpoint, noise, args.samples, args.seed))
    print(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
