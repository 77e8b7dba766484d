"""Domain randomisation while the student watches (``imitation.randomisation``): the levels drawn
stay within range and are seeded, a draw of level 0 is bit-identical to clean training, and the
configuration keeps runs of other settings apart."""

import json

import numpy as np
import pytest

from associator import encoding
from imitation import randomisation as rd
from imitation import reproduce, transfer
from imitation.cli import _randomisation_suffix, build_parser, reproduce_config
from imitation.config import RunConfig
from imitation.perturbations import FAMILIES
from imitation.runstate import RunState
from imitation.streams import TeacherStream
from perception.wallframe import ArenaGeometry, world_to_wall_batch

DT = 0.1


def _stream(n=1200, seed=0) -> TeacherStream:
    """Returns a synthetic teacher stream: a smooth walk inside the arena, words in blocks."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    pose = np.column_stack(
        [0.8 * np.sin(0.05 * t), 0.6 * np.cos(0.07 * t), np.angle(np.exp(0.1j * t))]
    ) + rng.normal(0, 1e-3, (n, 3))
    x, y, phi, _ = world_to_wall_batch(*pose.T)
    word = ((np.arange(n) // 100) % 3).astype(np.int8)
    directive = rng.integers(0, 4, n).astype(np.int8)
    changed = np.concatenate([[False], directive[1:] != directive[:-1]])
    return TeacherStream(
        pose.astype(np.float32),
        np.column_stack([x, y, phi]).astype(np.float32),
        word,
        directive,
        changed,
    )


def test_levels_are_drawn_within_range_and_seeded():
    config = rd.RandomisationConfig(families=("pose_noise", "latency"), upper_level=3)
    upper_noise = FAMILIES["pose_noise"][3]["perception.position_noise_cm"]
    upper_latency = FAMILIES["latency"][3]["perception.latency_ms"]
    draws = [rd.draw_faults(config, np.random.default_rng(7)) for _ in range(2)]
    assert draws[0] == draws[1]  # seeded
    rng = np.random.default_rng(1)
    many = [rd.draw_faults(config, rng) for _ in range(200)]
    noise = np.array([f.position_noise_cm for f in many])
    latency = np.array([f.latency_ms for f in many])
    assert noise.min() >= 0 and noise.max() <= upper_noise and noise.max() > 0.9 * upper_noise
    assert latency.min() >= 0 and latency.max() <= upper_latency
    assert all(f.heading_noise_deg == f.position_noise_cm for f in many)  # one draw per family
    assert abs(np.mean(latency) / upper_latency - 0.5) < 0.1  # uniform
    # A level beyond a family's grid is its last level.
    assert (
        rd.RandomisationConfig(families=("occlusion",), upper_level=99).upper("occlusion")
        == (FAMILIES["occlusion"][-1])
    )

    stream = _stream()
    one, faults = rd.randomised_stream(stream, config, DT, seed=3)
    again, _ = rd.randomised_stream(stream, config, DT, seed=3)
    other, _ = rd.randomised_stream(stream, config, DT, seed=4)
    assert len(faults) == 2  # 1200 steps of 0.1 s in segments of 60 s
    assert np.array_equal(one.pose_world, again.pose_world)
    assert not np.array_equal(one.pose_world, other.pose_world)
    assert len(one) == len(stream) and np.all(np.isfinite(one.pose_world))
    assert np.array_equal(one.word, stream.word) and np.array_equal(one.directive, stream.directive)
    error_cm = 100 * np.hypot(*(one.pose_world[:, :2] - stream.pose_world[:, :2]).T)
    assert 0 < np.median(error_cm) < upper_noise * 3


def test_a_draw_of_level_zero_is_bit_identical_to_clean():
    stream = _stream()
    off = rd.RandomisationConfig(families=())
    assert not off.active and rd.randomised_stream(stream, off, DT, 0)[0] is stream
    zero = rd.RandomisationConfig(families=tuple(rd.watching_families()), upper_level=0)
    seen, faults = rd.randomised_stream(stream, zero, DT, 0)
    assert faults and not any(f.active for f in faults)
    for name in ("pose_world", "pose_wall", "word", "directive", "motor_changed"):
        assert np.array_equal(getattr(seen, name), getattr(stream, name)), name
        assert getattr(seen, name).dtype == getattr(stream, name).dtype


def test_a_randomised_run_trains_on_the_randomised_stream_and_keeps_its_own_folder(
    tmp_path, monkeypatch
):
    config = RunConfig.quick().replace(
        {
            "learning.train_steps": 1000,
            "hierarchical.enabled": False,
            "workers": 1,
            "randomisation.families": [],
        }
    )
    randomised = config.replace({"randomisation.families": ["dropout"]})
    # Both trees hold the section, and a folder made with the other is refused.
    assert config.to_dict()["randomisation"]["families"] == []
    assert randomised.to_dict()["randomisation"]["families"] == ["dropout"]
    assert RunConfig.from_dict(json.loads(json.dumps(config.to_dict()))) == config
    assert RunConfig.from_dict(json.loads(json.dumps(randomised.to_dict()))) == randomised
    RunState(tmp_path / "run", config.to_dict()).close()
    with pytest.raises(ValueError, match="randomisation"):
        RunState(tmp_path / "run", randomised.to_dict())
    assert "randomisation" in reproduce.SHARED_LEARNING_SECTIONS

    seen = []
    original = rd.randomised_stream

    def spy(stream, settings, dt, seed):
        out = original(stream, settings, dt, seed)
        seen.append(not np.array_equal(out[0].pose_world, stream.pose_world))
        return out

    monkeypatch.setattr(rd, "randomised_stream", spy)
    stream = _stream(1000)
    encoder = encoding.VisionEncoder(half_side_m=ArenaGeometry().half_side_m)
    networks = {}
    for name, run in (("clean", config), ("randomised", randomised)):
        folder = tmp_path / name
        (folder / "streams").mkdir(parents=True)
        stream.save(folder / "streams" / "train.npz")
        reproduce.stage_learning(run, folder, encoder)
        networks[name] = np.load(folder / "network.npz")
    assert seen == [False, True]
    assert any(
        not np.array_equal(networks["clean"][k], networks["randomised"][k])
        for k in networks["clean"].files
        if networks["clean"][k].dtype != object and k != "metadata"
    )


def test_the_default_randomises_pose_noise_and_latency_and_none_turns_it_off():
    assert RunConfig().randomisation == rd.RandomisationConfig(("pose_noise", "latency"), 3)
    assert RunConfig.quick().randomisation.active
    default = reproduce_config(build_parser().parse_args(["reproduce"]))
    off = reproduce_config(build_parser().parse_args(["reproduce", "--randomise", "none"]))
    assert default.randomisation.active and not off.randomisation.active
    assert _randomisation_suffix(default.randomisation) == ""
    assert _randomisation_suffix(off.randomisation) == "-unrandomised"
    assert _randomisation_suffix(rd.RandomisationConfig(("dropout",))) == "-randomised-dropout"
    assert _randomisation_suffix(rd.RandomisationConfig(upper_level=2)) == (
        "-randomised-pose_noise-latency"
    )
    assert transfer._compare_label(off.randomisation, default.randomisation, "b") == "randomised"
    assert transfer._compare_label(default.randomisation, off.randomisation, "b") == (
        "unrandomised"
    )
    assert transfer._compare_label(default.randomisation, default.randomisation, "b") == "b"


def test_the_command_line_and_bad_settings():
    args = build_parser().parse_args(
        ["reproduce", "--quick", "--randomise", "pose_noise,latency", "--randomise-level", "2"]
    )
    config = reproduce_config(args)
    assert config.randomisation == rd.RandomisationConfig(("pose_noise", "latency"), 2)
    every = reproduce_config(build_parser().parse_args(["reproduce", "--randomise", "all"]))
    assert every.randomisation.families == ("pose_noise", "latency", "dropout", "occlusion")
    with pytest.raises(
        ValueError, match="'acceleration' cannot be randomised.*allowed: pose_noise"
    ):
        rd.parse_families("acceleration")
    with pytest.raises(ValueError, match="randomisation.families: 'mass' cannot"):
        RunConfig().replace({"randomisation.families": ["mass"]})
    with pytest.raises(ValueError, match="randomisation.upper_level must be"):
        RunConfig().replace({"randomisation.upper_level": -1})
    with pytest.raises(ValueError, match="randomisation.segment_s must be"):
        RunConfig().replace({"randomisation.segment_s": 0.0})
