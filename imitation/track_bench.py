"""``peoplebot track-bench``: how well the student's vision recovers poses from rendered frames.

The teacher is put at random poses (anywhere, near walls, in corners, docked at the table) with the
student in view; each frame is rendered by MuJoCo and tracked by ``perception`` alone, and the
estimate is compared with the simulator's pose. Two viewpoints:

- overhead: the arena's overhead camera; both robots' top markers;
- head: the student's pan-tilt camera aimed at the teacher (1 to 3 m away), seeing its side, back or
  front markers; the camera's extrinsics come from the student's own pose and head angles through
  ``perception.pantilt.head_camera``, as they would on the real robot.

Over time (``sequence``): tracking's speed and accuracy while the teacher loops, the student
standing; and (``self_localisation``) the student's own pose while it drives about the arena,
by odometry from its known start against the wall landmarks from an unknown one.
"""

from __future__ import annotations

import json
import math
import pathlib
import time

import mujoco
import numpy as np
from dm_control import mjcf
from tqdm import tqdm

from imitation.observers import Calibration, StudentVision
from imitation.performance import make_action
from peoplebot_sim import cameras
from peoplebot_sim.rendering import FrameRenderer
from peoplebot_sim.task import ImitationTask, TaskConfig, load
from perception import layout as marker_layout
from perception.markers import DetectorConfig
from perception.pantilt import PanTiltLimits, aim_at, head_camera
from perception.pipeline import Tracker
from perception.pose import wrap_radians
from perception.wallframe import wrap_degrees

CATEGORIES = ("anywhere", "near_wall", "corner", "docked")
#: The bench's parts: poses from single frames, tracking over time with the student standing,
#: self-localisation while it drives.
PARTS = ("viewpoints", "sequence", "self_localisation")
#: The sequence part's runs: (viewpoint, how the student knows its own pose; the row's name).
SEQUENCE_RUNS = (
    ("overhead", "odometry", "overhead"),
    ("head", "odometry", "head"),
    ("head", "landmarks", "head_landmarks"),
)


def _teacher_pose(task: ImitationTask, rng, category: str) -> tuple:
    h = task.geometry.half_side_m
    if category == "anywhere":
        return task.random_free_pose(rng, margin_m=0.45)
    if category == "near_wall":
        while True:
            along = rng.uniform(-h + 0.5, h - 0.5)
            depth = h - rng.uniform(0.45, 0.7)
            wall = rng.integers(4)
            x, y = [(along, depth), (depth, along), (along, -depth), (-depth, along)][wall]
            if task.geometry.clear_of_table(x, y, 0.45):
                return x, y, rng.uniform(-math.pi, math.pi)
    if category == "corner":
        sx, sy = rng.choice([-1, 1], size=2)
        return (
            sx * (h - rng.uniform(0.45, 0.8)),
            sy * (h - rng.uniform(0.45, 0.8)),
            rng.uniform(-math.pi, math.pi),
        )
    dock = task.teacher_controller.dock_pose
    return (
        dock[0] + rng.normal(0, 0.03),
        dock[1] + rng.normal(0, 0.02),
        dock[2] + math.radians(rng.normal(0, 3)),
    )


def _overhead_student(task, rng, teacher) -> tuple:
    for _ in range(1000):
        pose = task.random_free_pose(rng, margin_m=0.45)
        if math.hypot(pose[0] - teacher[0], pose[1] - teacher[1]) > 0.9:
            return pose
    raise RuntimeError("no free student pose")


def _head_student(task, rng, teacher) -> tuple | None:
    h = task.geometry.half_side_m - 0.45
    for _ in range(200):
        distance = rng.uniform(1.0, 3.0)
        bearing = rng.uniform(-math.pi, math.pi)
        x = teacher[0] + distance * math.cos(bearing)
        y = teacher[1] + distance * math.sin(bearing)
        if abs(x) > h or abs(y) > h or not task.geometry.clear_of_table(x, y, 0.45):
            continue
        facing = math.atan2(teacher[1] - y, teacher[0] - x) + math.radians(rng.uniform(-40, 40))
        return x, y, facing
    return None


