"""The performance stage of ``peoplebot reproduce`` and Fig. 4's traces, run in parallel
processes; the videos are ``imitation.videos``."""

from __future__ import annotations

import dataclasses
import json
import pathlib

import numpy as np

from associator import encoding, persistence
from imitation import performance, perturbations, storage
from imitation.config import RunConfig
from imitation.limits import AccelerationLimitEstimator
from imitation.observers import Calibration
from imitation.parallel import run_parallel
from imitation.results import Fig4Trace, PerformanceResult, SuccessRate, TrialRecord
from imitation.speedgain import MEASURED_AXES, SpeedGainEstimator
from peoplebot_sim.task import load
from perception.localisation import CHI2_2DOF_95
from perception.pose import wrap_radians

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
    """Returns the run's world with the student alone (and the overhead camera, or the head camera
    when the head mode localises by landmarks; the student robot's actuation and body
    perturbations), reset."""
    vision = config.vision
    cameras = ()
    if vision.mode == "overhead":
        cameras = ("overhead",)
    elif vision.mode == "head" and vision.self_localisation == "landmarks":
        cameras = ("head",)  # the student looks at the wall landmarks
    env = load(
        config.world_config(
            with_teacher=False, cameras=cameras, width=vision.width, height=vision.height
        ),
        seed=config.seed,
    )
    env.reset()
    return env


def make_agent(config: RunConfig, policy: str, word: str, env, model, calibration, rng=None):
    """Returns the agent of ``policy`` told ``word``: the teacher's controller (seeded by ``rng``;
    its true pose under the run's perception faults) or a student driving with ``model``, seeing
    through ``calibration`` (the world's) as the run's
    perturbations make it (their randomness keyed by ``rng``, default the run seed)."""
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
            teacher_config=reference_teacher_config(config),
            vision=perturbations.teacher_vision(
                config.perturbations, config.task.control_timestep, rng
            ),
        )
    student_vision = perturbations.student_vision(
        config.vision.mode,
        calibration,
        config.perturbations,
        config.task.control_timestep,
        [config.seed] if rng is None else rng,
        watch_teacher=False,
        self_localisation=config.vision.self_localisation,
        overhead_registration=config.vision.overhead_registration,
    )
    return performance.StudentAgent(
        model,
        word,
        student_vision,
        encoding.VisionEncoder(half_side_m=env.task.geometry.half_side_m),
        spec,
        drive=config.drive,
        graded=config.performance.drive == "graded",
        arena=env.task.geometry,
        **_support_arguments(config, policy),
        **_braking(config),
    )


def _support_arguments(config: RunConfig, policy: str) -> dict:
    """Returns the student agent's lookahead arguments: the hierarchical student's lookahead
    and, with measured ``performance.support_speeds``, its speed estimator of the axes they
    name; none for the paper's network (it drives as printed)."""
    support = _support(config) if policy == "student_hierarchical" else None
    speeds = config.performance.support_speeds
    if support is None or speeds == "nominal":
        return {"support": support}
    axes = MEASURED_AXES[speeds]
    return {"support": support, "speed_gains": SpeedGainEstimator(config.drive, axes=axes)}


def _support(config: RunConfig) -> performance.SupportLookahead | None:
    """Returns the hierarchical student's lookahead onto its demonstrations, or None (off)."""
    c = config.performance
    if c.support_horizon_s <= 0:
        return None
    return performance.SupportLookahead(c.support_horizon_s, c.support_weight)


def _braking(config: RunConfig) -> dict:
    """Returns the student agent's braking arguments: none, the limits it is told, or an
    estimator of them (``performance.brake_ahead`` and ``brake_limits``)."""
    if not config.performance.brake_ahead:
        return {}
    if config.performance.brake_limits == "estimated":
        return {"limit_estimator": AccelerationLimitEstimator(config.task.control_timestep)}
    return {"brake_ahead": config.perturbations.actuation}


