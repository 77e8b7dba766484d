"""Learning by watching: teacher streams encoded for the associator, trained with checkpoints.

The stream of what the student observes (the teacher's wall-frame pose, its word and its motor
directive) is encoded as the paper's 96 + 80 + 4 input units and fed to ``Associator.partial_fit`` in
chunks. After every chunk the network (with its random state and step count) is saved, so an
interrupted run resumes where it stopped and ends bit-identical to an uninterrupted one.
"""

from __future__ import annotations

import json
import pathlib

import numpy as np
from tqdm import tqdm

from associator import encoding, persistence
from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator
from imitation import storage
from imitation.streams import TeacherStream
from peoplebot_sim import directives
from perception.motion import DirectiveConfig, infer_directives_batch

MOTOR_SOURCES = ("teacher", "vision")


def check_motor_source(source: str) -> str:
    if source not in MOTOR_SOURCES:
        raise ValueError(f"unknown motor source {source!r}; allowed: {', '.join(MOTOR_SOURCES)}")
    return source


def inferred_directives(
    pose_world: np.ndarray, dt: float, config: DirectiveConfig = DirectiveConfig()
) -> np.ndarray:
    """Returns directive indices (n,), in ``directives.DIRECTIVES`` order, inferred from successive
    world poses (n, 3), causally: step t gets the motion from t-1 to t (step 0 copies step 1);
    where no motion is recognised the previous directive holds."""
    names = infer_directives_batch(pose_world, dt, config)
    index = np.full(len(pose_world), -1, np.int64)
    for i, name in enumerate(directives.DIRECTIVES):
        index[1:][names == name] = i
    if len(index) > 1:
        index[0] = index[1] if index[1] >= 0 else 0
    # Hold the last recognised directive through still or unknown steps.
    valid = index >= 0
    positions = np.where(valid, np.arange(len(index)), 0)
    np.maximum.accumulate(positions, out=positions)
    return np.where(valid[positions], index[positions], 0).astype(np.int8)


def following_directives(stream: TeacherStream, dt: float, start: int, stop: int) -> np.ndarray:
    """Returns the directive indices (stop - start,) inferred from the motion out of each pose of
    rows ``start:stop`` (step t gets the motion from t to t+1; the stream's last step keeps the
    motion into it): what the teacher did at each pose, which ``inferred_directives`` gives one
    step late."""
    n = len(stream)
    lo, hi = max(start - 2, 0), min(stop + 1, n)  # two steps of history, as encode_stream
    inferred = inferred_directives(stream.pose_world[lo:hi].astype(float), dt)
    following = inferred[start - lo + 1 :]
    if stop == n:  # no motion after the last step
        following = np.concatenate([following, inferred[-1:]])
    return following


def encode_stream(
    stream: TeacherStream,
    encoder: encoding.VisionEncoder,
    motor_source: str = "teacher",
    dt: float = 0.1,
    start: int = 0,
    stop: int | None = None,
):
    """Returns ``(vision (n, 96), language (n, 80), motor (n, 4), motor_changed (n,))`` for rows
    ``start:stop`` of a stream; with ``motor_source='vision'`` the directives are inferred from the
    poses' motion instead of taken from the teacher."""
    check_motor_source(motor_source)
    stop = len(stream) if stop is None else stop
    wall = stream.pose_wall[start:stop].astype(float)
    vision = encoder.encode_batch(wall[:, 0], wall[:, 1], wall[:, 2], clip=True)
    words = np.asarray(directives.WORDS)[stream.word[start:stop]]
    language = encoding.encode_words(list(words))
    if motor_source == "teacher":
        motor_index = stream.directive[start:stop].astype(int)
        changed = stream.motor_changed[start:stop]
    else:
        # Two steps of history, so that chunk boundaries do not change the result.
        lo = max(start - 2, 0)
        inferred = inferred_directives(stream.pose_world[lo:stop].astype(float), dt)
        changed = np.concatenate([[False], inferred[1:] != inferred[:-1]])
        motor_index = inferred[start - lo :].astype(int)
        changed = changed[start - lo :]
    motor = encoding.encode_motor_batch(motor_index)
    return vision, language, motor, changed


