"""The performance and video stages of ``peoplebot reproduce``, run in parallel processes."""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import pathlib

import numpy as np

from associator import encoding, persistence
from peoplebot_sim import performance
from peoplebot_sim.observers import Calibration, StudentVision
from peoplebot_sim.task import TaskConfig, load

WORD_OF_ROW = performance.ROW_WORD


def trial_plan(trials: int, seed: int, policies=performance.POLICIES) -> list[dict]:
    """Returns every trial to run: per row, ``trials`` random starts shared by the policies
    (paired); the teacher has no reference for docking at a wall without a table."""
    plan = []
    for r, row in enumerate(performance.ROWS):
        rng = np.random.default_rng([seed, r])
        for k in range(trials):
            start, wall = performance.sample_start(row, rng)
            for policy in policies:
                if policy == "teacher" and row == "pick_other_wall":
                    continue
                plan.append(
                    {"row": row, "policy": policy, "index": k, "start": list(start), "wall": wall}
                )
    return plan


def _environment(vision: str, seed: int, width: int = 320, height: int = 240):
    cameras = ("overhead",) if vision == "overhead" else ()
    env = load(
        TaskConfig(with_teacher=False, cameras=cameras, width=width, height=height), seed=seed
    )
    env.reset()
    return env


def _agent(
    policy: str, word: str, env, model, vision: str, calibration, rng=None, graded: bool = True
):
    spec = env.action_spec()
    if policy == "teacher":
        if rng is None:
            raise ValueError("a teacher reference agent needs its trial's rng seed")
        return performance.TeacherAgent(word, spec, rng=rng)
    student_vision = StudentVision(vision, calibration, watch_teacher=False)
    return performance.StudentAgent(
        model, word, student_vision, encoding.VisionEncoder(), spec, graded=graded
    )


def _worker_setup(networks: dict, vision: str, seed: int):
    """Returns a worker process's networks (policy -> model), student-only environment and camera
    calibration."""
    import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL in a freshly spawned process)

    model = {policy: persistence.load(path) for policy, path in networks.items()}
    env = _environment(vision, seed)
    calibration = Calibration(env.physics, 320, 240) if vision != "truth" else None
    return model, env, calibration


def _trials_worker(
    plan: list,
    networks: dict,
    vision: str,
    seconds: float,
    seed: int,
    graded: bool,
    progress_file: str,
) -> list[dict]:
    models, env, calibration = _worker_setup(networks, vision, seed)
    config = performance.SuccessConfig(seconds=seconds)
    out = []
    for k, item in enumerate(plan):
        row_index = performance.ROWS.index(item["row"])
        agent = _agent(
            item["policy"],
            WORD_OF_ROW[item["row"]],
            env,
            models.get(item["policy"]),
            vision,
            calibration,
            rng=[seed, row_index, item["index"]],
            graded=graded,
        )
        result = performance.run_trial(
            env, agent, item["row"], tuple(item["start"]), item["wall"], config=config
        )
        est = result.estimate
        valid = np.all(np.isfinite(est), axis=1)
        own_error = np.hypot(*(est[valid, :2] - result.trace[valid, :2]).T)
        out.append(
            {
                **item,
                "success": bool(result.success),
                "seconds": result.seconds,
                "touched": bool(result.touched),
                "end_pose": [float(v) for v in result.trace[-1]],
                "own_pose_error_cm_median": float(np.median(own_error) * 100)
                if own_error.size
                else None,
            }
        )
        pathlib.Path(progress_file).write_text(str(k + 1))
    env.close()
    return out


def _run_parallel(
    fn, chunks: list, args: tuple, workers: int, folder: pathlib.Path, desc: str, total: int
):
    from peoplebot_sim.reproduce import _poll

    progress = [folder / f".{desc.replace(' ', '_')}.{i}.progress" for i in range(len(chunks))]
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        futures = [
            pool.submit(fn, chunk, *args, str(p)) for chunk, p in zip(chunks, progress, strict=True)
        ]
        results = _poll(futures, progress, total, desc)
    for p in progress:
        p.unlink(missing_ok=True)
    return results


