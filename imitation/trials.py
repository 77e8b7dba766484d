"""The performance and video stages of ``peoplebot reproduce``, run in parallel processes."""

from __future__ import annotations

import dataclasses
import json
import pathlib

import imageio.v2 as imageio
import mujoco
import numpy as np

from associator import encoding, persistence
from imitation import performance, storage
from imitation.config import RunConfig
from imitation.observers import Calibration, StudentVision
from imitation.overlay import annotate
from imitation.parallel import run_parallel
from imitation.results import Fig4Trace, PerformanceResult, SuccessRate, TrialRecord
from imitation.rosbag import EpisodeRecorder
from peoplebot_sim.cameras import camera_model
from peoplebot_sim.rendering import FrameRenderer
from peoplebot_sim.task import load

#: Student policies and the network file each drives with (in the run folder).
STUDENT_NETWORKS = {"student": "network.npz", "student_hierarchical": "hierarchical.npz"}


def policies_of(config: RunConfig) -> tuple[str, ...]:
    """Returns the policies a run evaluates: the paper's network, the teacher (the reference) and,
    if enabled, the hierarchical associator."""
    return tuple(
        p
        for p in performance.POLICIES
        if config.hierarchical.enabled or p != "student_hierarchical"
    )


@dataclasses.dataclass(frozen=True)
class PlannedTrial:
    """One trial to run: its row, policy, index among the row's starts, start (world x m, y m,
    yaw rad) and the wall its success refers to."""

    row: str
    policy: str
    index: int
    start: tuple
    wall: str


def trial_plan(config: RunConfig, policies=None) -> list[PlannedTrial]:
    """Returns every trial to run: per row, ``config.performance.trials`` random starts shared by
    the policies (paired); the teacher has no reference for docking at a wall without a table."""
    policies = policies_of(config) if policies is None else policies
    plan = []
    for r, row in enumerate(performance.ROWS):
        rng = np.random.default_rng([config.seed, r])
        for k in range(config.performance.trials):
            start, wall = performance.sample_start(row, rng, teacher=config.teacher)
            for policy in policies:
                if policy == "teacher" and row == "pick_other_wall":
                    continue
                plan.append(PlannedTrial(row, policy, k, tuple(start), wall))
    return plan


def student_environment(config: RunConfig):
    """Returns the run's world with the student alone (and the overhead camera in that vision
    mode), reset."""
    vision = config.vision
    cameras = ("overhead",) if vision.mode == "overhead" else ()
    env = load(
        config.task_config(
            with_teacher=False, cameras=cameras, width=vision.width, height=vision.height
        ),
        seed=config.seed,
    )
    env.reset()
    return env


def make_agent(config: RunConfig, policy: str, word: str, env, model, calibration, rng=None):
    """Returns the agent of ``policy`` told ``word``: the teacher's controller (seeded by ``rng``)
    or a student driving with ``model``."""
    spec = env.action_spec()
    if policy == "teacher":
        if rng is None:
            raise ValueError("a teacher reference agent needs its trial's rng seed")
        return performance.TeacherAgent(
            word,
            spec,
            drive=config.drive,
            arena=env.task.geometry,
            rng=rng,
            teacher_config=config.teacher,
        )
    student_vision = StudentVision(config.vision.mode, calibration, watch_teacher=False)
    return performance.StudentAgent(
        model,
        word,
        student_vision,
        encoding.VisionEncoder(half_side_m=env.task.geometry.half_side_m),
        spec,
        drive=config.drive,
        graded=config.performance.drive == "graded",
        arena=env.task.geometry,
    )


def _worker_setup(config: RunConfig, networks: dict):
    """Returns a worker process's networks (policy -> model), student-only environment and camera
    calibration."""
    import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL in a freshly spawned process)

    models = {policy: persistence.load(path) for policy, path in networks.items()}
    env = student_environment(config)
    calibration = None
    if config.vision.mode != "truth":
        calibration = Calibration(env.physics, config.vision.width, config.vision.height)
    return models, env, calibration


def _trials_worker(plan: list, config: RunConfig, networks: dict, progress_file: str) -> list:
    models, env, calibration = _worker_setup(config, networks)
    out = []
    for k, item in enumerate(plan):
        row_index = performance.ROWS.index(item.row)
        agent = make_agent(
            config,
            item.policy,
            performance.ROW_WORD[item.row],
            env,
            models.get(item.policy),
            calibration,
            rng=[config.seed, row_index, item.index],
        )
        result = performance.run_trial(
            env,
            agent,
            item.row,
            item.start,
            item.wall,
            seconds=config.performance.trial_seconds,
            config=config.performance.success,
        )
        est = result.estimate
        valid = np.all(np.isfinite(est), axis=1)
        own_error = np.hypot(*(est[valid, :2] - result.trace[valid, :2]).T)
        out.append(
            TrialRecord(
                row=item.row,
                policy=item.policy,
                index=item.index,
                start=item.start,
                wall=item.wall,
                success=bool(result.success),
                seconds=result.seconds,
                touched=bool(result.touched),
                end_pose=tuple(float(v) for v in result.trace[-1]),
                own_pose_error_cm_median=float(np.median(own_error) * 100)
                if own_error.size
                else None,
            )
        )
        pathlib.Path(progress_file).write_text(str(k + 1))
    env.close()
    return out


