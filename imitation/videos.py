"""The video stage of ``peoplebot reproduce``: the teacher and every student performing every word
from the paper's Fig. 4 start, filmed by a camera following the robot from behind and above (with a
close-up of the table while it docks), and per word a side-by-side video of them all on one time
base. Each video runs the whole trial at 1 frame per control step, played at ``SPEEDUP`` times real
time, then holds its last frame for ``HOLD_S`` with the verdict and its reason. In the head mode a
student's own-pose estimate is drawn on the floor beside the true robot, with the landmark
filter's 95% position ellipse and heading wedge (``overlay.own_pose_estimate``)."""

from __future__ import annotations

import dataclasses
import pathlib

import imageio.v2 as imageio
import mujoco
import numpy as np

from associator import persistence
from imitation import performance, storage, trials
from imitation.config import RunConfig
from imitation.observers import Calibration
from imitation.overlay import annotate, inset, own_pose_estimate, verdict
from imitation.parallel import run_parallel
from imitation.rosbag import EpisodeRecorder
from peoplebot_sim.cameras import camera_model, free_camera_model
from peoplebot_sim.rendering import FrameRenderer
from peoplebot_sim.viewpoints import FollowCamera, table_closeup

#: Simulated seconds the last frame is held with the verdict.
HOLD_S = 4.0
#: Playback speed: simulated seconds per second of video (as ``peoplebot demo``'s default).
SPEEDUP = 2.0
#: The close-up of the table is inset while the robot's centre is this near the dock (metres).
DOCKING_RANGE_M = 1.2
#: Shown during 'pick' and 'lift' (the paper: "All behaviours involve only body movements but no
#: actual gripper actions").
BODY_ONLY_NOTE = "the paper's 'pick' and 'lift': body movement only, no gripper action"
#: Each policy's caption.
TITLES = {
    "teacher": "teacher (reference)",
    "student": "student: paper's network",
    "student_hierarchical": "student: hierarchical",
}
WORDS = ("go", "pick", "lift")


def video_policies(config: RunConfig) -> tuple[str, ...]:
    """Returns the policies filmed: the teacher, then the run's students."""
    return ("teacher", *(p for p in trials.policies_of(config) if p != "teacher"))


def video_name(policy: str, word: str) -> str:
    """Returns the file name of ``policy``'s video of ``word`` (in the run folder)."""
    return f"{policy}_{word}.mp4"


def side_by_side_name(word: str) -> str:
    """Returns the file name of the side-by-side video of ``word``."""
    return f"side_by_side_{word}.mp4"


def frames_per_video(config: RunConfig) -> int:
    """Returns the frame count of every video: one per control step of a trial, then the held
    verdict."""
    dt = config.task.control_timestep
    return int(round(config.performance.trial_seconds / dt)) + int(round(HOLD_S / dt))


def fps(config: RunConfig) -> float:
    """Returns the videos' frame rate (frames/s): one frame per control step, ``SPEEDUP`` times
    real time."""
    return SPEEDUP / config.task.control_timestep


def _writer(path, config: RunConfig):
    return imageio.get_writer(
        str(path),
        fps=fps(config),
        codec="libx264",
        quality=7,
        macro_block_size=8,
        ffmpeg_log_level="error",
    )