def train(
    model: Associator,
    stream: TeacherStream,
    checkpoint_path,
    *,
    encoder: encoding.VisionEncoder,
    motor_source: str = "teacher",
    dt: float = 0.1,
    chunk: int = 50_000,
    progress: bool = True,
    desc: str = "learning by watching",
    provenance: dict | None = None,
):
    """Trains ``model`` (an ``Associator`` or a ``HierarchicalAssociator``) on ``stream``, resuming
    from ``checkpoint_path`` if it holds a partly trained network; saves the network there after
    every chunk (crash-safe) and returns it. A ``HierarchicalAssociator`` then counts its word
    statistics on the same stream (``count_word_statistics``; with ``motor_source='vision'`` the
    directives counted are those of the motion out of each pose, ``following_directives``) and is
    saved again.

    ``provenance`` (JSON values: what the network is trained from, e.g. the stream's digest, the
    seed and the motor source) is stored in the checkpoint's metadata; a checkpoint made with other
    hyper-parameters or another provenance is refused (ValueError), an unreadable one is discarded.
    """
    checkpoint_path = pathlib.Path(checkpoint_path)
    provenance = json.loads(json.dumps(provenance or {}))
    if checkpoint_path.exists():
        try:
            saved = persistence.load(checkpoint_path)
            saved_provenance = persistence.load_metadata(checkpoint_path).get("provenance", {})
        except ValueError as error:
            print(f"checkpoint {checkpoint_path} is unreadable ({error}); training starts over")
            saved = None
        if saved is not None:
            if saved.get_params() != model.get_params():
                raise ValueError(
                    f"checkpoint {checkpoint_path} was made with other hyper-parameters; delete "
                    "it or use the same settings"
                )
            if saved_provenance != provenance:
                raise ValueError(
                    f"checkpoint {checkpoint_path} was trained from other data or settings "
                    f"({saved_provenance} vs {provenance}); delete it or use the same settings"
                )
            model = saved
    done = int(getattr(model, "n_steps_", 0))
    total = len(stream)
    if done > total:
        raise ValueError(f"checkpoint has {done} steps, more than the stream's {total}")
    bar = tqdm(total=total, initial=done, desc=desc, unit="step", disable=not progress)
    while done < total:
        stop = min(done + chunk, total)
        model.partial_fit(*encode_stream(stream, encoder, motor_source, dt, done, stop))
        done = stop
        save_atomically(model, checkpoint_path, {"provenance": provenance})
        bar.update(stop - bar.n)
    bar.close()
    if isinstance(model, HierarchicalAssociator) and not model.has_word_statistics_:
        # The word layer's pose and motor statistics, counted with the trained lower level (all
        # at once: an interrupted count starts again, it is a pure function of network and stream).
        bar = tqdm(total=total, desc=f"{desc}: word statistics", unit="step", disable=not progress)
        for start in range(0, total, chunk):
            stop = min(start + chunk, total)
            vision, language, motor, _ = encode_stream(
                stream, encoder, motor_source, dt, start, stop
            )
            performed = None
            if motor_source == "vision":  # what was done at a pose: the motion out of it
                performed = encoding.encode_motor_batch(
                    following_directives(stream, dt, start, stop)
                )
            model.count_word_statistics(vision, language, motor, performed)
            bar.update(stop - start)
        bar.close()
        save_atomically(model, checkpoint_path, {"provenance": provenance})
    return model


def save_atomically(model: Associator, path, metadata: dict | None = None) -> None:
    """Saves the network (with ``metadata``) to ``path`` via a temporary file, flushed to disk, so an
    interruption never leaves a half-written checkpoint."""
    tmp = storage.temporary_name(path)
    persistence.save(model, tmp, metadata)
    storage.commit(tmp, path)
