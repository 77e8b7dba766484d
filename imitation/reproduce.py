"""``peoplebot reproduce``: the paper's experiment end to end, in physics.

Stages, each checkpointed in the run folder (``state.json``), so an interrupted run resumes:

1. ``streams``: the teacher loops go-pick-lift while the student watches; two streams (training and
   test) are generated in parallel processes, in checkpointed chunks.
2. ``learning``: the associator learns by wake-sleep from the training stream (checkpointed).
3. ``recognition``: Table I on the test stream; with a camera vision mode also on steps watched
   through the camera, paired with the truth on the same steps.
4. ``performance``: success rates per word from random starts, student and teacher (reference).
5. ``figures``: Figs. 3-7 of the paper from the trained network, and Fig. 4's traces.
6. ``videos``: the teacher and each student performing each word from the paper's start, and the
   three side by side (``imitation.videos``).

The run's configuration is written first, as ``config.toml``; then ``results.json``,
``results.md`` and the report page ``index.html`` (``imitation.page``).
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import shutil
import time

import numpy as np

from associator import encoding, persistence
from associator.hierarchy import PERFORM_ONLY_PARAMS, HierarchicalAssociator
from associator.network import Associator
from imitation import config as run_config
from imitation import learning, page, randomisation, recognition, report, storage, trials, videos
from imitation.config import RunConfig
from imitation.parallel import run_parallel
from imitation.results import (
    READOUTS,
    LearningResult,
    NetworkSummary,
    PerformanceResult,
    RecognitionResult,
    Results,
    StreamsResult,
    StreamSummary,
    package_versions,
)
from imitation.runstate import RunState
from imitation.streams import (
    TeacherStream,
    cached_stream,
    generate_resumable,
    stream_provenance,
)
from peoplebot_sim import directives
from perception.wallframe import ArenaGeometry

STAGES = ("streams", "learning", "recognition", "performance", "figures", "videos")


def _stream_worker(job, config: RunConfig, folder: str, cache, progress_file: str) -> str:
    import peoplebot_sim  # noqa: F401  (headless rendering set before mujoco loads)

    seed, n_steps, name = job
    task = config.task_config()
    if cache is None:
        path = generate_resumable(
            seed, n_steps, folder, name, config=task, progress_file=progress_file
        )
        return str(path)
    shared = cached_stream(seed, n_steps, cache, task, progress_file)
    return str(storage.link(shared, pathlib.Path(folder) / f"{name}.npz"))


def stage_streams(config: RunConfig, folder: pathlib.Path, cache=None) -> dict:
    """Generates the training and test streams (or takes them from ``cache``, a folder shared by
    runs, where they are generated once); returns their summaries by name."""
    streams = folder / "streams"
    jobs = [
        (config.seed * 2 + 1, config.learning.train_steps, "train"),
        (config.seed * 2 + 2, config.learning.test_steps, "test"),
    ]
    streams.mkdir(parents=True, exist_ok=True)
    paths = run_parallel(
        _stream_worker,
        jobs,
        (config, str(streams), None if cache is None else str(cache)),
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
    """Trains the paper's network and, if enabled, the hierarchical associator (checkpointed),
    on the training stream as the student sees it (``imitation.randomisation``: the stream
    itself unless randomisation is on)."""
    stream_path = folder / "streams" / "train.npz"
    dt = config.task.control_timestep
    stream, _ = randomisation.randomised_stream(
        TeacherStream.load(stream_path), config.randomisation, dt, config.seed
    )
    motor_source = config.learning.motor_source
    # What the networks learn from: checkpoints made from anything else are never resumed.
    provenance = {
        "stream": stream_provenance(stream_path),
        "motor_source": motor_source,
        "seed": config.seed,
    }
    if config.randomisation.active:
        provenance["randomisation"] = config.to_dict()["randomisation"]
    model = learning.train(
        Associator(**config.network_params()),
        stream,
        folder / "network.npz",
        encoder=encoder,
        motor_source=motor_source,
        dt=dt,
        provenance=provenance,
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
            provenance=provenance,
        )
        hierarchical = NetworkSummary(
            "hierarchical.npz", int(upper.n_steps_), _listed(upper.get_params())
        )
    return LearningResult(paper, hierarchical)


def _listed(params: dict) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in params.items()}


def stage_recognition(config: RunConfig, folder: pathlib.Path, model, encoder) -> RecognitionResult:
    """Table I on the test stream for every read-out; through the camera in camera modes, and in
    the 'truth' mode under perception faults on the stream's first ``vision.test_steps`` steps
    as the faults make the student see them."""
    stream = TeacherStream.load(folder / "streams" / "test.npz")
    dt = config.task.control_timestep
    motor_source = config.learning.motor_source

    def on_stream(network, **readout):
        recognised = recognition.recognise_stream(
            network, stream, encoder, motor_source, dt, **readout
        )
        return recognised, recognition.table(stream.word, recognised)

    recognised, truth = on_stream(model, motor_weight=READOUTS["paper"])
    storage.save_npy(folder / "recognised_test.npy", recognised)
    values = {
        "truth": truth,
        "truth_motor_weighted": on_stream(model, motor_weight=READOUTS["motor_weighted"])[1],
    }
    hierarchical = None
    if config.hierarchical.enabled:
        hierarchical = persistence.load(folder / "hierarchical.npz")
        values["truth_hierarchical"] = on_stream(hierarchical)[1]
        values["truth_hierarchical_over_time"] = on_stream(hierarchical, over_time=True)[1]
    observed = None
    if config.vision.mode == "truth" and config.perturbations.perception.active:
        observed = recognition.perturbed_truth(
            stream, config.vision.test_steps, config.perturbations, dt, config.seed * 2 + 3
        )
    elif config.vision.mode != "truth":
        observed = recognition.watch_with_vision(
            config.seed * 2 + 3,
            config.vision.test_steps,
            config.vision.mode,
            config.vision.width,
            config.vision.height,
            task=config.world_config(),
            perturbations=config.perturbations,
            self_localisation=config.vision.self_localisation,
            overhead_registration=config.vision.overhead_registration,
        )
    if observed is not None:

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
    "randomisation",
)


def _learning_part(config: dict, section: str):
    """Returns ``config[section]`` as far as it decides the streams and networks: the hierarchical
    section without its performing-only settings (``PERFORM_ONLY_PARAMS``)."""
    value = config.get(section)
    if section == "hierarchical" and isinstance(value, dict):
        return {k: v for k, v in value.items() if k not in PERFORM_ONLY_PARAMS}
    return value


def _perform_settings(config: dict) -> dict:
    """Returns the hierarchical section's performing-only settings of a run's configuration."""
    section = config.get("hierarchical") or {}
    return {k: section[k] for k in PERFORM_ONLY_PARAMS if k in section}


def _set_perform_settings(path: pathlib.Path, settings: dict) -> dict:
    """Rewrites the hierarchical network saved at ``path`` (its metadata kept) to perform with
    ``settings``; returns its hyper-parameters as the learning stage records them."""
    model = persistence.load(path)
    for name, value in settings.items():
        setattr(model, name, value)
    model.validate_params()
    learning.save_atomically(model, path, persistence.load_metadata(path))
    return _listed(model.get_params())


def reuse_learning(state: RunState, source) -> None:
    """Copies the streams and the trained networks of the finished run in ``source`` into this
    run, if both were made by this version, agree on ``SHARED_LEARNING_SECTIONS`` (so vision modes
    can be compared on one network) and the source's files are intact; raises ValueError
    otherwise. The hierarchical network may differ in its performing-only settings
    (``PERFORM_ONLY_PARAMS``: read-outs compared on one network): its copy performs with this
    run's."""
    source = pathlib.Path(source)
    try:
        other = json.loads((source / "state.json").read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"--reuse-from {source} is not a run folder ({error})") from None
    if not isinstance(other, dict) or not isinstance(other.get("config"), dict):
        raise ValueError(f"--reuse-from {source} is not a run folder (its state.json is not one)")
    if other.get("version") != state.version:
        raise ValueError(
            f"--reuse-from {source} was made by peoplebot-imitation {other.get('version')}, this "
            f"is {state.version}; it cannot be reused"
        )
    mine, theirs = state.data["config"], other["config"]
    differing = [
        k for k in SHARED_LEARNING_SECTIONS if _learning_part(theirs, k) != _learning_part(mine, k)
    ]
    if differing:
        raise ValueError(
            f"--reuse-from {source} was run with other {', '.join(differing)}; it cannot be reused"
        )
    if state.done("learning"):
        return
    copied = {}
    for stage in ("streams", "learning"):
        if stage not in other.get("stages", {}):
            raise ValueError(f"--reuse-from {source} has not finished its {stage} stage")
        copied[stage] = []
        for name, digest in other.get("artifacts", {}).get(stage, {}).items():
            path = source / name
            if not path.is_file() or storage.file_digest(path) != digest:
                raise ValueError(
                    f"--reuse-from {source}: {name} is missing or changed since its run; it "
                    "cannot be reused"
                )
            target = state.folder / name
            target.parent.mkdir(parents=True, exist_ok=True)
            tmp = storage.temporary_name(target)
            shutil.copyfile(path, tmp)
            copied[stage].append(storage.commit(tmp, target))
    results = {stage: {**other["stages"][stage], "reused_from": str(source)} for stage in copied}
    settings = _perform_settings(mine)
    hierarchical = results["learning"].get("hierarchical")
    if hierarchical is not None and settings != _perform_settings(theirs):
        path = state.folder / hierarchical["network"]
        hierarchical = {**hierarchical, "params": _set_perform_settings(path, settings)}
        results["learning"]["hierarchical"] = hierarchical
    for stage in ("streams", "learning"):
        state.finish(stage, results[stage], copied[stage])


