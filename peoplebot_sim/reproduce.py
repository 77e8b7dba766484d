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

Then ``results.json`` and ``results.md``.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import json
import math
import multiprocessing
import pathlib
import platform
import shutil
import time

import numpy as np
from tqdm import tqdm

from associator import encoding, persistence
from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator
from peoplebot_sim import directives, learning, recognition, report
from peoplebot_sim.observers import check_vision_mode
from peoplebot_sim.runstate import RunState
from peoplebot_sim.streams import TeacherStream, generate_resumable

STAGES = ("streams", "learning", "recognition", "performance", "figures", "videos")


@dataclasses.dataclass(frozen=True)
class ReproduceConfig:
    """The experiment's settings.

    Attributes:
      seed: one seed for everything (streams, network, trials).
      vision: how the student sees the robots: 'truth', 'overhead' or 'head'.
      motor_source: 'teacher' (the teacher's directive is given, as in the paper) or 'vision'
        (inferred from the observed motion).
      train_steps, test_steps: teacher control steps watched for learning and for Table I.
      vision_test_steps: steps watched through the camera for recognition (camera modes only:
        rendering and tracking run at about 50-100 steps/s on 2 cores).
      trials: random starts per word and policy for the success rates.
      trial_seconds: the length of a trial.
      videos: render the performance videos.
      video_width, video_height: their size.
      workers: parallel processes for streams and trials.
      network: Associator hyper-parameters, as (name, value) pairs; the defaults otherwise (the
        paper's values, and our documented choices where the paper is silent).
      drive: how the student's motor area drives its wheels while performing: 'graded' (the
        reconstructed activations set the wheel speeds) or 'directive' (the strongest unit's
        directive at its fixed speeds).
      hierarchical: also train and evaluate the two-level associator
        (``associator.hierarchy``) on the same streams, as a second row beside the paper's
        network (recognition and performance).
    """

    seed: int = 0
    vision: str = "truth"
    motor_source: str = "teacher"
    train_steps: int = 1_000_000
    test_steps: int = 1_000_000
    vision_test_steps: int = 20_000
    trials: int = 50
    trial_seconds: float = 60.0
    videos: bool = True
    video_width: int = 480
    video_height: int = 360
    workers: int = 2
    network: tuple = ()
    drive: str = "graded"
    hierarchical: bool = True

    def __post_init__(self):
        check_vision_mode(self.vision)
        learning.check_motor_source(self.motor_source)
        if self.drive not in ("graded", "directive"):
            raise ValueError(f"unknown drive {self.drive!r}; allowed: graded, directive")
        for name in ("train_steps", "test_steps", "vision_test_steps", "trials", "workers"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if not (math.isfinite(self.trial_seconds) and self.trial_seconds >= 5):
            raise ValueError(f"trial_seconds must be at least 5 s, got {self.trial_seconds!r}")

    @classmethod
    def quick(cls, **overrides) -> ReproduceConfig:
        """Returns the same stages at a small scale (about 3 minutes on 2 cores)."""
        values = dict(
            train_steps=60_000,
            test_steps=20_000,
            vision_test_steps=600,
            trials=3,
            trial_seconds=40.0,
            video_width=320,
            video_height=240,
        )
        values.update(overrides)
        return cls(**values)

    def network_params(self) -> dict:
        params = {k: tuple(v) if isinstance(v, list) else v for k, v in dict(self.network).items()}
        params.setdefault("n_steps_total", self.train_steps)
        params.setdefault("rng", self.seed)
        return params

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["network"] = dict(self.network)
        return d


def _stream_worker(seed, n_steps, folder, name, progress_file):
    import peoplebot_sim  # noqa: F401  (headless rendering set before mujoco loads)

    return str(generate_resumable(seed, n_steps, folder, name, progress_file=progress_file))


def _poll(futures: list, progress_files: list, total: int, desc: str):
    bar = tqdm(total=total, desc=desc, unit="step")
    while not all(f.done() for f in futures):
        done = 0
        for path in progress_files:
            try:
                done += int(pathlib.Path(path).read_text() or 0)
            except (FileNotFoundError, ValueError):
                pass
        bar.n = done
        bar.refresh()
        time.sleep(1.0)
    bar.n = total
    bar.close()
    return [f.result() for f in futures]


def stage_streams(config: ReproduceConfig, folder: pathlib.Path) -> dict:
    streams = folder / "streams"
    jobs = [
        (config.seed * 2 + 1, config.train_steps, "train"),
        (config.seed * 2 + 2, config.test_steps, "test"),
    ]
    progress = [streams / f"{name}.progress" for _, _, name in jobs]
    streams.mkdir(parents=True, exist_ok=True)
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(
        max_workers=min(config.workers, 2), mp_context=context
    ) as pool:
        futures = [
            pool.submit(_stream_worker, seed, n, str(streams), name, str(p))
            for (seed, n, name), p in zip(jobs, progress, strict=True)
        ]
        paths = _poll(
            futures,
            progress,
            config.train_steps + config.test_steps,
            "teacher streams (train + test)",
        )
    for p in progress:
        p.unlink(missing_ok=True)
    out = {}
    for (_, _, name), path in zip(jobs, paths, strict=True):
        stream = TeacherStream.load(path)
        out[name] = {
            "path": str(pathlib.Path(path).relative_to(folder)),
            "steps": len(stream),
            "time_share": {
                w: float(np.mean(stream.word == i)) for i, w in enumerate(directives.WORDS)
            },
        }
    return out


def stage_learning(config: ReproduceConfig, folder: pathlib.Path, encoder) -> dict:
    stream = TeacherStream.load(folder / "streams" / "train.npz")
    model = Associator(**config.network_params())
    model = learning.train(
        model, stream, folder / "network.npz", encoder=encoder, motor_source=config.motor_source
    )
    out = {
        "network": "network.npz",
        "steps": int(model.n_steps_),
        "params": _listed(model.get_params()),
    }
    if config.hierarchical:
        upper = learning.train(
            HierarchicalAssociator(**config.network_params()),
            stream,
            folder / "hierarchical.npz",
            encoder=encoder,
            motor_source=config.motor_source,
            desc="learning by watching (hierarchical)",
        )
        out["hierarchical"] = {
            "network": "hierarchical.npz",
            "steps": int(upper.n_steps_),
            "params": _listed(upper.get_params()),
        }
    return out


def _listed(params: dict) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in params.items()}


