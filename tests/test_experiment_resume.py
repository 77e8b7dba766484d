"""Interrupted learning and stream generation resume to exactly the result of an uninterrupted run
(``imitation.learning.train`` and ``imitation.streams.generate_resumable``)."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import dataclasses
import json

import numpy as np
import pytest

from associator import encoding, persistence
from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator
from imitation import learning, streams
from imitation.streams import TeacherStream, generate_resumable
from peoplebot_sim.task import TaskConfig
from perception.wallframe import ArenaGeometry

ARENA = ArenaGeometry()


class Interrupt(KeyboardInterrupt):
    """Raised by a test to simulate Ctrl-C at a chosen point."""


def interrupt_on_call(monkeypatch, module, name: str, call: int):
    """Replaces ``module.name`` with a wrapper that raises ``Interrupt`` on its ``call``-th call
    (1-based; 0: never); returns the list that records the calls."""
    original = getattr(module, name)
    calls = []

    def wrapper(*args, **kwargs):
        calls.append(1)
        if len(calls) == call:
            raise Interrupt(f"simulated interruption in {name}, call {call}")
        return original(*args, **kwargs)

    monkeypatch.setattr(module, name, wrapper)
    return calls


def assert_same_network(a, b):
    np.testing.assert_array_equal(a.W_bu_, b.W_bu_)
    np.testing.assert_array_equal(a.W_td_, b.W_td_)
    assert a.n_steps_ == b.n_steps_
    assert a.rng_.bit_generator.state == b.rng_.bit_generator.state


# ------------------------------------------------------------------------------ learning.train
def _network_of(model):
    """Returns the paper's network inside ``model`` (the lower level of a hierarchical one)."""
    return model.lower_ if isinstance(model, HierarchicalAssociator) else model