def stage_performance(config, folder: pathlib.Path) -> dict:
    """Runs every trial of ``trial_plan`` and the Fig. 4 traces; returns the success rates."""
    policies = [p for p in performance.POLICIES if p != "student_hierarchical"]
    if config.hierarchical:
        policies.append("student_hierarchical")
    networks = {
        p: str(folder / name) for p, name in performance.STUDENT_NETWORKS.items() if p in policies
    }
    plan = trial_plan(config.trials, config.seed, tuple(policies))
    workers = max(1, min(config.workers, len(plan)))
    chunks = [plan[i::workers] for i in range(workers)]
    results = _run_parallel(
        _trials_worker,
        chunks,
        (
            networks,
            config.vision,
            config.trial_seconds,
            config.seed,
            config.drive == "graded",
        ),
        workers,
        folder,
        "performance trials",
        len(plan),
    )
    trials = [t for chunk in results for t in chunk]
    (folder / "performance_trials.json").write_text(__import__("json").dumps(trials, indent=1))
    rates = {}
    for row in performance.ROWS:
        rates[row] = {}
        for policy in policies:
            mine = [t for t in trials if t["row"] == row and t["policy"] == policy]
            if not mine:
                rates[row][policy] = None
                continue
            successes = sum(t["success"] for t in mine)
            errors = [
                t["own_pose_error_cm_median"]
                for t in mine
                if t["own_pose_error_cm_median"] is not None
            ]
            rates[row][policy] = {
                "success_rate": successes / len(mine),
                "successes": successes,
                "trials": len(mine),
                "touched": sum(t["touched"] for t in mine),
                "mean_seconds": float(np.mean([t["seconds"] for t in mine])),
                "own_pose_error_cm_median": float(np.median(errors)) if errors else None,
            }
    rates["fig4"] = fig4_traces(config, folder)
    return rates


def fig4_traces(config, folder: pathlib.Path) -> dict:
    """Runs the student from the paper's start with each word (no early stop) and saves the traces
    (``fig4_traces.npz``); returns where each ended."""
    model = persistence.load(folder / "network.npz")
    env = _environment(config.vision, config.seed)
    calibration = Calibration(env.physics, 320, 240) if config.vision != "truth" else None
    success = performance.SuccessConfig(seconds=config.trial_seconds)
    traces, out = {}, {}
    for word in ("go", "pick", "lift"):
        agent = _agent(
            "student",
            word,
            env,
            model,
            config.vision,
            calibration,
            graded=config.drive == "graded",
        )
        result = performance.run_trial(
            env, agent, word, performance.FIG4_START, "top", config=success, stop_on_success=False
        )
        traces[word] = result.trace
        traces[f"{word}_directives"] = np.asarray([d or "" for d in result.directives])
        out[word] = {
            "end_pose": [float(v) for v in result.trace[-1]],
            "touched": result.touched,
            "seconds": result.seconds,
        }
    env.close()
    np.savez(folder / "fig4_traces.npz", **traces)
    return out


class _VideoWriter:
    """Writes one annotated showcase frame per control step of a trial."""

    def __init__(
        self, env, path, word: str, width: int, height: int, progress_file: str, frames_before: int
    ):
        import imageio.v2 as imageio

        from peoplebot_sim.rendering import FrameRenderer

        self.word, self.progress_file, self.frames = word, progress_file, frames_before
        self.steps = 0
        self.renderer = FrameRenderer(env.physics, width, height, antialias=True)
        self.writer = imageio.get_writer(
            str(path),
            fps=20,
            codec="libx264",
            quality=7,
            macro_block_size=8,
            ffmpeg_log_level="error",
        )

    def __call__(self, env, agent) -> None:
        from peoplebot_sim.overlay import annotate

        self.steps += 1
        caption = f"student told '{self.word}'   t = {self.steps * 0.1:4.1f} s"
        image = self.renderer.render("showcase")
        self.writer.append_data(annotate(image, self.word, agent.directive, caption, agent.motor))
        self.frames += 1
        if self.frames % 20 == 0:
            pathlib.Path(self.progress_file).write_text(str(self.frames))

    def close(self) -> None:
        self.writer.close()
        self.renderer.close()


def _video_worker(
    words: list,
    network: str,
    vision: str,
    seconds: float,
    seed: int,
    width: int,
    height: int,
    folder: str,
    graded: bool,
    progress_file: str,
) -> list[str]:
    models, env, calibration = _worker_setup({"student": network}, vision, seed)
    model = models["student"]
    paths, frames = [], 0
    for word in words:
        agent = _agent("student", word, env, model, vision, calibration, graded=graded)
        path = pathlib.Path(folder) / f"student_{word}.mp4"
        video = _VideoWriter(env, path, word, width, height, progress_file, frames)
        try:
            performance.run_trial(
                env,
                agent,
                word,
                performance.FIG4_START,
                "top",
                config=performance.SuccessConfig(seconds=seconds),
                stop_on_success=False,
                frame_callback=video,
            )
        finally:
            video.close()
        frames = video.frames
        paths.append(path.name)
    env.close()
    return paths


def stage_videos(config, folder: pathlib.Path) -> dict:
    """Renders ``student_<word>.mp4``: the student performing each word from the paper's start."""
    words = ["go", "pick", "lift"]
    workers = max(1, min(config.workers, len(words)))
    chunks = [words[i::workers] for i in range(workers)]
    frames = int(round(config.trial_seconds / 0.1)) * len(words)
    results = _run_parallel(
        _video_worker,
        chunks,
        (
            str(folder / "network.npz"),
            config.vision,
            config.trial_seconds,
            config.seed,
            config.video_width,
            config.video_height,
            str(folder),
            config.drive == "graded",
        ),
        workers,
        folder,
        "videos",
        frames,
    )
    return {"videos": sorted(p for chunk in results for p in chunk)}