class _Film:
    """Writes one annotated frame per control step of one policy's trial, then its verdict."""

    def __init__(self, env, path, policy: str, word: str, config: RunConfig, progress, frames):
        width, height = config.videos.width, config.videos.height
        self.path, self.tmp = pathlib.Path(path), storage.temporary_name(path)
        self.policy, self.word, self.config = policy, word, config
        self.progress_file, self.frames, self.steps = progress, frames, 0
        self.renderer = FrameRenderer(
            env.physics, width, height, shadows=True, antialias=True, shadow_size=1024
        )
        inset_w, inset_h = 2 * (width // 6), 2 * (height // 6)
        self.inset_renderer = FrameRenderer(env.physics, inset_w, inset_h, antialias=True)
        self.follow, self.closeup = FollowCamera(), table_closeup(env.task.geometry)
        self.dock = performance.dock_pose_at("top", env.task.geometry, config.teacher)
        self.bag = self.bag_renderer = None
        if config.videos.mcap:
            self.bag = EpisodeRecorder(self.path.with_suffix(".mcap"))
            self.bag_renderer = FrameRenderer(env.physics, width, height)
            self.camera = camera_model(env.physics, "showcase", width, height)
        self.writer = _writer(self.tmp, config)
        self.last = None

    def __call__(self, env, agent) -> None:
        self.steps += 1
        dt = env.task.control_timestep
        time_s = self.steps * dt
        pose = env.task.student.planar_pose(env.physics)
        view = self.follow.update(pose, dt)
        image = self.renderer.render(view)
        if self.config.vision.mode == "head" and self.policy != "teacher":
            image = own_pose_estimate(
                image,
                free_camera_model(env.physics, view, image.shape[1], image.shape[0]),
                getattr(agent, "own_pose", None),
                getattr(agent, "own_covariance", None),
            )
        if np.hypot(pose[0] - self.dock[0], pose[1] - self.dock[1]) <= DOCKING_RANGE_M:
            close = self.inset_renderer.render(self.closeup)
            image = inset(image, close, "table close-up")
        if self.bag is not None:
            self._log(env, agent, time_s)
        motor = getattr(agent, "motor", None)
        self.last = annotate(
            image,
            self.word,
            agent.directive or "standing still",
            f"t = {time_s:4.1f} s",
            np.zeros(4) if motor is None else motor,
            title=f"{TITLES[self.policy]} told '{self.word}'",
            note=BODY_ONLY_NOTE if self.word in ("pick", "lift") else "",
        )
        self._append(self.last)

    def _append(self, frame) -> None:
        self.writer.append_data(frame)
        self.frames += 1
        if self.frames % 20 == 0:
            pathlib.Path(self.progress_file).write_text(str(self.frames))

    def finish(self, result) -> None:
        """Holds the last frame for ``HOLD_S`` with the verdict and its reason."""
        held = verdict(self.last, result.success, result.reason)
        for _ in range(int(round(HOLD_S / self.config.task.control_timestep))):
            self._append(held)

    def _log(self, env, agent, time_s: float) -> None:
        """Records the step in the episode's MCAP log: the wheel command, the robot's true and
        estimated pose and velocity, the showcase camera's frame, the word and directive."""
        physics, student = env.physics, env.task.student
        velocity = np.zeros(6)  # body frame: angular (x, y, z), then linear (x, y, z)
        mujoco.mj_objectVelocity(
            physics.model.ptr,
            physics.data.ptr,
            mujoco.mjtObj.mjOBJ_BODY,
            student.body_id(physics),
            velocity,
            1,
        )
        self.bag.record(
            time_s,
            cmd_vel=physics.named.data.ctrl[["student/forward", "student/turn"]],
            student_pose=student.planar_pose(physics),
            student_velocity=(velocity[3], velocity[2]),
            image=self.bag_renderer.render("showcase"),
            camera_matrix=self.camera.matrix,
            camera_pose=(self.camera.rotation_world_from_camera, self.camera.position_world),
            estimated_poses={"student": getattr(agent, "own_pose", None)},
            word=self.word,
            directive=agent.directive,
        )

    def close(self, keep: bool = True) -> None:
        """Finishes the video; ``keep``: move it to its name (False: a failed trial's is dropped)."""
        self.writer.close()
        self.renderer.close()
        self.inset_renderer.close()
        if self.bag is not None:
            self.bag.close(keep=keep)
            self.bag_renderer.close()
        if keep:
            storage.commit(self.tmp, self.path)
        else:
            self.tmp.unlink(missing_ok=True)


@dataclasses.dataclass(frozen=True)
class Filmed:
    """One filmed trial: its policy, word, video file name and verdict with its reason."""

    policy: str
    word: str
    video: str
    success: bool
    reason: str


def _film_worker(jobs: list, config: RunConfig, folder: str, progress_file: str) -> list:
    import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL in a freshly spawned process)

    env = trials.student_environment(config)
    calibration = None
    if config.vision.mode != "truth":
        calibration = Calibration(env.physics, config.vision.width, config.vision.height)
    models = {}
    out, frames = [], 0
    for policy, word in jobs:
        if policy != "teacher" and policy not in models:
            models[policy] = persistence.load(
                pathlib.Path(folder) / trials.STUDENT_NETWORKS[policy]
            )
        path = pathlib.Path(folder) / video_name(policy, word)
        film = _Film(env, path, policy, word, config, progress_file, frames)
        finished = False
        try:
            result = trials.from_fig4_start(
                config, env, policy, models.get(policy), calibration, word, film
            )
            film.finish(result)
            finished = True
        finally:
            film.close(keep=finished)
        frames = film.frames
        out.append(Filmed(policy, word, path.name, bool(result.success), result.reason))
    env.close()
    return out


