"""``peoplebot watch``: the student's perception and a trained network over a recorded video, as the
student would run live on a real robot's camera.

For every frame: both robots' tracked poses (``perception.Tracker`` on the calibrated camera), the
teacher's wall-frame pose in the recorded room (an arena file), the directive inferred from the
teacher's motion, and, with a network, the word recognised one step at a time and over time.
Writes ``poses.csv``, ``recognition.csv``, ``summary.json`` and ``watched.mp4`` (the frames with
the robots' poses and the word drawn).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import pathlib

import cv2
import imageio.v2 as imageio
import numpy as np

from associator import encoding, persistence
from associator.hierarchy import HierarchicalAssociator
from imitation import storage
from imitation.learning import inferred_directives
from imitation.overlay import annotate
from imitation.recognition import recognise_stream
from imitation.rosbag import EpisodeRecorder
from imitation.streams import TeacherStream
from perception import camerainfo
from perception.arenafile import ArenaSetup, read_arena
from perception.camera import PinholeCamera
from perception.markers import MarkerDetector
from perception.pipeline import Tracker
from perception.wallframe import WALL_NAMES, world_to_wall_batch

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")


@dataclasses.dataclass(frozen=True)
class Watched:
    """What the student saw in a recording, per frame: times (s), each robot's tracked world pose
    ``(x m, y m, yaw rad)`` (NaN where unknown) and track status, and the inferred directives."""

    time_s: np.ndarray
    poses: dict
    status: dict
    directive: np.ndarray


def frames_of(source) -> tuple[list, float | None]:
    """Returns the RGB frames of a video file or a folder of images (sorted by name), and the
    video's frames per second (None for images)."""
    source = pathlib.Path(source)
    if source.is_dir():
        paths = sorted(p for p in source.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not paths:
            raise ValueError(f"{source} holds no images ({', '.join(IMAGE_SUFFIXES)})")
        frames = []
        for path in paths:
            image = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if image is None:
                raise ValueError(f"cannot read image {path}")
            frames.append(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
        return frames, None
    if not source.is_file():
        raise ValueError(f"no video or image folder at {source}")
    try:
        with imageio.get_reader(str(source)) as reader:
            fps = reader.get_meta_data().get("fps")
            frames = [np.asarray(frame)[..., :3] for frame in reader]
    except (OSError, RuntimeError, ValueError) as error:
        raise ValueError(f"cannot read video {source}: {error}") from None
    return frames, fps


def recording_camera(intrinsics: PinholeCamera, arena_setup: ArenaSetup) -> PinholeCamera:
    """Returns the fixed recording camera: ``intrinsics`` (a camera_info's), pose from the arena."""
    if not arena_setup.has_camera:
        raise ValueError(
            "the arena file gives no [camera] pose (position_m, rotation_world_from_camera): "
            "watch needs where the fixed camera hangs"
        )
    return intrinsics.with_pose(arena_setup.camera_rotation, arena_setup.camera_position_m)


def track(frames, camera: PinholeCamera, arena, frame_seconds: float) -> Watched:
    """Tracks both robots through the frames (one ``Tracker``, as live)."""
    for i, frame in enumerate(frames):
        if (frame.shape[1], frame.shape[0]) != camera.image_size:
            raise ValueError(
                f"frame {i} is {frame.shape[1]}x{frame.shape[0]} pixels, the camera_info "
                f"{camera.image_size[0]}x{camera.image_size[1]}"
            )
    tracker = Tracker(arena=arena)
    n = len(frames)
    poses = {robot: np.full((n, 3), np.nan) for robot in tracker.robots}
    status = {robot: [] for robot in tracker.robots}
    times = np.arange(n) * frame_seconds
    for i, frame in enumerate(frames):
        for robot, tracked in tracker.update(frame, camera, float(times[i])).items():
            status[robot].append(tracked.track.status)
            if tracked.track.pose is not None:
                poses[robot][i] = tracked.track.pose
    directive = inferred_directives(poses["teacher"], frame_seconds)
    return Watched(times, poses, {r: np.asarray(s) for r, s in status.items()}, directive)


def load_networks(source) -> dict:
    """Returns the networks to recognise with by name ('paper', 'hierarchical'): a run folder's
    ``network.npz`` and ``hierarchical.npz``, or one ``.npz``."""
    source = pathlib.Path(source)
    if source.is_dir():
        out = {"paper": persistence.load(source / "network.npz")}
        if (source / "hierarchical.npz").exists():
            out["hierarchical"] = persistence.load(source / "hierarchical.npz")
        return out
    model = persistence.load(source)
    return {"hierarchical" if isinstance(model, HierarchicalAssociator) else "paper": model}


def recognise(watched: Watched, networks: dict, arena, frame_seconds: float) -> dict:
    """Returns per read-out the recognised word per frame (None where the teacher was not
    known): each network one step at a time, and the hierarchical one over time."""
    pose = watched.poses["teacher"]
    seen = np.all(np.isfinite(pose), axis=1)
    wall = np.full_like(pose, np.nan)
    if seen.any():
        x, y, phi, _ = world_to_wall_batch(*pose[seen].T, arena)
        wall[seen] = np.column_stack([x, y, phi])
    n = len(pose)
    stream = TeacherStream(
        pose.astype(np.float32),
        wall.astype(np.float32),
        np.zeros(n, np.int8),  # the true word: unknown, and unused by recognition
        watched.directive.astype(np.int8),
        np.concatenate([[False], watched.directive[1:] != watched.directive[:-1]]),
    )
    encoder = encoding.VisionEncoder(half_side_m=arena.half_side_m)
    readouts = {}
    for name, model in networks.items():
        kinds = [(name, False)] + ([(f"{name}_over_time", True)] if name == "hierarchical" else [])
        for label, over_time in kinds:
            if not seen.any():
                readouts[label] = [None] * n
                continue
            index = recognise_stream(
                model, stream, encoder, "teacher", frame_seconds, over_time=over_time, seen=seen
            )
            words = model.vocabulary
            readouts[label] = [words[i] if i >= 0 else None for i in index]
    return readouts


def run(
    video,
    camera_info,
    arena_file,
    out,
    network=None,
    frame_seconds: float | None = None,
    mcap: bool = False,
) -> dict:
    """Watches a recording (see the module notes); writes into ``out`` and returns the summary."""
    out = pathlib.Path(out)
    setup = read_arena(arena_file)
    camera = recording_camera(camerainfo.read(camera_info).camera, setup)
    networks = load_networks(network) if network is not None else {}
    frames, fps = frames_of(video)
    if frame_seconds is None:
        frame_seconds = 1.0 / fps if fps else 0.1
    if not (math.isfinite(frame_seconds) and frame_seconds > 0):
        raise ValueError(f"--frame-seconds must be a positive number, got {frame_seconds!r}")
    watched = track(frames, camera, setup.arena, frame_seconds)
    readouts = recognise(watched, networks, setup.arena, frame_seconds) if networks else {}
    out.mkdir(parents=True, exist_ok=True)
    storage.write_text(out / "poses.csv", _poses_csv(watched, setup.arena))
    storage.write_text(out / "recognition.csv", _recognition_csv(watched, readouts))
    _write_video(out / "watched.mp4", frames, watched, readouts, camera, frame_seconds)
    if mcap:
        _write_log(out / "watched.mcap", frames, watched, readouts, camera)
    seen = {r: float(np.mean(np.all(np.isfinite(p), axis=1))) for r, p in watched.poses.items()}
    summary = {
        "video": str(video),
        "camera_info": str(camera_info),
        "arena": dataclasses.asdict(setup.arena),
        "network": None if network is None else str(network),
        "frames": len(frames),
        "frame_seconds": frame_seconds,
        "seen_fraction": seen,
        "word_shares": {
            label: {
                w: float(np.mean([v == w for v in words]))
                for w in sorted({v for v in words if v is not None})
            }
            for label, words in readouts.items()
        },
        "files": ["poses.csv", "recognition.csv", "watched.mp4", "summary.json"]
        + (["watched.mcap"] if mcap else []),
    }
    storage.write_json(out / "summary.json", summary)
    return summary


def _poses_csv(watched: Watched, arena) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    header = ["frame", "time_s"]
    for robot in watched.poses:
        header += [f"{robot}_status", f"{robot}_x_m", f"{robot}_y_m", f"{robot}_yaw_rad"]
    header += ["teacher_wall", "teacher_wall_x_m", "teacher_wall_y_m", "teacher_wall_phi_deg"]
    writer.writerow(header)
    teacher = watched.poses["teacher"]
    seen = np.all(np.isfinite(teacher), axis=1)
    wall = np.full((len(teacher), 4), np.nan)
    if seen.any():
        x, y, phi, w = world_to_wall_batch(*teacher[seen].T, arena)
        wall[seen] = np.column_stack([x, y, phi, w])
    for i, time_s in enumerate(watched.time_s):
        row = [i, f"{time_s:.3f}"]
        for robot, poses in watched.poses.items():
            row += [watched.status[robot][i], *(_num(v) for v in poses[i])]
        row += [WALL_NAMES[int(wall[i, 3])] if seen[i] else "", *(_num(v) for v in wall[i, :3])]
        writer.writerow(row)
    return buffer.getvalue()


def _recognition_csv(watched: Watched, readouts: dict) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["frame", "time_s", "directive", *(f"word_{k}" for k in readouts)])
    for i, time_s in enumerate(watched.time_s):
        seen = bool(np.all(np.isfinite(watched.poses["teacher"][i])))
        directive = encoding.DIRECTIVES[int(watched.directive[i])] if seen else ""
        words = [readouts[k][i] or "" for k in readouts]
        writer.writerow([i, f"{time_s:.3f}", directive, *words])
    return buffer.getvalue()


def _num(value) -> str:
    return "" if not np.isfinite(value) else f"{float(value):.4f}"


def _write_video(path, frames, watched, readouts, camera, frame_seconds) -> None:
    """The frames with each known robot's position and heading drawn, and the word."""
    tmp = storage.temporary_name(path)
    label = next((k for k in ("hierarchical_over_time", "paper") if k in readouts), None)
    colours = {"teacher": (230, 140, 30), "student": (60, 170, 75)}
    with imageio.get_writer(
        str(tmp),
        fps=max(1.0, 1.0 / frame_seconds),
        codec="libx264",
        quality=7,
        macro_block_size=8,
        ffmpeg_log_level="error",
    ) as writer:
        for i, frame in enumerate(frames):
            image = np.ascontiguousarray(frame).copy()
            for robot, poses in watched.poses.items():
                x, y, yaw = poses[i]
                if not np.isfinite(x):
                    continue
                points = np.array(
                    [[x, y, 0.0], [x + 0.4 * math.cos(yaw), y + 0.4 * math.sin(yaw), 0.0]]
                )
                (u0, v0), (u1, v1) = camera.project(points)
                cv2.circle(image, (int(u0), int(v0)), 6, colours[robot], 2, cv2.LINE_AA)
                cv2.arrowedLine(
                    image,
                    (int(u0), int(v0)),
                    (int(u1), int(v1)),
                    colours[robot],
                    2,
                    cv2.LINE_AA,
                    tipLength=0.3,
                )
            seen = bool(np.all(np.isfinite(watched.poses["teacher"][i])))
            directive = encoding.DIRECTIVES[int(watched.directive[i])] if seen else None
            word = readouts[label][i] if label else None
            caption = f"t = {watched.time_s[i]:5.1f} s"
            writer.append_data(annotate(image, word, directive, caption))
    storage.commit(tmp, path)


def _write_log(path, frames, watched, readouts, camera) -> None:
    """What the student saw, as a ROS 2 MCAP log: the frames with the camera's calibration and
    pose, the detected markers' poses, the robots' tracked poses, the inferred directive and the
    recognised word."""
    label = next((k for k in ("hierarchical_over_time", "paper") if k in readouts), None)
    detector = MarkerDetector()
    with EpisodeRecorder(path) as bag:
        for i, frame in enumerate(frames):
            known = {
                r: p[i] if np.all(np.isfinite(p[i])) else None for r, p in watched.poses.items()
            }
            markers = [
                (d.rotation_camera_from_marker, d.position_camera_m)
                for d in detector.detect(frame, camera)
            ]
            bag.record(
                float(watched.time_s[i]),
                image=frame,
                marker_poses=markers,
                camera_matrix=camera.matrix,
                camera_pose=(camera.rotation_world_from_camera, camera.position_world),
                estimated_poses=known,
                word=readouts[label][i] if label else None,
                directive=encoding.DIRECTIVES[int(watched.directive[i])]
                if known["teacher"] is not None
                else None,
            )