def stage_performance(config: RunConfig, folder: pathlib.Path) -> PerformanceResult:
    """Runs every trial of ``trial_plan`` and the Fig. 4 traces; returns the success rates."""
    policies = policies_of(config)
    networks = {p: str(folder / name) for p, name in STUDENT_NETWORKS.items() if p in policies}
    plan = trial_plan(config, policies)
    workers = max(1, min(config.workers, len(plan)))
    chunks = [plan[i::workers] for i in range(workers)]
    results = run_parallel(
        _trials_worker, chunks, (config, networks), workers, folder, "performance trials", len(plan)
    )
    # In the plan's order, whatever the number of workers.
    done = {(t.row, t.policy, t.index): t for chunk in results for t in chunk}
    trials = [done[(p.row, p.policy, p.index)] for p in plan]
    storage.write_text(
        folder / "performance_trials.json", json.dumps([t.to_json() for t in trials], indent=1)
    )
    rates = {}
    for row in performance.ROWS:
        rates[row] = {}
        for policy in policies:
            mine = [t for t in trials if t.row == row and t.policy == policy]
            rates[row][policy] = SuccessRate.of(mine) if mine else None
    return PerformanceResult(rates, fig4_traces(config, folder))


def fig4_traces(config: RunConfig, folder: pathlib.Path) -> dict:
    """Runs the student from the paper's start with each word (no early stop) and saves the traces
    (``fig4_traces.npz``); returns where each ended."""
    model = persistence.load(folder / "network.npz")
    env = student_environment(config)
    calibration = None
    if config.vision.mode != "truth":
        calibration = Calibration(env.physics, config.vision.width, config.vision.height)
    traces, out = {}, {}
    for word in ("go", "pick", "lift"):
        result = _from_fig4_start(config, env, model, calibration, word)
        traces[word] = result.trace
        traces[f"{word}_directives"] = np.asarray([d or "" for d in result.directives])
        out[word] = Fig4Trace(
            tuple(float(v) for v in result.trace[-1]), result.touched, result.seconds
        )
    env.close()
    storage.save_npz(folder / "fig4_traces.npz", **traces)
    return out


def _from_fig4_start(config: RunConfig, env, model, calibration, word: str, frame_callback=None):
    """Runs the student told ``word`` from the paper's Fig. 4 start for a whole trial (no early
    stop); returns the trial."""
    agent = make_agent(config, "student", word, env, model, calibration)
    return performance.run_trial(
        env,
        agent,
        word,
        performance.FIG4_START,
        "top",
        seconds=config.performance.trial_seconds,
        config=config.performance.success,
        stop_on_success=False,
        frame_callback=frame_callback,
    )


class _VideoWriter:
    """Writes one annotated showcase frame per control step of a trial."""

    def __init__(
        self,
        env,
        path,
        word: str,
        width: int,
        height: int,
        progress_file: str,
        frames_before: int,
        mcap: bool = False,
    ):
        self.path, self.tmp = pathlib.Path(path), storage.temporary_name(path)
        self.bag = EpisodeRecorder(self.path.with_suffix(".mcap")) if mcap else None
        self.camera = camera_model(env.physics, "showcase", width, height)
        self.word, self.progress_file, self.frames = word, progress_file, frames_before
        self.steps = 0
        self.renderer = FrameRenderer(env.physics, width, height, antialias=True)
        self.writer = imageio.get_writer(
            str(self.tmp),
            fps=20,
            codec="libx264",
            quality=7,
            macro_block_size=8,
            ffmpeg_log_level="error",
        )

    def __call__(self, env, agent) -> None:
        self.steps += 1
        time_s = self.steps * env.task.control_timestep
        caption = f"student told '{self.word}'   t = {time_s:4.1f} s"
        image = self.renderer.render("showcase")
        if self.bag is not None:
            self._log(env, agent, time_s, image)
        self.writer.append_data(annotate(image, self.word, agent.directive, caption, agent.motor))
        self.frames += 1
        if self.frames % 20 == 0:
            pathlib.Path(self.progress_file).write_text(str(self.frames))

    def _log(self, env, agent, time_s: float, image) -> None:
        """Records the step in the episode's MCAP log: the wheel command, the student's true and
        estimated pose and velocity, the camera's frame, the word and directive."""
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
            image=image,
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
        if self.bag is not None:
            self.bag.close(keep=keep)
        if keep:
            storage.commit(self.tmp, self.path)
        else:
            self.tmp.unlink(missing_ok=True)


def _video_worker(
    words: list, config: RunConfig, network: str, folder: str, progress_file: str
) -> list[str]:
    models, env, calibration = _worker_setup(config, {"student": network})
    model = models["student"]
    paths, frames = [], 0
    width, height = config.videos.width, config.videos.height
    for word in words:
        path = pathlib.Path(folder) / f"student_{word}.mp4"
        video = _VideoWriter(
            env, path, word, width, height, progress_file, frames, mcap=config.videos.mcap
        )
        finished = False
        try:
            _from_fig4_start(config, env, model, calibration, word, video)
            finished = True
        finally:
            video.close(keep=finished)
        frames = video.frames
        paths.append(path.name)
    env.close()
    return paths


def stage_videos(config: RunConfig, folder: pathlib.Path) -> dict:
    """Renders ``student_<word>.mp4``: the student performing each word from the paper's start."""
    words = ["go", "pick", "lift"]
    workers = max(1, min(config.workers, len(words)))
    chunks = [words[i::workers] for i in range(workers)]
    frames = int(round(config.performance.trial_seconds / config.task.control_timestep)) * len(
        words
    )
    results = run_parallel(
        _video_worker,
        chunks,
        (config, str(folder / "network.npz"), str(folder)),
        workers,
        folder,
        "videos",
        frames,
    )
    videos = sorted(p for chunk in results for p in chunk)
    logs = [str(pathlib.Path(v).with_suffix(".mcap")) for v in videos] if config.videos.mcap else []
    return {"videos": videos, **({"mcap": logs} if logs else {})}