def run(
    n_samples: int = 200,
    width: int = 320,
    height: int = 240,
    seed: int = 0,
    out_path=None,
    progress: bool = True,
    detector_config: DetectorConfig | None = None,
    parts: tuple[str, ...] = PARTS,
) -> dict:
    """Runs the bench's ``parts`` (of ``PARTS``); returns (and writes, if ``out_path``) its
    figures as a dict."""
    if n_samples <= 0:
        raise ValueError(f"n_samples must be positive, got {n_samples}")
    unknown = [part for part in parts if part not in PARTS]
    if unknown or not parts:
        raise ValueError(f"unknown bench parts {unknown or parts!r}; allowed: {', '.join(PARTS)}")
    report = {"width": width, "height": height, "samples": n_samples, "seed": seed}
    if "viewpoints" in parts:
        report["viewpoints"] = _viewpoints(
            n_samples, width, height, seed, progress, detector_config
        )
    if "sequence" in parts:
        report["sequence"] = sequence_timing(width, height, seed, n_steps=max(100, n_samples))
    if "self_localisation" in parts:
        report["self_localisation"] = self_localisation_run(
            width, height, seed, n_steps=max(300, 3 * n_samples)
        )
    if out_path is not None:
        out_path = pathlib.Path(out_path)
        out_path.parent.mkdir(parents=True, exist_ok=True)
        out_path.write_text(json.dumps(report, indent=2))
    return report


def _viewpoints(n_samples, width, height, seed, progress, detector_config) -> dict:
    """The single-frame part: per viewpoint, the tracked robots' errors and detection rates."""
    rng = np.random.default_rng(seed)
    task = ImitationTask(TaskConfig(width=width, height=height))
    physics = mjcf.Physics.from_mjcf_model(task.root_entity.mjcf_model)
    m, d = physics.model.ptr, physics.data.ptr
    pan_qpos = physics.model.jnt_qposadr[physics.model.name2id("student/head_pan", "joint")]
    tilt_qpos = physics.model.jnt_qposadr[physics.model.name2id("student/head_tilt", "joint")]
    limits = PanTiltLimits()
    results = {}
    with FrameRenderer(physics, width, height) as renderer:
        for view in ("overhead", "head"):
            tracker = Tracker(
                detector_config=detector_config or DetectorConfig(),
                robots=("teacher", "student") if view == "overhead" else ("teacher",),
            )
            fixed = cameras.camera_model(physics, "overhead", width, height)
            intrinsics = cameras.camera_model(physics, "student/head_camera", width, height)
            errors = {"teacher": [], "student": []}
            seen = {"teacher": 0, "student": 0}
            total = 0
            render_s = track_s = 0.0
            per_category = {c: {"n": 0, "seen": 0} for c in CATEGORIES}
            iterator = range(n_samples)
            if progress:
                iterator = tqdm(iterator, desc=f"track-bench {view}", unit="frame")
            for i in iterator:
                category = CATEGORIES[i % len(CATEGORIES)]
                teacher = _teacher_pose(task, rng, category)
                if view == "overhead":
                    student = _overhead_student(task, rng, teacher)
                    pan = tilt = 0.0
                else:
                    student = _head_student(task, rng, teacher)
                    if student is None:
                        continue
                    target = (teacher[0], teacher[1], marker_layout.SIDE_MARKER_HEIGHT_M)
                    pan, tilt = aim_at(student, target)
                    pan = float(np.clip(pan, limits.pan_min_deg, limits.pan_max_deg))
                    tilt = float(np.clip(tilt, limits.tilt_min_deg, limits.tilt_max_deg))
                task.teacher.set_planar_pose(physics, *teacher)
                task.student.set_planar_pose(physics, *student)
                d.qpos[pan_qpos] = math.radians(pan)
                d.qpos[tilt_qpos] = math.radians(tilt)
                mujoco.mj_forward(m, d)
                t0 = time.perf_counter()
                image = renderer.render("overhead" if view == "overhead" else "student/head_camera")
                t1 = time.perf_counter()
                # The head camera's extrinsics come from the student's pose and head angles each
                # frame (perception's work, timed); the intrinsics and the fixed overhead camera are
                # calibrated once, before the loop.
                camera = (
                    fixed if view == "overhead" else head_camera(intrinsics, student, pan, tilt)
                )
                frame = tracker.estimate(image, camera)
                t2 = time.perf_counter()
                render_s += t1 - t0
                track_s += t2 - t1
                total += 1
                per_category[category]["n"] += 1
                truths = {"teacher": teacher, "student": student}
                for robot in tracker.robots:
                    estimate = frame.poses.get(robot)
                    if estimate is None:
                        continue
                    seen[robot] += 1
                    if robot == "teacher":
                        per_category[category]["seen"] += 1
                    truth = truths[robot]
                    errors[robot].append(
                        (
                            100.0 * math.hypot(estimate.x_m - truth[0], estimate.y_m - truth[1]),
                            abs(float(wrap_degrees(math.degrees(estimate.yaw_rad - truth[2])))),
                        )
                    )
            figures = {}
            for robot in tracker.robots:
                e = np.array(errors[robot]).reshape(-1, 2)
                figures[robot] = {
                    "frames": total,
                    "detection_rate": seen[robot] / max(total, 1),
                    "position_error_cm": _stats(e[:, 0]),
                    "heading_error_deg": _stats(e[:, 1]),
                }
            results[view] = {
                "robots": figures,
                "teacher_detection_by_category": {
                    c: v["seen"] / v["n"] if v["n"] else None for c, v in per_category.items()
                },
                "render_only_fps": total / render_s if render_s else None,
                "render_and_track_fps": total / (render_s + track_s) if render_s else None,
                "tracking_share_of_render_time": track_s / render_s if render_s else None,
            }
    return results