def _side_by_side_worker(words: list, policies: tuple, folder: str, progress_file: str) -> list:
    """Writes, per word, the policies' videos side by side (left to right in ``policies``' order),
    frame by frame: same start, same time base."""
    out, frames = [], 0
    for word in words:
        path = pathlib.Path(folder) / side_by_side_name(word)
        tmp = storage.temporary_name(path)
        readers = [imageio.get_reader(pathlib.Path(folder) / video_name(p, word)) for p in policies]
        fps_ = readers[0].get_meta_data()["fps"]
        writer = imageio.get_writer(
            str(tmp),
            fps=fps_,
            codec="libx264",
            quality=7,
            macro_block_size=8,
            ffmpeg_log_level="error",
        )
        try:
            for panels in zip(*readers, strict=True):
                writer.append_data(np.hstack(panels))
                frames += 1
                if frames % 20 == 0:
                    pathlib.Path(progress_file).write_text(str(frames))
        finally:
            writer.close()
            for reader in readers:
                reader.close()
        storage.commit(tmp, path)
        out.append(path.name)
    return out


def stage_videos(config: RunConfig, folder: pathlib.Path) -> dict:
    """Renders every policy's video of every word (``<policy>_<word>.mp4``) and per word the
    side-by-side video (``side_by_side_<word>.mp4``); returns their names, the verdicts and, with
    MCAP logs on, the logs' names."""
    policies = video_policies(config)
    jobs = [(p, w) for w in WORDS for p in policies]
    workers = max(1, min(config.workers, len(jobs)))
    chunks = [jobs[i::workers] for i in range(workers)]
    frames = frames_per_video(config)
    filmed = run_parallel(
        _film_worker, chunks, (config, str(folder)), workers, folder, "videos", frames * len(jobs)
    )
    filmed = sorted(
        (f for chunk in filmed for f in chunk), key=lambda f: jobs.index((f.policy, f.word))
    )
    word_chunks = [list(WORDS[i :: min(workers, 3)]) for i in range(min(workers, 3))]
    side = run_parallel(
        _side_by_side_worker,
        word_chunks,
        (policies, str(folder)),
        len(word_chunks),
        folder,
        "side-by-side videos",
        frames * len(WORDS),
    )
    videos = sorted([f.video for f in filmed] + [name for chunk in side for name in chunk])
    result = {
        "videos": videos,
        "verdicts": [dataclasses.asdict(f) for f in filmed],
        "fps": fps(config),
        "frames": frames,
        "side_by_side_panels": list(policies),
    }
    if config.videos.mcap:
        result["mcap"] = [str(pathlib.Path(f.video).with_suffix(".mcap")) for f in filmed]
    return result
