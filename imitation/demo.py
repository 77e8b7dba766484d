"""``peoplebot demo``: a video of the teacher looping go-pick-lift, and a JSON summary of the run."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import pathlib
import time

import cv2
import imageio.v2 as imageio
import numpy as np
from tqdm import tqdm

from imitation import perturbations
from imitation.observers import Calibration
from imitation.overlay import annotate, inset
from imitation.performance import dock_pose_at
from imitation.rosbag import EpisodeRecorder
from imitation.videos import BODY_ONLY_NOTE, DOCKING_RANGE_M
from peoplebot_sim import cameras, directives, registration
from peoplebot_sim.rendering import FrameRenderer
from peoplebot_sim.task import TaskConfig, load
from peoplebot_sim.viewpoints import VIEWS, FollowCamera, table_closeup
from perception import camerainfo
from perception.arenafile import write_arena

#: The longest demo, simulated seconds.
MAX_SECONDS = 86_400.0


@dataclasses.dataclass(frozen=True)
class DemoConfig:
    """What the demo renders.

    Attributes:
      seconds: simulated seconds.
      width, height: video size in pixels (up to 1280x960).
      seed: the environment's seed (teacher start and jitter).
      camera: one of ``peoplebot_sim.viewpoints.VIEWS``: 'showcase' (oblique, whole arena),
        'follow' (behind and above the teacher, a table close-up inset while it docks) or
        'overhead' (a real-time recording for ``peoplebot watch``).
      speedup: playback speed; the video runs at ``speedup / control_timestep`` frames/s.
      video: write the mp4 (False: the summary alone, much faster).
      shadows: render shadows in the video.
      mcap: also write the episode as a ROS 2 MCAP log (``<name>.mcap``: the overhead camera's
        frames and camera_info, the robots' poses, the teacher's word and directive).
      preset: a named perturbation level set (``imitation.perturbations.PRESETS``; "" none): the
        room's appearance, and for an overhead recording its frames' image faults and the
        calibration written beside it (the one a student would believe).
    """

    seconds: float = 180.0
    width: int = 640
    height: int = 480
    seed: int = 0
    camera: str = "showcase"
    speedup: float = 2.0
    video: bool = True
    shadows: bool = True
    mcap: bool = False
    preset: str = ""

    def __post_init__(self):
        if self.preset:
            perturbations.preset(self.preset)
        if not (np.isfinite(self.seconds) and 0.1 <= self.seconds <= MAX_SECONDS):
            raise ValueError(
                f"seconds must be at least one control step (0.1 s) and at most {MAX_SECONDS:.0f} "
                f"(a day), got {self.seconds!r}"
            )
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int)
            or not 0 <= self.seed < 2**32
        ):
            raise ValueError(f"seed must be an integer in [0, 2**32), got {self.seed!r}")
        if self.camera not in VIEWS:
            raise ValueError(f"unknown camera {self.camera!r}; allowed: {', '.join(VIEWS)}")
        if not (np.isfinite(self.speedup) and self.speedup > 0):
            raise ValueError(f"speedup must be positive, got {self.speedup!r}")
        for name in ("width", "height"):
            value = getattr(self, name)
            if not isinstance(value, int) or not 16 <= value <= 1280 or value % 2:
                raise ValueError(
                    f"{name} must be an even number of pixels in [16, 1280], got {value!r}"
                )
        if self.height > 960:
            raise ValueError(f"height must be at most 960 pixels, got {self.height}")


def run_demo(config: DemoConfig, out_path, progress: bool = True) -> dict:
    """Runs the teacher for ``config.seconds``, writes the video (``out_path``, .mp4) and the summary
    (same name, .json); returns the summary."""
    out_path = pathlib.Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    faults = perturbations.preset(config.preset) if config.preset else None
    appearance = faults.appearance if faults is not None else TaskConfig().appearance
    env = load(TaskConfig(appearance=appearance), seed=config.seed)
    image_rng = perturbations.rng_for(config.seed, "image")
    timestep = env.reset()
    task = env.task
    control_dt = task.control_timestep
    n_steps = int(round(config.seconds / control_dt))
    action = np.zeros(env.action_spec().shape)
    counts = np.zeros(len(directives.WORDS), int)
    start = time.perf_counter()
    renderer = writer = bag = bag_renderer = closeup_renderer = None
    follow = FollowCamera() if config.camera == "follow" else None
    dock = dock_pose_at("top", task.geometry, task.config.teacher)
    finished = False
    try:
        if config.video:
            renderer = FrameRenderer(
                env.physics, config.width, config.height, shadows=config.shadows, antialias=True
            )
            if follow is not None:
                closeup = table_closeup(task.geometry)
                closeup_renderer = FrameRenderer(
                    env.physics, 2 * (config.width // 6), 2 * (config.height // 6), antialias=True
                )
            writer = imageio.get_writer(
                str(out_path),
                # An overhead recording plays in real time, as a camera records it.
                fps=(1.0 if config.camera == "overhead" else config.speedup) / control_dt,
                codec="libx264",
                quality=7,
                macro_block_size=8,
                ffmpeg_log_level="error",
            )
        if config.mcap:
            bag = EpisodeRecorder(out_path.with_suffix(".mcap"))
            bag_renderer = FrameRenderer(env.physics, 320, 240)
            overhead = cameras.camera_model(env.physics, "overhead", 320, 240)
        camera = "showcase" if config.camera == "showcase" else "overhead"
        recording = config.camera == "overhead"  # frames as the camera sees them, for watch
        truth = []
        steps = tqdm(range(n_steps), desc="demo", unit="step", disable=not progress)
        for i in steps:
            timestep = env.step(action)
            word = directives.WORDS[int(timestep.observation["teacher_word"])]
            directive = directives.DIRECTIVES[int(timestep.observation["teacher_directive"])]
            counts[directives.word_index(word)] += 1
            if recording:
                truth.append(_truth_row(i, i * control_dt, timestep.observation, word, directive))
            if bag is not None:
                observation = timestep.observation
                bag.record(
                    float(env.physics.data.time),
                    cmd_vel=env.physics.named.data.ctrl[["student/forward", "student/turn"]],
                    student_pose=observation["student_pose"],
                    teacher_pose=observation["teacher_pose"],
                    image=bag_renderer.render("overhead"),
                    camera_matrix=overhead.matrix,
                    camera_pose=(overhead.rotation_world_from_camera, overhead.position_world),
                    word=word,
                    directive=directive,
                )
            if writer is not None:
                if follow is not None:
                    pose = timestep.observation["teacher_pose"]
                    frame = renderer.render(follow.update(pose, control_dt))
                    if math.hypot(pose[0] - dock[0], pose[1] - dock[1]) <= DOCKING_RANGE_M:
                        frame = inset(frame, closeup_renderer.render(closeup), "table close-up")
                else:
                    frame = renderer.render(camera)
                if recording:
                    if faults is not None and faults.image.active:
                        frame = faults.image.apply(frame, image_rng)
                    writer.append_data(frame)
                    continue
                caption = (
                    f"t = {env.physics.data.time:6.1f} s   cycles "
                    f"{task.teacher_controller.cycles_completed}"
                )
                note = BODY_ONLY_NOTE if word in ("pick", "lift") else ""
                writer.append_data(
                    annotate(frame, word, directive, caption, title="teacher", note=note)
                )
        finished = True
    finally:
        if writer is not None:
            writer.close()
        if renderer is not None:
            renderer.close()
        if closeup_renderer is not None:
            closeup_renderer.close()
        if bag is not None:
            bag.close(keep=finished)
            bag_renderer.close()
    teacher = task.teacher_controller
    simulated = float(env.physics.data.time)
    summary = {
        "simulated_seconds": simulated,
        "control_steps": n_steps,
        "cycles_completed": teacher.cycles_completed,
        "cycles_per_10_minutes": teacher.cycles_completed * 600.0 / simulated,
        "time_share": {
            w: float(c / max(n_steps, 1)) for w, c in zip(directives.WORDS, counts, strict=True)
        },
        "collisions": task.collisions,
        "watchdog_recoveries": len(teacher.events),
        "watchdog_events": [dataclasses.asdict(e) for e in teacher.events],
        "seed": config.seed,
        "video": str(out_path) if config.video else None,
        "mcap": str(out_path.with_suffix(".mcap")) if config.mcap else None,
        "wall_clock_seconds": time.perf_counter() - start,
        "config": dataclasses.asdict(config),
    }
    if config.camera == "overhead":
        summary["recording"] = _write_recording(env, config, out_path, truth, control_dt)
    out_path.with_suffix(".json").write_text(json.dumps(summary, indent=2))
    env.close()
    return summary


#: The columns of a recording's true poses (one row per frame).
TRUTH_COLUMNS = (
    "frame",
    "time_s",
    "teacher_x_m",
    "teacher_y_m",
    "teacher_yaw_rad",
    "student_x_m",
    "student_y_m",
    "student_yaw_rad",
    "word",
    "directive",
)


def _truth_row(frame: int, time_s: float, observation, word: str, directive: str) -> list:
    teacher, student = observation["teacher_pose"], observation["student_pose"]
    return [frame, f"{time_s:.3f}", *(f"{v:.5f}" for v in (*teacher, *student)), word, directive]


def _write_recording(env, config: DemoConfig, video_path: pathlib.Path, truth, dt) -> dict:
    """Beside an overhead recording, writes what a real one would come with, so that ``peoplebot
    watch`` can take it: the camera's ``camera_info`` YAML, the arena file with the camera's pose
    (under a preset, the calibration its student would believe), the camera's photo of the floor
    markers (``<name>.floor.png``, for ``peoplebot register``) and the true poses per frame
    (``<name>.truth.csv``); returns their paths."""
    camera = cameras.camera_model(env.physics, "overhead", config.width, config.height)
    if config.preset:
        error = perturbations.preset(config.preset).calibration
        world = Calibration(env.physics, config.width, config.height)
        rng = perturbations.rng_for(config.seed, "calibration")
        camera = perturbations.believed_calibration(world, error, rng).overhead
    stem = video_path.with_suffix("")
    paths = {
        "camera_info": stem.with_name(f"{stem.name}.camera_info.yaml"),
        "arena": stem.with_name(f"{stem.name}.arena.toml"),
        "floor_photo": stem.with_name(f"{stem.name}.floor.png"),
        "truth": stem.with_name(f"{stem.name}.truth.csv"),
    }
    photo = registration.registration_frame(config.width, config.height)
    if not cv2.imwrite(str(paths["floor_photo"]), cv2.cvtColor(photo, cv2.COLOR_RGB2BGR)):
        raise ValueError(f"cannot write {paths['floor_photo']}")
    camerainfo.write(paths["camera_info"], camera, camera_name="overhead")
    write_arena(paths["arena"], env.task.geometry, camera)
    with open(paths["truth"], "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(TRUTH_COLUMNS)
        writer.writerows(truth)
    return {**{k: str(v) for k, v in paths.items()}, "frame_seconds": dt}