def run(
    config: RunConfig, out_dir, fresh: bool = False, reuse_from=None, stream_cache=None
) -> Results:
    """Runs (or resumes) the whole experiment in ``out_dir``; returns the results.

    A finished stage is kept only while every file it wrote is unchanged; otherwise it and the
    stages after it run again. ``fresh`` removes everything an earlier run wrote first.
    ``reuse_from``: a finished run folder whose streams and network to take (see
    ``reuse_learning``). ``stream_cache``: a folder where runs share their teacher streams (one
    generation per seed, steps and world; ``peoplebot sweep`` passes one).
    """
    folder = pathlib.Path(out_dir)
    state = RunState(folder, config.to_dict(), fresh=fresh, defaults=RunConfig().to_dict())
    try:
        run_config.dump(config, folder / "config.toml")
        _drop_changed_stages(state, reusing=reuse_from is not None)
        if reuse_from is not None:
            reuse_learning(state, reuse_from)
        encoder = _encoder()
        for i, stage in enumerate(STAGES):
            if state.done(stage):
                print(f"[{stage}] done earlier, kept")
                continue
            if not state.replacing(stage) and any(state.done(s) for s in STAGES[i + 1 :]):
                state.forget(STAGES[i + 1 :])  # they read this stage's files, about to change
            if stage == "videos" and not config.videos.enabled:
                continue
            start = time.perf_counter()
            result, files = _run_stage(stage, config, folder, encoder, stream_cache)
            state.finish(stage, result, files, time.perf_counter() - start)
        results = collect(config, state)
        storage.write_json(folder / "results.json", results.to_json())
        results_md = report.markdown(results)
        storage.write_text(folder / "results.md", results_md)
        page.write_run_page(folder, results_md, results.figures, results.videos)
        return results
    finally:
        state.close()