@pytest.mark.parametrize(
    "kind, motor_source",
    [("paper", "teacher"), ("paper", "vision"), ("hierarchical", "teacher")],
)
def test_interrupted_training_resumes_bit_identical(
    teacher_stream, tmp_path, monkeypatch, small_associator, kind, motor_source
):
    """Training stopped inside the third chunk (two checkpoints written) and started again with a
    fresh model ends with the same weights, step count and random state (and, for the
    hierarchical associator, word links and word statistics) as one uninterrupted call."""
    encoder = encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
    n = len(teacher_stream)
    chunk = 400

    def fresh():
        if kind == "paper":
            return small_associator(n)
        return HierarchicalAssociator(
            lower=Associator(hidden_shape=(6, 12), n_steps_total=n, rng=0)
        )

    def train(checkpoint, chunk_size):
        return learning.train(
            fresh(),
            teacher_stream,
            checkpoint,
            encoder=encoder,
            motor_source=motor_source,
            chunk=chunk_size,
            progress=False,
        )

    reference = train(tmp_path / "whole.npz", n)
    checkpoint = tmp_path / "resumed.npz"
    with monkeypatch.context() as patch:
        interrupt_on_call(patch, learning, "encode_stream", call=3)
        with pytest.raises(Interrupt):
            train(checkpoint, chunk)
    partial = persistence.load(checkpoint)
    assert partial.n_steps_ == 2 * chunk, "the interruption should leave two chunks saved"
    assert not (tmp_path / "resumed.partial.npz").exists()

    with monkeypatch.context() as patch:
        calls = interrupt_on_call(patch, learning, "encode_stream", call=0)
        resumed = train(checkpoint, chunk)
    # The hierarchical associator then counts its word statistics in one pass over the stream.
    counting = -(-n // chunk) if kind == "hierarchical" else 0
    assert len(calls) == 2 + counting, "the resumed run should train only the chunks not yet saved"
    assert type(resumed) is type(reference) and resumed.n_steps_ == n
    for model in (resumed, persistence.load(checkpoint)):
        assert_same_network(_network_of(model), _network_of(reference))
        if kind == "hierarchical":
            np.testing.assert_array_equal(model.word_links_, reference.word_links_)
            np.testing.assert_array_equal(model.word_motor_counts_, reference.word_motor_counts_)
            # Summed in pieces of another size: equal up to the order of float additions.
            np.testing.assert_allclose(model.word_pose_sums_, reference.word_pose_sums_, 1e-12)
    network = _network_of(resumed)
    assert np.all(np.isfinite(network.W_bu_)) and np.all(np.isfinite(network.W_td_))


def test_training_is_independent_of_chunk_size(teacher_stream, tmp_path, small_associator):
    """Odd chunk sizes (boundaries inside directive changes) give the same network, including the
    motion-inferred directives, which need history across the boundary."""
    encoder = encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
    n = len(teacher_stream)
    whole = learning.train(
        small_associator(n),
        teacher_stream,
        tmp_path / "a.npz",
        encoder=encoder,
        motor_source="vision",
        chunk=n,
        progress=False,
    )
    pieces = learning.train(
        small_associator(n),
        teacher_stream,
        tmp_path / "b.npz",
        encoder=encoder,
        motor_source="vision",
        chunk=137,
        progress=False,
    )
    assert_same_network(pieces, whole)


def test_encode_stream_chunks_match_the_whole(teacher_stream):
    """encode_stream over [start, stop) equals the same rows of the whole stream's encoding, for
    both motor sources."""
    encoder = encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
    for source in ("teacher", "vision"):
        whole = learning.encode_stream(teacher_stream, encoder, source)
        for start, stop in ((0, 1), (1, 2), (2, 301), (777, 1500)):
            part = learning.encode_stream(teacher_stream, encoder, source, start=start, stop=stop)
            for w, p in zip(whole, part, strict=True):
                np.testing.assert_array_equal(w[start:stop], p)


def test_training_refuses_a_checkpoint_with_other_hyper_parameters(
    teacher_stream, tmp_path, small_associator
):
    encoder = encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
    n = len(teacher_stream)
    path = tmp_path / "net.npz"
    learning.train(
        small_associator(n), teacher_stream, path, encoder=encoder, chunk=500, progress=False
    )
    other = small_associator(n)
    other.eta = 0.002
    with pytest.raises(ValueError, match="hyper-parameters"):
        learning.train(other, teacher_stream, path, encoder=encoder, progress=False)


def test_training_refuses_a_checkpoint_longer_than_the_stream(
    teacher_stream, tmp_path, small_associator
):
    encoder = encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
    n = len(teacher_stream)
    path = tmp_path / "net.npz"
    learning.train(small_associator(n), teacher_stream, path, encoder=encoder, progress=False)
    shorter = TeacherStream(
        *(getattr(teacher_stream, f.name)[:100] for f in dataclasses.fields(TeacherStream))
    )
    with pytest.raises(ValueError, match="more than the stream"):
        learning.train(small_associator(n), shorter, path, encoder=encoder, progress=False)


def test_unknown_motor_source_is_refused_by_name(teacher_stream):
    with pytest.raises(ValueError, match="telepathy.*teacher, vision"):
        learning.encode_stream(
            teacher_stream, encoding.VisionEncoder(half_side_m=ARENA.half_side_m), "telepathy"
        )


# ------------------------------------------------------------------------------ streams
def test_interrupted_stream_resumes_identical(tmp_path, monkeypatch):
    """A stream generated in chunks of 200 steps, interrupted inside its third chunk and resumed
    (physics and teacher state restored from the checkpoint), equals the same stream generated in
    one go, row for row."""
    n, seed = 700, 11
    reference = TeacherStream.load(generate_resumable(seed, n, tmp_path / "whole", "s", chunk=n))

    folder = tmp_path / "resumed"
    with monkeypatch.context() as patch:
        interrupt_on_call(patch, streams.StreamGenerator, "generate", call=3)
        with pytest.raises(Interrupt):
            generate_resumable(seed, n, folder, "s", chunk=200)
    state = json.loads((folder / "s.state.json").read_text())
    assert state["generator"]["steps_done"] == 400 and len(state["parts"]) == 2
    assert len(sorted(folder.glob("s.part*.npz"))) == 2
    assert not (folder / "s.npz").exists()

    progress = tmp_path / "progress.txt"
    with monkeypatch.context() as patch:
        calls = interrupt_on_call(patch, streams.StreamGenerator, "generate", call=0)
        path = generate_resumable(seed, n, folder, "s", chunk=200, progress_file=progress)
    assert len(calls) == 2, "the resumed run should simulate only the steps not yet saved"
    resumed = TeacherStream.load(path)
    assert len(resumed) == n
    for field in dataclasses.fields(TeacherStream):
        np.testing.assert_array_equal(
            getattr(resumed, field.name), getattr(reference, field.name), err_msg=field.name
        )
    assert progress.read_text() == str(n)
    # Only the finished stream is left behind.
    assert sorted(p.name for p in folder.iterdir()) == ["s.npz"]


def test_parts_without_a_committed_checkpoint_are_discarded(tmp_path, monkeypatch):
    """A crash can leave a part its checkpoint does not name (written, then killed before the
    checkpoint), a 0-byte part, or parts with no checkpoint at all: none is trusted, and the
    resumed stream equals the one generated in one go (no duplicated or missing rows)."""
    n, seed = 500, 4
    reference = TeacherStream.load(generate_resumable(seed, n, tmp_path / "whole", "s", chunk=n))

    def interrupted(folder):
        with monkeypatch.context() as patch:
            interrupt_on_call(patch, streams.StreamGenerator, "generate", call=2)
            with pytest.raises(Interrupt):
                generate_resumable(seed, n, folder, "s", chunk=200)

    cases = {
        "uncommitted part": lambda f: (f / "s.part0001.npz").write_bytes(
            (f / "s.part0000.npz").read_bytes()
        ),
        "0-byte part": lambda f: (f / "s.part0001.npz").write_bytes(b""),
        "no checkpoint": lambda f: (f / "s.state.json").unlink(),
        "0-byte part, no checkpoint": lambda f: (
            (f / "s.state.json").unlink(),
            (f / "s.part0000.npz").write_bytes(b""),
        ),
        "corrupt checkpoint": lambda f: (f / "s.state.json").write_text("{"),
        "changed part": lambda f: (f / "s.part0000.npz").write_bytes(
            (f / "s.part0000.npz").read_bytes()[:-7]
        ),
    }
    for name, damage in cases.items():
        folder = tmp_path / name.replace(" ", "_").replace(",", "")
        interrupted(folder)
        damage(folder)
        resumed = TeacherStream.load(generate_resumable(seed, n, folder, "s", chunk=200))
        assert len(resumed) == n, name
        for field in dataclasses.fields(TeacherStream):
            np.testing.assert_array_equal(
                getattr(resumed, field.name), getattr(reference, field.name), err_msg=name
            )


def test_a_stream_of_other_settings_is_never_reused(tmp_path):
    """A finished stream file is reused only when it was made with the same seed, steps and
    world: another seed in the same folder generates it again."""
    first = TeacherStream.load(generate_resumable(2, 60, tmp_path, "t", chunk=60))
    other = TeacherStream.load(generate_resumable(3, 60, tmp_path, "t", chunk=60))
    assert not np.array_equal(first.pose_world, other.pose_world)
    assert streams.stream_provenance(tmp_path / "t.npz")["seed"] == 3
    longer = TeacherStream.load(generate_resumable(3, 80, tmp_path, "t", chunk=80))
    assert len(longer) == 80


@pytest.mark.parametrize("accel", [0.0, 0.05])
def test_stream_generator_state_round_trip(accel):
    """get_state after k steps, set_state into a fresh generator: the next steps are identical
    (also with the teacher robot's firmware ramping its set-points, whose state is kept); a
    different seed gives a different stream (the comparison can fail)."""
    teacher = dataclasses.replace(TaskConfig().teacher, robot_linear_accel_mps2=accel)
    a = streams.StreamGenerator(5, TaskConfig(teacher=teacher))
    a.generate(150)
    state = json.loads(json.dumps(a.get_state()))  # as written to disk
    if accel:  # caught while the forward set-point ramps (7 s from rest to full speed)
        assert 0.0 < abs(state["setpoint"][0]) < 0.34
    b = streams.StreamGenerator(5, TaskConfig(teacher=teacher))
    b.set_state(state)
    next_a, next_b = a.generate(250), b.generate(250)
    np.testing.assert_array_equal(next_a.pose_world, next_b.pose_world)
    np.testing.assert_array_equal(next_a.directive, next_b.directive)
    np.testing.assert_array_equal(next_a.word, next_b.word)
    other = streams.StreamGenerator(6).generate(400)
    assert not np.array_equal(other.pose_world[150:], next_a.pose_world)
    with pytest.raises(ValueError, match="physics state"):
        b.set_state({**state, "physics": state["physics"][:-1]})


def test_finished_stream_is_kept(tmp_path, monkeypatch):
    """A second call finds the finished file and does not simulate again."""
    path = generate_resumable(2, 50, tmp_path, "t", chunk=50)

    def fail(*args, **kwargs):
        raise AssertionError("generated again")

    monkeypatch.setattr(streams.StreamGenerator, "generate", fail)
    assert generate_resumable(2, 50, tmp_path, "t", chunk=50) == path


def test_a_stage_rerun_keeps_the_stages_after_it_only_if_it_writes_the_same_files(tmp_path):
    """``RunState.replace``: a damaged stage runs again; the stages that read its files stay
    finished when it writes the same bytes and result, and run again when anything differs (also
    after the folder is reopened between the two, as after a kill)."""
    from imitation.runstate import RunState

    config = {"seed": 0}
    data, later = tmp_path / "data.bin", tmp_path / "later.bin"

    def fresh_state():
        state = RunState(tmp_path, config)
        data.write_bytes(b"A")
        later.write_bytes(b"L")
        state.finish("first", {"n": 1}, [data])
        state.finish("second", {"m": 2}, [later])
        return state

    state = fresh_state()
    state.replace("first", ["second"])
    assert not state.done("first") and state.done("second")
    state.finish("first", {"n": 1}, [data])  # the same bytes and result
    assert state.done("second") and state.intact("second")
    state.close()

    for changed_bytes, changed_result in ((b"B", {"n": 1}), (b"A", {"n": 3})):
        state = fresh_state()
        state.replace("first", ["second"])
        state.close()
        state = RunState(tmp_path, config)  # reopened: the kept record is read back
        assert state.replacing("first") and state.done("second")
        data.write_bytes(changed_bytes)
        state.finish("first", changed_result, [data])
        assert not state.done("second") and not state.replacing("first")
        state.close()
        (tmp_path / "state.json").unlink()


def test_a_setting_added_later_counts_as_its_default_in_an_earlier_folder(tmp_path):
    """A folder whose saved configuration lacks a setting (made before the setting existed,
    within the same version) resumes when the setting is at its default, and is refused, naming
    the setting, when it is not; without defaults every setting must match."""
    from imitation.runstate import RunState

    defaults = {"seed": 0, "performance": {"trials": 50, "new_option": "off"}}
    earlier = {"seed": 3, "performance": {"trials": 10}}
    RunState(tmp_path, earlier).close()
    same = {"seed": 3, "performance": {"trials": 10, "new_option": "off"}}
    RunState(tmp_path, same, defaults=defaults).close()
    changed = {"seed": 3, "performance": {"trials": 10, "new_option": "on"}}
    with pytest.raises(ValueError, match=r"other settings \(performance\.new_option\)"):
        RunState(tmp_path, changed, defaults=defaults)
    with pytest.raises(ValueError, match=r"other settings \(performance\.new_option\)"):
        RunState(tmp_path, same)