def stage_recognition(config: ReproduceConfig, folder: pathlib.Path, model, encoder) -> dict:
    stream = TeacherStream.load(folder / "streams" / "test.npz")
    out = {"readouts": dict(recognition.READOUTS)}
    for name, gain in recognition.READOUTS.items():
        recognised = recognition.recognise_stream(
            model, stream, encoder, config.motor_source, motor_gain=gain
        )
        key = "truth" if name == "paper" else f"truth_{name}"
        out[key] = recognition.table(recognition.confusion_counts(stream.word, recognised))
        if name == "paper":
            np.save(folder / "recognised_test.npy", recognised)
    hierarchical = None
    if config.hierarchical:
        hierarchical = persistence.load(folder / "hierarchical.npz")
        recognised = recognition.recognise_stream(
            hierarchical, stream, encoder, config.motor_source
        )
        out["truth_hierarchical"] = recognition.table(
            recognition.confusion_counts(stream.word, recognised)
        )
        recognised = recognition.recognise_stream(
            hierarchical, stream, encoder, config.motor_source, over_time=True
        )
        out["truth_hierarchical_over_time"] = recognition.table(
            recognition.confusion_counts(stream.word, recognised)
        )
    if config.vision != "truth":
        observed = recognition.watch_with_vision(
            config.seed * 2 + 3, config.vision_test_steps, config.vision
        )
        out["vision"] = recognition.recognise_observed(
            model, observed, encoder, config.motor_source
        )
        out["vision_motor_weighted"] = recognition.recognise_observed(
            model,
            observed,
            encoder,
            config.motor_source,
            motor_gain=recognition.READOUTS["motor_weighted"],
        )
        if hierarchical is not None:
            out["vision_hierarchical"] = recognition.recognise_observed(
                hierarchical, observed, encoder, config.motor_source
            )
            out["vision_hierarchical_over_time"] = recognition.recognise_observed(
                hierarchical, observed, encoder, config.motor_source, over_time=True
            )
        error = np.hypot(
            *(
                observed.observed.pose_world[observed.seen, :2]
                - observed.truth.pose_world[observed.seen, :2]
            ).T
        )
        out["vision"]["teacher_position_error_cm"] = {
            "median": float(np.median(error) * 100),
            "p95": float(np.percentile(error, 95) * 100),
        }
    return out