def reference_teacher_config(config: RunConfig):
    """Returns the teacher settings the reference row performs with: the run's, told the
    acceleration limits of the robot it drives, the student's (``[perturbations.actuation]``;
    a real controller is configured for its robot), not those of the robot that recorded the
    demonstrations."""
    actuation = config.perturbations.actuation
    return dataclasses.replace(
        config.teacher,
        robot_linear_accel_mps2=actuation.linear_accel_mps2,
        robot_yaw_accel_degps2=actuation.yaw_accel_degps2,
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


def run_planned_trial(config: RunConfig, env, item: PlannedTrial, policy: str, model, calibration):
    """Runs one planned trial of ``policy`` (driving with ``model``; the teacher seeded by the
    trial) and returns it."""
    agent = make_agent(
        config,
        policy,
        performance.ROW_WORD[item.row],
        env,
        model,
        calibration,
        rng=[config.seed, performance.ROWS.index(item.row), item.index],
    )
    return performance.run_trial(
        env,
        agent,
        item.row,
        item.start,
        item.wall,
        seconds=config.performance.trial_seconds,
        config=config.performance.success,
    )


def ellipse95_semi_major_m(covariances) -> np.ndarray:
    """Returns the 95% position ellipses' semi-major axes, metres, of the steps with a covariance
    (``covariances``: (n, 3, 3), NaN where none; None: none at all), shape (k,)."""
    if covariances is None:
        return np.zeros(0)
    covariances = np.asarray(covariances, dtype=float).reshape(-1, 3, 3)
    known = np.all(np.isfinite(covariances.reshape(-1, 9)), axis=1)
    if not np.any(known):
        return np.zeros(0)
    largest = np.linalg.eigvalsh(covariances[known, :2, :2])[:, -1]
    return np.sqrt(CHI2_2DOF_95 * np.clip(largest, 0.0, None))


def _p95(values: np.ndarray) -> float:
    return np.percentile(values, 95)


def _statistic(function, values: np.ndarray) -> float | None:
    """Returns ``function(values)`` as a float, or None when there are no values."""
    return float(function(values)) if values.size else None


def _trials_worker(plan: list, config: RunConfig, networks: dict, progress_file: str) -> list:
    models, env, calibration = _worker_setup(config, networks)
    out = []
    for k, item in enumerate(plan):
        result = run_planned_trial(
            config, env, item, item.policy, models.get(item.policy), calibration
        )
        # The estimate of step k is made from the observation before the step, i.e. the pose
        # after step k - 1 (the start for k = 0); trace[k] is the pose after step k.
        est = result.estimate
        truth_then = np.vstack([np.asarray(item.start, dtype=float)[None, :], result.trace[:-1]])
        valid = np.all(np.isfinite(est), axis=1)
        own_error_cm = 100 * np.hypot(*(est[valid, :2] - truth_then[valid, :2]).T)
        heading_error_deg = np.degrees(np.abs(wrap_radians(est[valid, 2] - truth_then[valid, 2])))
        ellipse_cm = 100 * ellipse95_semi_major_m(result.estimate_covariance)
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
                own_pose_error_cm_median=_statistic(np.median, own_error_cm),
                reason=result.reason,
                own_pose_error_cm_p95=_statistic(_p95, own_error_cm),
                own_position_ellipse95_cm_median=_statistic(np.median, ellipse_cm),
                own_heading_error_deg_median=_statistic(np.median, heading_error_deg),
                own_heading_error_deg_p95=_statistic(_p95, heading_error_deg),
            )
        )
        pathlib.Path(progress_file).write_text(str(k + 1))
    env.close()
    return out


def stage_performance(config: RunConfig, folder: pathlib.Path) -> PerformanceResult:
    """Runs every trial of ``trial_plan`` and the Fig. 4 traces; returns the success rates."""
    return PerformanceResult(success_rates(config, folder), fig4_traces(config, folder))


def success_rates(
    config: RunConfig,
    folder: pathlib.Path,
    networks_from: pathlib.Path | None = None,
    policies: tuple | None = None,
) -> dict:
    """Runs every trial of ``trial_plan`` of ``policies`` (default ``policies_of(config)``) with
    the networks of ``networks_from`` (default ``folder``), writes them to ``folder``'s
    ``performance_trials.json`` and returns the success rates, ``rates[row][policy]`` (None where
    a policy has no trials on a row)."""
    policies = policies_of(config) if policies is None else tuple(policies)
    source = folder if networks_from is None else pathlib.Path(networks_from)
    networks = {p: str(source / name) for p, name in STUDENT_NETWORKS.items() if p in policies}
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
    return rates


#: Random-start traces per word and policy drawn beside Fig. 4 (the first starts of the trials).
RANDOM_TRACES = 10
#: The rows whose random starts Fig. 4's second panel shows, one per word.
TRACE_ROWS = {"go": "go", "pick": "pick", "lift": "lift"}


