"""``peoplebot reproduce``: the paper's experiment end to end, in physics.

Stages, each checkpointed in the run folder (``state.json``), so an interrupted run resumes:

1. ``streams``: the teacher loops go-pick-lift while the student watches; two streams (training and
   test) are generated in parallel processes, in checkpointed chunks.
2. ``learning``: the associator learns by wake-sleep from the training stream (checkpointed).
3. ``recognition``: Table I on the test stream; with a camera vision mode also on steps watched
   through the camera, paired with the truth on the same steps.
4. ``performance``: success rates per word from random starts, student and teacher (reference).
5. ``figures``: Figs. 3-7 of the paper from the trained network, and Fig. 4's traces.
6. ``videos``: the student performing each word from the paper's start.

The run's configuration is written first, as ``config.toml``; then ``results.json`` and
``results.md``.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import shutil
import time

import numpy as np

from associator import encoding, persistence
from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator
from imitation import config as run_config
from imitation import learning, recognition, report, trials
from imitation.config import RunConfig
from imitation.parallel import run_parallel
from imitation.results import (
    READOUTS,
    LearningResult,
    NetworkSummary,
    PerformanceResult,
    RecognitionResult,
    Results,
    StreamSummary,
    package_versions,
)
from imitation.runstate import RunState
from imitation.streams import TeacherStream, generate_resumable
from peoplebot_sim import directives
from perception.wallframe import ArenaGeometry

STAGES = ("streams", "learning", "recognition", "performance", "figures", "videos")


def _stream_worker(job, config: RunConfig, folder: str, progress_file: str) -> str:
    import peoplebot_sim  # noqa: F401  (headless rendering set before mujoco loads)

    seed, n_steps, name = job
    path = generate_resumable(
        seed, n_steps, folder, name, config=config.task_config(), progress_file=progress_file
    )
    return str(path)


def stage_streams(config: RunConfig, folder: pathlib.Path) -> dict:
    """Generates the training and test streams; returns their summaries by name."""
    streams = folder / "streams"
    jobs = [
        (config.seed * 2 + 1, config.learning.train_steps, "train"),
        (config.seed * 2 + 2, config.learning.test_steps, "test"),
    ]
    streams.mkdir(parents=True, exist_ok=True)
    paths = run_parallel(
        _stream_worker,
        jobs,
        (config, str(streams)),
        min(config.workers, 2),
        streams,
        "teacher streams (train + test)",
        config.learning.train_steps + config.learning.test_steps,
    )
    out = {}
    for (_, _, name), path in zip(jobs, paths, strict=True):
        stream = TeacherStream.load(path)
        out[name] = StreamSummary(
            path=str(pathlib.Path(path).relative_to(folder)),
            steps=len(stream),
            time_share={
                w: float(np.mean(stream.word == i)) for i, w in enumerate(directives.WORDS)
            },
        )
    return out


def _encoder() -> encoding.VisionEncoder:
    """Returns the vision encoder of the world's arena."""
    return encoding.VisionEncoder(half_side_m=ArenaGeometry().half_side_m)


def stage_learning(config: RunConfig, folder: pathlib.Path, encoder) -> LearningResult:
    """Trains the paper's network and, if enabled, the hierarchical associator (checkpointed)."""
    stream = TeacherStream.load(folder / "streams" / "train.npz")
    dt = config.task.control_timestep
    motor_source = config.learning.motor_source
    model = learning.train(
        Associator(**config.network_params()),
        stream,
        folder / "network.npz",
        encoder=encoder,
        motor_source=motor_source,
        dt=dt,
    )
    paper = NetworkSummary("network.npz", int(model.n_steps_), _listed(model.get_params()))
    hierarchical = None
    if config.hierarchical.enabled:
        upper = learning.train(
            HierarchicalAssociator(
                lower=Associator(**config.network_params()),
                **config.hierarchical.hyper_parameters(),
            ),
            stream,
            folder / "hierarchical.npz",
            encoder=encoder,
            motor_source=motor_source,
            dt=dt,
            desc="learning by watching (hierarchical)",
        )
        hierarchical = NetworkSummary(
            "hierarchical.npz", int(upper.n_steps_), _listed(upper.get_params())
        )
    return LearningResult(paper, hierarchical)


def _listed(params: dict) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in params.items()}


def stage_recognition(config: RunConfig, folder: pathlib.Path, model, encoder) -> RecognitionResult:
    """Table I on the test stream for every read-out; through the camera in camera modes."""
    stream = TeacherStream.load(folder / "streams" / "test.npz")
    dt = config.task.control_timestep
    motor_source = config.learning.motor_source

    def on_stream(network, **readout):
        recognised = recognition.recognise_stream(
            network, stream, encoder, motor_source, dt, **readout
        )
        return recognised, recognition.table(stream.word, recognised)

    recognised, truth = on_stream(model, motor_weight=READOUTS["paper"])
    np.save(folder / "recognised_test.npy", recognised)
    values = {
        "truth": truth,
        "truth_motor_weighted": on_stream(model, motor_weight=READOUTS["motor_weighted"])[1],
    }
    hierarchical = None
    if config.hierarchical.enabled:
        hierarchical = persistence.load(folder / "hierarchical.npz")
        values["truth_hierarchical"] = on_stream(hierarchical)[1]
        values["truth_hierarchical_over_time"] = on_stream(hierarchical, over_time=True)[1]
    if config.vision.mode != "truth":
        observed = recognition.watch_with_vision(
            config.seed * 2 + 3,
            config.vision.test_steps,
            config.vision.mode,
            config.vision.width,
            config.vision.height,
            task=config.task_config(),
        )

        def on_camera(network, **readout):
            return recognition.recognise_observed(
                network, observed, encoder, motor_source, dt, **readout
            )

        values["vision"] = dataclasses.replace(
            on_camera(model),
            teacher_position_error_cm=recognition.teacher_position_error_cm(observed),
        )
        values["vision_motor_weighted"] = on_camera(model, motor_weight=READOUTS["motor_weighted"])
        if hierarchical is not None:
            values["vision_hierarchical"] = on_camera(hierarchical)
            values["vision_hierarchical_over_time"] = on_camera(hierarchical, over_time=True)
    return RecognitionResult(**values)