def _run_stage(stage: str, config: RunConfig, folder: pathlib.Path, encoder, cache) -> tuple:
    """Runs one stage; returns its result (JSON values) and the files it wrote."""
    if stage == "streams":
        summaries = stage_streams(config, folder, cache)
        return (
            {k: v.to_json() for k, v in summaries.items()},
            [folder / v.path for v in summaries.values()],
        )
    if stage == "learning":
        learned = stage_learning(config, folder, encoder)
        networks = [learned.paper] + ([learned.hierarchical] if learned.hierarchical else [])
        return learned.to_json(), [folder / n.network for n in networks]
    model = persistence.load(folder / "network.npz")
    if stage == "recognition":
        return stage_recognition(config, folder, model, encoder).to_json(), [
            folder / "recognised_test.npy"
        ]
    if stage == "performance":
        result = trials.stage_performance(config, folder).to_json()
        return result, [folder / "performance_trials.json", folder / "fig4_traces.npz"]
    if stage == "figures":
        paths = report.figures(config, folder, model, encoder)
        return paths, [folder / p for p in paths.values()]
    filmed = videos.stage_videos(config, folder)
    return filmed, [folder / name for name in (*filmed["videos"], *filmed.get("mcap", ()))]


def _drop_changed_stages(state: RunState, reusing: bool = False) -> None:
    """Marks each finished stage whose files are missing or changed to run again. The stages after
    it are kept if the rerun writes the same files (``RunState.replace``); with ``reusing`` (a
    run on another run's streams and networks) a changed streams or learning stage is forgotten
    with every stage after it, so that both are copied again."""
    for i, stage in enumerate(STAGES):
        if state.done(stage) and not state.intact(stage):
            if reusing and stage in ("streams", "learning"):
                print(
                    f"[{stage}] its files are missing or changed: it runs again, with the "
                    "stages after it"
                )
                state.forget(STAGES[i:])
                return
            print(
                f"[{stage}] its files are missing or changed: it runs again (the stages after "
                "it too if its files come out different)"
            )
            state.replace(stage, STAGES[i + 1 :])


def collect(config: RunConfig, state: RunState) -> Results:
    """Returns the run's results from its finished stages."""
    stages = state.data["stages"]

    def record(stage, kind):
        return kind.from_json(stages[stage]) if stage in stages else None

    return Results(
        vision=config.vision.mode,
        motor_source=config.learning.motor_source,
        seed=config.seed,
        recognition=record("recognition", RecognitionResult),
        performance=record("performance", PerformanceResult),
        streams=record("streams", StreamsResult),
        learning=record("learning", LearningResult),
        figures=stages.get("figures"),
        videos=stages.get("videos", {}).get("videos"),
        seconds_per_stage=dict(state.data["seconds"]),
        config=config.to_dict(),
        versions=package_versions(),
    )