def fig4_traces(config: RunConfig, folder: pathlib.Path) -> dict:
    """Runs every policy from the paper's start with each word (no early stop), and from the
    first ``RANDOM_TRACES`` trial starts of each word's row (stopping at success, as the trials
    do); saves the traces (``fig4_traces.npz``); returns where the paper's network ended.

    Keys: ``<word>`` and ``<word>_directives`` (the paper's network, Fig. 4),
    ``fig4_<policy>_<word>`` (n, 3) and ``fig4_<policy>_<word>_success`` for every policy,
    ``random_<policy>_<word>`` (k, n, 3), NaN after a trial's end, and
    ``random_<policy>_<word>_success`` (k,).
    """
    policies = tuple(
        p for p in ("teacher", "student", "student_hierarchical") if p in policies_of(config)
    )
    jobs = [("fig4", policy, word, None) for word in TRACE_ROWS for policy in policies]
    for item in trial_plan(config, policies):
        if item.row in TRACE_ROWS.values() and item.index < RANDOM_TRACES:
            jobs.append(("random", item.policy, item.row, item))
    workers = max(1, min(config.workers, len(jobs)))
    chunks = [jobs[i::workers] for i in range(workers)]
    results = run_parallel(
        _traces_worker, chunks, (config, str(folder)), workers, folder, "Fig. 4 traces", len(jobs)
    )
    done = {}
    for chunk in results:
        done.update(chunk)
    n = int(round(config.performance.trial_seconds / config.task.control_timestep))
    traces, out = {}, {}
    for kind, policy, word, item in jobs:
        key = (kind, policy, word, None if item is None else item.index)
        trace, directives, success, touched, seconds = done[key]
        if kind == "fig4":
            traces[f"fig4_{policy}_{word}"] = trace
            traces[f"fig4_{policy}_{word}_success"] = np.asarray(success)
            if policy == "student":
                traces[word] = trace
                traces[f"{word}_directives"] = np.asarray([d or "" for d in directives])
                out[word] = Fig4Trace(tuple(float(v) for v in trace[-1]), touched, seconds)
            continue
        padded = np.full((n, 3), np.nan)
        padded[: len(trace)] = trace[:n]
        traces.setdefault(f"random_{policy}_{word}", []).append(padded)
        traces.setdefault(f"random_{policy}_{word}_success", []).append(success)
    storage.save_npz(folder / "fig4_traces.npz", **{k: np.asarray(v) for k, v in traces.items()})
    return out


def _traces_worker(jobs: list, config: RunConfig, folder: str, progress_file: str) -> dict:
    """Runs the trace jobs ``(kind, policy, word, planned trial or None)``; returns each job's
    ``(trace, directives, success, touched, seconds)``."""
    import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL in a freshly spawned process)

    env = student_environment(config)
    calibration = None
    if config.vision.mode != "truth":
        calibration = Calibration(env.physics, config.vision.width, config.vision.height)
    models, out = {}, {}
    for k, (kind, policy, word, item) in enumerate(jobs):
        if policy != "teacher" and policy not in models:
            models[policy] = persistence.load(pathlib.Path(folder) / STUDENT_NETWORKS[policy])
        if kind == "fig4":
            result = from_fig4_start(config, env, policy, models.get(policy), calibration, word)
        else:
            result = run_planned_trial(config, env, item, policy, models.get(policy), calibration)
        key = (kind, policy, word, None if item is None else item.index)
        out[key] = (
            result.trace,
            result.directives,
            bool(result.success),
            bool(result.touched),
            result.seconds,
        )
        pathlib.Path(progress_file).write_text(str(k + 1))
    env.close()
    return out


def fig4_teacher_rng(config: RunConfig, word: str) -> list:
    """Returns the seed of the teacher's run from the paper's start with ``word``."""
    return [config.seed, len(performance.ROWS), ("go", "pick", "lift").index(word)]


def from_fig4_start(
    config: RunConfig, env, policy: str, model, calibration, word: str, frame_callback=None
):
    """Runs ``policy`` (a student driving with ``model``, or the teacher) told ``word`` from the
    paper's Fig. 4 start for a whole trial (no early stop); returns the trial."""
    rng = fig4_teacher_rng(config, word)
    agent = make_agent(config, policy, word, env, model, calibration, rng=rng)
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