#: Sections of the configuration that decide the streams and the networks: runs agreeing on them
#: can share both.
SHARED_LEARNING_SECTIONS = (
    "seed",
    "task",
    "teacher",
    "drive",
    "learning",
    "network",
    "hierarchical",
)


def reuse_learning(state: RunState, source) -> None:
    """Copies the streams and the trained networks of the finished run in ``source`` into this
    run, if both agree on ``SHARED_LEARNING_SECTIONS`` (so vision modes can be compared on one
    network); raises ValueError otherwise."""
    source = pathlib.Path(source)
    try:
        other = json.loads((source / "state.json").read_text())
    except (FileNotFoundError, NotADirectoryError, json.JSONDecodeError) as error:
        raise ValueError(f"{source} is not a run folder ({error})") from None
    mine = state.data["config"]
    theirs = other.get("config", {}) if isinstance(other, dict) else {}
    differing = [k for k in SHARED_LEARNING_SECTIONS if theirs.get(k) != mine.get(k)]
    if differing:
        raise ValueError(f"{source} was run with other {', '.join(differing)}; it cannot be reused")
    for stage in ("streams", "learning"):
        if stage not in other["stages"]:
            raise ValueError(f"{source} has not finished its {stage} stage")
    if state.done("learning"):
        return
    (state.folder / "streams").mkdir(exist_ok=True)
    for name in ("train", "test"):
        shutil.copyfile(
            source / "streams" / f"{name}.npz", state.folder / "streams" / f"{name}.npz"
        )
    shutil.copyfile(source / "network.npz", state.folder / "network.npz")
    if mine["hierarchical"]["enabled"]:
        shutil.copyfile(source / "hierarchical.npz", state.folder / "hierarchical.npz")
    for stage in ("streams", "learning"):
        state.finish(stage, {**other["stages"][stage], "reused_from": str(source)})
        state.data.setdefault("seconds", {})[stage] = 0.0


def run(config: RunConfig, out_dir, fresh: bool = False, reuse_from=None) -> Results:
    """Runs (or resumes) the whole experiment in ``out_dir``; returns the results.

    ``reuse_from``: a finished run folder whose streams and network to take (see
    ``reuse_learning``).
    """
    folder = pathlib.Path(out_dir)
    state = RunState(folder, config.to_dict(), fresh=fresh)
    run_config.dump(config, folder / "config.toml")
    if reuse_from is not None:
        reuse_learning(state, reuse_from)
    encoder = _encoder()
    timings = state.data.setdefault("seconds", {})
    for stage in STAGES:
        if state.done(stage):
            print(f"[{stage}] done earlier, kept")
            continue
        if stage == "videos" and not config.videos.enabled:
            continue
        start = time.perf_counter()
        if stage == "streams":
            result = {k: v.to_json() for k, v in stage_streams(config, folder).items()}
        elif stage == "learning":
            result = stage_learning(config, folder, encoder).to_json()
        else:
            model = persistence.load(folder / "network.npz")
            if stage == "recognition":
                result = stage_recognition(config, folder, model, encoder).to_json()
            elif stage == "performance":
                result = trials.stage_performance(config, folder).to_json()
            elif stage == "figures":
                result = report.figures(config, folder, model, encoder)
            else:
                result = trials.stage_videos(config, folder)
        timings[stage] = time.perf_counter() - start
        state.finish(stage, result)
    results = collect(config, state)
    (folder / "results.json").write_text(json.dumps(results.to_json(), indent=2))
    (folder / "results.md").write_text(report.markdown(results))
    return results


def collect(config: RunConfig, state: RunState) -> Results:
    """Returns the run's results from its finished stages."""
    stages = state.data["stages"]

    def record(stage, kind):
        return kind.from_json(stages[stage]) if stage in stages else None

    streams = stages.get("streams")
    return Results(
        vision=config.vision.mode,
        motor_source=config.learning.motor_source,
        seed=config.seed,
        recognition=record("recognition", RecognitionResult),
        performance=record("performance", PerformanceResult),
        streams=None
        if streams is None
        else {
            name: StreamSummary.from_json(value)
            for name, value in streams.items()
            if name in ("train", "test")
        },
        learning=record("learning", LearningResult),
        figures=stages.get("figures"),
        videos=stages.get("videos", {}).get("videos"),
        seconds_per_stage=state.data.get("seconds", {}),
        config=config.to_dict(),
        versions=package_versions(),
    )