def _stats(values: np.ndarray) -> dict:
    if values.size == 0:
        return {"median": None, "p95": None}
    return {"median": float(np.median(values)), "p95": float(np.percentile(values, 95))}


def sequence_timing(
    width: int = 320,
    height: int = 240,
    seed: int = 0,
    n_steps: int = 300,
    runs: tuple = SEQUENCE_RUNS,
) -> dict:
    """Times tracking over time as the experiments use it, per viewpoint: the environment's camera
    observable renders each control step while the teacher loops, and the student's vision
    (:class:`~imitation.observers.StudentVision`, ``Tracker.update`` searching each frame)
    follows the robots - both from the overhead camera; the teacher from the head camera, with the
    student's own pose from odometry (``head``, from its known start) or from the wall landmarks
    (``head_landmarks``, from an unknown start, the head shared between the teacher and the
    landmarks). Returns per viewpoint the steps/s without the camera, with it, and with tracking,
    the render and tracking times per frame, tracking's share of the render time and the tracked
    teacher's position and heading errors; the head viewpoints also the student's own-pose errors
    (from the first step it has a pose) and ``head_landmarks`` the steps to its first pose and the
    glances. With both head rows, ``glance_cost`` puts side by side what sharing the head with
    the landmarks costs the teacher's tracking. ``runs``: which of ``SEQUENCE_RUNS``.
    Tracking is timed around each vision update; rendering is the environment step's time with
    the camera less its time without."""

    def run_loop(view, track, self_localisation="odometry"):
        env = load(seed=seed, cameras=(view,) if view else (), width=width, height=height)
        timestep = env.reset()
        vision = None
        if track:
            vision = StudentVision(
                view,
                Calibration(env.physics, width, height),
                self_localisation=self_localisation,
            )
            vision.reset(
                timestep.observation["student_pose"], timestep.observation["student_wheel_angles"]
            )
        spec, dt = env.action_spec(), env.task.control_timestep
        errors, own_errors, first_pose = [], [], None
        step_s = track_s = 0.0
        for i in range(n_steps):
            if vision is not None:
                t0 = time.perf_counter()
                poses = vision.update(timestep.observation, i * dt, dt)
                track_s += time.perf_counter() - t0
                pose, own = poses["teacher"], poses["student"]
                if pose is not None:
                    truth = timestep.observation["teacher_pose"]
                    errors.append(
                        (
                            100 * math.hypot(pose[0] - truth[0], pose[1] - truth[1]),
                            abs(math.degrees(float(wrap_radians(pose[2] - truth[2])))),
                        )
                    )
                if own is not None:
                    first_pose = i if first_pose is None else first_pose
                    truth = timestep.observation["student_pose"]
                    own_errors.append(
                        (
                            100 * math.hypot(own[0] - truth[0], own[1] - truth[1]),
                            abs(math.degrees(float(wrap_radians(own[2] - truth[2])))),
                        )
                    )
            head = (0.0, 0.0) if vision is None else vision.head_command
            action = make_action(spec, (0.0, 0.0), head)
            t0 = time.perf_counter()
            timestep = env.step(action)
            step_s += time.perf_counter() - t0
        env.close()
        glances = getattr(getattr(vision, "gaze", None), "glances_", None)
        return step_s, track_s, errors, np.asarray(own_errors).reshape(-1, 2), first_pose, glances

    physics_s = run_loop(None, False)[0]
    out = {"steps": n_steps}
    for view, method, name in runs:
        render_s, track_s, errors, own, first_pose, glances = run_loop(view, True, method)
        errors = np.asarray(errors).reshape(-1, 2)
        render_per_frame = (render_s - physics_s) / n_steps
        track_per_frame = track_s / n_steps
        row = {
            "steps_per_s_without_camera": n_steps / physics_s,
            "steps_per_s_with_camera": n_steps / render_s,
            "steps_per_s_with_camera_and_tracking": n_steps / (render_s + track_s),
            "render_ms_per_frame": 1000 * render_per_frame,
            "tracking_ms_per_frame": 1000 * track_per_frame,
            "tracking_share_of_render_time": track_per_frame / render_per_frame,
            "teacher_seen_fraction": len(errors) / n_steps,
            "tracked_teacher_position_error_cm": _stats(errors[:, 0]),
            "tracked_teacher_heading_error_deg": _stats(errors[:, 1]),
        }
        if view == "head":
            row["own_position_error_cm"] = _stats(own[:, 0])
            row["own_heading_error_deg"] = _stats(own[:, 1])
        if method == "landmarks":
            row["steps_to_first_own_pose"] = first_pose
            row["glances"] = glances
        out[name] = row
    if "head" in out and "head_landmarks" in out:
        rows = (("odometry", "head"), ("landmarks", "head_landmarks"))
        out["glance_cost"] = {
            key: {method: out[row][key] for method, row in rows}
            for key in (
                "teacher_seen_fraction",
                "tracked_teacher_position_error_cm",
                "tracked_teacher_heading_error_deg",
            )
        }
        out["glance_cost"]["glances"] = out["head_landmarks"]["glances"]
    return out


