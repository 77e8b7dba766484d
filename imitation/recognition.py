"""Recognition (the paper's Table I): the teacher loops, the student names what it sees.

The language area is omitted; the student gets the teacher's pose (truth, or estimated through its
vision) and motor directive (the teacher's, or inferred from the observed motion), and the word whose
code best matches the language area reconstructed through W_td is compared with the true one.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from tqdm import tqdm

from associator import encoding
from associator.network import Associator
from imitation.learning import encode_stream, inferred_directives
from imitation.observers import Calibration, pose_or_nan
from imitation.performance import make_action
from imitation.perturbations import PerturbationConfig, PoseCorruptor, rng_for, student_vision
from imitation.results import CameraRecognition, ConfusionTable, ErrorSummary
from imitation.streams import TeacherStream
from peoplebot_sim import directives
from peoplebot_sim.task import TaskConfig, load
from perception.wallframe import world_to_wall_batch


def confusion_counts(true_words: np.ndarray, recognised: np.ndarray) -> np.ndarray:
    """Returns counts[true][recognised], shape (3, 3), from word indices."""
    n = len(directives.WORDS)
    return np.bincount(
        true_words.astype(int) * n + recognised.astype(int), minlength=n * n
    ).reshape(n, n)


def table(true_words: np.ndarray, recognised: np.ndarray) -> ConfusionTable:
    """Returns the confusion table of recognised word indices against the true ones."""
    return ConfusionTable.from_counts(confusion_counts(true_words, recognised))


def recognise_stream(
    model: Associator,
    stream: TeacherStream,
    encoder: encoding.VisionEncoder,
    motor_source: str = "teacher",
    dt: float = 0.1,
    chunk: int = 200_000,
    motor_weight: float = 1.0,
    over_time: bool = False,
    seen: np.ndarray | None = None,
) -> np.ndarray:
    """Returns the recognised word index for every step of a stream (language omitted).

    ``motor_weight``: the read-out's weight on the motor area (1: the paper's read-out).
    ``over_time``: recognise with the hierarchical associator's belief carried from step to step
    (``HierarchicalAssociator.recognise_sequence``) instead of step by step. ``seen``: (n,) bool,
    the steps on which the teacher was seen (the others, whose poses may be NaN, get the index -1;
    over time they only carry the belief on); default all."""
    n = len(stream)
    seen = np.ones(n, bool) if seen is None else np.asarray(seen, bool)
    if seen.shape != (n,):
        raise ValueError(f"seen must have one entry per step ({n}), got shape {seen.shape}")
    if not seen.all() and motor_source != "teacher":
        raise ValueError(
            "steps not seen need the directives given (motor_source 'teacher'; infer them on the "
            "whole stream first)"
        )
    out = np.full(n, -1, np.int8)
    vocabulary = {w: i for i, w in enumerate(directives.WORDS)}
    state = None
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        rows = start + np.flatnonzero(seen[start:stop])
        if len(rows) == stop - start:
            vision, _, motor, _ = encode_stream(stream, encoder, motor_source, dt, start, stop)
        else:
            vision, _, motor, _ = encode_stream(stream.rows(rows), encoder, motor_source, dt)
        if over_time:
            result = model.recognise_sequence(
                vision, motor, motor_weight=motor_weight, seen=seen[start:stop], state=state
            )
            state = result.state
            out[rows] = [vocabulary[w] for w in result.words[seen[start:stop]]]
        else:
            words = model.recognise_batch(vision, motor, motor_weight=motor_weight).words
            out[rows] = [vocabulary[w] for w in words]
    return out


@dataclasses.dataclass
class ObservedStream:
    """A teacher stream seen through the student's vision, with the truth beside it.

    Attributes:
      truth: the stream with the simulator's poses.
      observed: the same steps with the poses the student estimated (rows of NaN where the teacher
        was not known; use ``seen``).
      seen: (n,) bool, the student had a pose estimate of the teacher.
    """

    truth: TeacherStream
    observed: TeacherStream
    seen: np.ndarray


def watch_with_vision(
    seed: int,
    n_steps: int,
    vision_mode: str,
    width: int = 320,
    height: int = 240,
    progress: bool = True,
    task: TaskConfig = TaskConfig(),
    perturbations: PerturbationConfig = PerturbationConfig(),
    self_localisation: str = "landmarks",
    overhead_registration: str = "believed",
) -> ObservedStream:
    """Runs the environment (``task``, with the teacher) with the teacher looping and the student
    watching through its camera (``vision_mode`` 'overhead' or 'head', frames of ``width`` x
    ``height`` pixels; the head mode's own pose by ``self_localisation``, see
    ``observers.StudentVision``; the overhead camera's pose by ``overhead_registration``) as
    ``perturbations`` make it see (their randomness keyed by ``seed``); returns what it saw
    beside the truth."""
    if vision_mode not in ("overhead", "head"):
        raise ValueError(f"vision_mode must be 'overhead' or 'head', got {vision_mode!r}")
    if n_steps <= 0:
        raise ValueError(f"n_steps must be positive, got {n_steps}")
    env = load(
        task, seed=seed, with_teacher=True, cameras=(vision_mode,), width=width, height=height
    )
    timestep = env.reset()
    calibration = Calibration(env.physics, width, height)
    vision = student_vision(
        vision_mode,
        calibration,
        perturbations,
        env.task.control_timestep,
        seed,
        self_localisation=self_localisation,
        overhead_registration=overhead_registration,
    )
    start = np.asarray(timestep.observation["student_pose"])
    vision.reset(start, timestep.observation["student_wheel_angles"])
    spec = env.action_spec()
    dt = env.task.control_timestep
    truth_world = np.empty((n_steps, 3))
    seen_world = np.full((n_steps, 3), np.nan)
    word = np.empty(n_steps, np.int8)
    directive = np.empty(n_steps, np.int8)
    bar = tqdm(
        total=n_steps, desc=f"watching ({vision_mode} camera)", unit="step", disable=not progress
    )
    for i in range(n_steps):
        # The observation at this step: the teacher's pose now and the directive it now chooses.
        # The pose at the step's start (seen and true); the word and directive the teacher chooses
        # there are reported by the observation after the step.
        estimate = vision.update(timestep.observation, i * dt, dt)["teacher"]
        seen_world[i] = pose_or_nan(estimate)
        truth_world[i] = timestep.observation["teacher_pose"]
        timestep = env.step(make_action(spec, (0.0, 0.0), vision.head_command))
        word[i] = timestep.observation["teacher_word"]
        directive[i] = timestep.observation["teacher_directive"]
        bar.update(1)
    bar.close()
    env.close()
    changed = np.concatenate([[False], directive[1:] != directive[:-1]])
    truth = _stream(truth_world, word, directive, changed)
    observed = _stream(seen_world, word, directive, changed)
    return ObservedStream(truth, observed, np.all(np.isfinite(seen_world), axis=1))


def perturbed_truth(
    stream: TeacherStream, n_steps: int, perturbations: PerturbationConfig, dt: float, seed
) -> ObservedStream:
    """Returns the first ``n_steps`` of a recorded ``stream`` as a student in the 'truth' mode
    sees them under ``perturbations.perception`` (noise, latency, dropout, occlusion of the
    simulator's teacher poses; their randomness keyed by ``seed``), beside the truth."""
    stream = stream.rows(slice(0, min(n_steps, len(stream))))
    corruptor = PoseCorruptor(perturbations.perception, dt, rng_for(seed, "vision"), ("teacher",))
    seen_world = np.full((len(stream), 3), np.nan)
    for i, pose in enumerate(stream.pose_world.astype(float)):
        seen_world[i] = pose_or_nan(corruptor.step({"teacher": pose})["teacher"])
    truth = _stream(
        stream.pose_world.astype(float), stream.word, stream.directive, stream.motor_changed
    )
    observed = _stream(seen_world, stream.word, stream.directive, stream.motor_changed)
    return ObservedStream(truth, observed, np.all(np.isfinite(seen_world), axis=1))


def _stream(pose_world, word, directive, changed) -> TeacherStream:
    finite = np.all(np.isfinite(pose_world), axis=1)
    wall = np.full_like(pose_world, np.nan)
    if np.any(finite):
        x, y, phi, _ = world_to_wall_batch(*pose_world[finite].T)
        wall[finite] = np.column_stack([x, y, phi])
    return TeacherStream(
        pose_world.astype(np.float32),
        wall.astype(np.float32),
        word.copy(),
        directive.copy(),
        changed.copy(),
    )


def recognise_observed(
    model: Associator,
    observed: ObservedStream,
    encoder,
    motor_source: str,
    dt: float = 0.1,
    motor_weight: float = 1.0,
    over_time: bool = False,
) -> CameraRecognition:
    """Recognition on the steps the student saw, from its estimates and, paired, from the truth
    (``over_time``: see ``recognise_stream``; the truth then has the same gaps as the camera)."""
    seen = observed.seen
    rows = np.flatnonzero(seen)
    tables = {}
    for name, stream in (("vision", observed.observed), ("truth_same_steps", observed.truth)):
        stream = stream.rows(slice(None))
        if motor_source == "vision":
            stream.directive = inferred_directives(stream.pose_world.astype(float), dt)
        recognised = recognise_stream(
            model,
            stream,
            encoder,
            "teacher",
            dt,
            motor_weight=motor_weight,
            over_time=over_time,
            seen=seen,
        )[rows]
        tables[name] = table(stream.word[rows], recognised)
    return CameraRecognition(
        steps=int(len(seen)),
        seen_fraction=float(seen.mean()) if len(seen) else 0.0,
        vision=tables["vision"],
        truth_same_steps=tables["truth_same_steps"],
    )


def teacher_position_error_cm(observed: ObservedStream) -> ErrorSummary:
    """Returns the tracked teacher's position error (cm) on the steps it was seen."""
    seen = observed.seen
    error = np.hypot(
        *(observed.observed.pose_world[seen, :2] - observed.truth.pose_world[seen, :2]).T
    )
    return ErrorSummary(float(np.median(error) * 100), float(np.percentile(error, 95) * 100))