#: Settings that decide the streams and the network: runs agreeing on them can share both.
SHARED_LEARNING_SETTINGS = (
    "seed",
    "motor_source",
    "train_steps",
    "test_steps",
    "network",
    "hierarchical",
)


def reuse_learning(state: RunState, source) -> None:
    """Copies the streams and the trained network of the finished run in ``source`` into this run,
    if both runs agree on ``SHARED_LEARNING_SETTINGS`` (so vision modes can be compared on one
    network); raises ValueError otherwise."""
    source = pathlib.Path(source)
    try:
        other = json.loads((source / "state.json").read_text())
    except (FileNotFoundError, json.JSONDecodeError) as error:
        raise ValueError(f"{source} is not a run folder ({error})") from None
    differing = [
        k for k in SHARED_LEARNING_SETTINGS if other["config"].get(k) != state.data["config"].get(k)
    ]
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
    if state.data["config"].get("hierarchical"):
        shutil.copyfile(source / "hierarchical.npz", state.folder / "hierarchical.npz")
    for stage in ("streams", "learning"):
        state.finish(stage, {**other["stages"][stage], "reused_from": str(source)})
        state.data.setdefault("seconds", {})[stage] = 0.0


def run(config: ReproduceConfig, out_dir, fresh: bool = False, reuse_from=None) -> dict:
    """Runs (or resumes) the whole experiment in ``out_dir``; returns the results.

    ``reuse_from``: a finished run folder whose streams and network to take (see
    ``reuse_learning``).
    """
    from peoplebot_sim import trials as trial_runner  # imports mujoco; after MUJOCO_GL is set

    folder = pathlib.Path(out_dir)
    state = RunState(folder, config.as_dict(), fresh=fresh)
    if reuse_from is not None:
        reuse_learning(state, reuse_from)
    encoder = encoding.VisionEncoder()
    timings = state.data.setdefault("seconds", {})
    for stage in STAGES:
        if state.done(stage):
            print(f"[{stage}] done earlier, kept")
            continue
        if stage == "videos" and not config.videos:
            continue
        start = time.perf_counter()
        if stage == "streams":
            result = stage_streams(config, folder)
        elif stage == "learning":
            result = stage_learning(config, folder, encoder)
        else:
            model = persistence.load(folder / "network.npz")
            if stage == "recognition":
                result = stage_recognition(config, folder, model, encoder)
            elif stage == "performance":
                result = trial_runner.stage_performance(config, folder)
            elif stage == "figures":
                result = report.figures(config, folder, model, encoder)
            else:
                result = trial_runner.stage_videos(config, folder)
        timings[stage] = time.perf_counter() - start
        state.finish(stage, result)
    results = report.results(config, state, folder)
    (folder / "results.json").write_text(json.dumps(results, indent=2))
    (folder / "results.md").write_text(report.markdown(results))
    return results


def versions() -> dict:
    """Returns the versions of the packages the results depend on."""
    from importlib import metadata

    names = ("peoplebot-imitation", "mujoco", "dm-control", "numpy", "opencv-python-headless")
    out = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out