def _wander(observation, rng, state: dict) -> tuple[float, float]:
    """Returns the bench driver's wheel command ``(m/s, rad/s)`` from the true poses: forward with
    a little steering; near a wall, the table or the teacher it turns in place for 1-3 s, except
    that one time in six at a wall it drives on into it for 2 s (the wheels slip)."""
    x, y, yaw = observation["student_pose"]
    teacher = np.asarray(observation["teacher_pose"][:2])
    if state["push"] > 0:
        state["push"] -= 1
        return 0.35, 0.0
    if state["turn"] > 0:
        state["turn"] -= 1
        return 0.0, math.radians(60.0)
    ahead = np.array([x + 0.6 * math.cos(yaw), y + 0.6 * math.sin(yaw)])
    if np.hypot(*(ahead - teacher)) < 0.9 or np.hypot(x - teacher[0], y - teacher[1]) < 0.8:
        state["turn"] = int(rng.integers(10, 30))
        return 0.0, 0.0
    if np.max(np.abs(ahead)) > 1.75 or (abs(ahead[0]) < 0.7 and ahead[1] > 1.35):
        if rng.random() < 1.0 / 6.0:
            state["push"] = 20
        else:
            state["turn"] = int(rng.integers(10, 30))
        return 0.0, 0.0
    return 0.35, float(rng.normal(0.0, 0.2))


def self_localisation_run(
    width: int = 320, height: int = 240, seed: int = 0, n_steps: int = 600
) -> dict:
    """The student's own pose while it drives (``_wander``, seeded, the same path for both) and
    watches the looping teacher through its head camera, per method: 'odometry' (from the known
    start) and 'landmarks' (from an unknown start). Returns per method the own position and
    heading errors (median, p95; from the first step with a pose), the steps to that pose, the
    teacher's seen fraction, the glances at landmarks and the vision time per step (ms)."""
    out = {"steps": n_steps}
    for method in ("odometry", "landmarks"):
        env = load(seed=seed, cameras=("head",), width=width, height=height)
        timestep = env.reset()
        spec, dt = env.action_spec(), env.task.control_timestep
        vision = StudentVision(
            "head", Calibration(env.physics, width, height), self_localisation=method
        )
        vision.reset(
            timestep.observation["student_pose"], timestep.observation["student_wheel_angles"]
        )
        rng, state = np.random.default_rng(seed), {"push": 0, "turn": 0}
        own, seen, first, vision_s = [], 0, None, 0.0
        for i in range(n_steps):
            t0 = time.perf_counter()
            poses = vision.update(timestep.observation, i * dt, dt)
            vision_s += time.perf_counter() - t0
            seen += poses["teacher"] is not None
            if poses["student"] is not None:
                first = i if first is None else first
                e = poses["student"] - timestep.observation["student_pose"]
                own.append((100 * math.hypot(e[0], e[1]), abs(math.degrees(wrap_radians(e[2])))))
            command = _wander(timestep.observation, rng, state)
            timestep = env.step(make_action(spec, command, vision.head_command))
        env.close()
        own = np.asarray(own).reshape(-1, 2)
        gaze = getattr(vision, "gaze", None)
        out[method] = {
            "own_position_error_cm": _stats(own[:, 0]),
            "own_heading_error_deg": _stats(own[:, 1]),
            "steps_to_first_own_pose": first,
            "teacher_seen_fraction": seen / n_steps,
            "glances": None if gaze is None else gaze.glances_,
            "vision_ms_per_step": 1000 * vision_s / n_steps,
        }
    return out
