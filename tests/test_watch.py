"""``peoplebot watch`` on a recording made by ``peoplebot demo --camera overhead`` (an mp4 with its
camera_info YAML, arena file and true poses): poses within 2 cm (median) of the truth, and the same
recognition as the student's live run on the same steps within 2 points. Arena files round trip and
bad ones are refused by key."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import csv
import json

import numpy as np
import pytest

from associator import encoding
from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator
from imitation import learning, recognition
from imitation.cli import main
from imitation.demo import DemoConfig, run_demo
from peoplebot_sim import assets
from perception import camerainfo
from perception.arenafile import read_arena, write_arena
from perception.wallframe import ArenaGeometry

SECONDS = 40.0


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A 40 s overhead recording of the teacher (320 x 240, no shadows) with its companions."""
    folder = tmp_path_factory.mktemp("recording")
    summary = run_demo(
        DemoConfig(
            seconds=SECONDS, width=320, height=240, camera="overhead", shadows=False, seed=5
        ),
        folder / "teacher.mp4",
        progress=False,
    )
    return folder, summary


@pytest.fixture(scope="module")
def networks(tmp_path_factory, teacher_stream):
    """A run-folder-like folder with a small paper's network and hierarchical associator."""
    from associator import persistence

    folder = tmp_path_factory.mktemp("networks")
    codes = learning.encode_stream(
        teacher_stream, encoding.VisionEncoder(half_side_m=ArenaGeometry().half_side_m)
    )
    n = len(teacher_stream)
    persistence.save(
        Associator(hidden_shape=(6, 12), n_steps_total=n, rng=0).fit(*codes), folder / "network.npz"
    )
    hierarchical = HierarchicalAssociator(
        lower=Associator(hidden_shape=(6, 12), n_steps_total=n, rng=0)
    ).fit(*codes)
    persistence.save(hierarchical, folder / "hierarchical.npz")
    return folder


def _truth(path) -> dict:
    with open(path) as handle:
        rows = list(csv.DictReader(handle))
    return {
        "teacher": np.array(
            [[float(r[f"teacher_{k}"]) for k in ("x_m", "y_m", "yaw_rad")] for r in rows]
        ),
        "word": [r["word"] for r in rows],
    }


def test_watch_recovers_the_recorded_poses(recording, networks, tmp_path, capsys):
    folder, summary = recording
    files = summary["recording"]
    out = tmp_path / "watched"
    code = main(
        [
            "watch",
            str(folder / "teacher.mp4"),
            "--camera-info",
            files["camera_info"],
            "--arena",
            files["arena"],
            "--network",
            str(networks),
            "--mcap",
            "--out",
            str(out),
        ]
    )
    assert code == 0, capsys.readouterr().err
    watched = json.loads((out / "summary.json").read_text())
    assert watched["frames"] == int(SECONDS / 0.1)
    assert watched["frame_seconds"] == pytest.approx(0.1)
    assert watched["seen_fraction"]["teacher"] > 0.95
    truth = _truth(files["truth"])
    with open(out / "poses.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == len(truth["word"])
    errors = []
    for row, true in zip(rows, truth["teacher"], strict=True):
        if row["teacher_x_m"]:
            errors.append(
                np.hypot(float(row["teacher_x_m"]) - true[0], float(row["teacher_y_m"]) - true[1])
            )
    assert np.median(errors) < 0.02, np.median(errors)
    with open(out / "recognition.csv") as handle:
        words = list(csv.DictReader(handle))
    assert {"word_paper", "word_hierarchical", "word_hierarchical_over_time"} <= set(words[0])
    assert (out / "watched.mp4").stat().st_size > 10_000
    counts = _mcap_counts(out / "watched.mcap")
    for topic in ("/camera/image/compressed", "/markers", "/robots/teacher/pose", "/word"):
        assert counts[topic] >= 0.95 * len(rows), topic


def _mcap_counts(path) -> dict:
    from mcap.reader import make_reader

    with open(path, "rb") as handle:
        summary = make_reader(handle).get_summary()
    return {
        channel.topic: summary.statistics.channel_message_counts[i]
        for i, channel in summary.channels.items()
    }


def test_demo_logs_an_episode_as_mcap(tmp_path):
    summary = run_demo(
        DemoConfig(seconds=2.0, width=160, height=120, video=False, mcap=True),
        tmp_path / "d.mp4",
        progress=False,
    )
    counts = _mcap_counts(summary["mcap"])
    for topic in ("/cmd_vel", "/odom", "/tf", "/camera/image/compressed", "/camera/camera_info"):
        assert counts[topic] == 20, topic


def test_watch_recognises_as_the_live_student_does(recording, networks, tmp_path):
    """The same network on the poses watched from the compressed recording and on the poses the
    student tracked live from the rendered frames (same seed, same steps): correct recognition
    within 2 points for every word."""
    from imitation import watch

    folder, summary = recording
    files = summary["recording"]
    nets = watch.load_networks(networks)
    setup = read_arena(files["arena"])
    frames, _ = watch.frames_of(folder / "teacher.mp4")
    camera = watch.recording_camera(camerainfo.read(files["camera_info"]).camera, setup)
    watched = watch.track(frames, camera, setup.arena, 0.1)
    from_video = watch.recognise(watched, nets, setup.arena, 0.1)
    truth = _truth(files["truth"])
    live = recognition.watch_with_vision(5, len(frames) + 1, "overhead", progress=False)
    encoder = encoding.VisionEncoder(half_side_m=2.0)
    # The demo's frame i is rendered after control step i: the live run's step i + 1.
    observed = recognition.ObservedStream(
        live.truth.rows(slice(1, None)), live.observed.rows(slice(1, None)), live.seen[1:]
    )
    live_table = recognition.recognise_observed(nets["paper"], observed, encoder, "vision")
    true_index = np.array([encoding.WORDS.index(w) for w in truth["word"]])
    video_words = np.array([encoding.WORDS.index(w) if w else -1 for w in from_video["paper"]])
    both = (video_words >= 0) & observed.seen
    video_table = recognition.table(true_index[both], video_words[both])
    for word in encoding.WORDS:
        if live_table.vision.totals()[word] >= 20:
            assert (
                abs((video_table.correct(word) or 0) - live_table.vision.correct(word)) <= 0.02
            ), word


def test_the_shipped_arena_file_is_the_simulated_arena(tmp_path):
    assert read_arena(assets.ARENA_TOML).arena == ArenaGeometry()
    bigger = ArenaGeometry(side_m=6.0, table_width_m=1.2)
    write_arena(tmp_path / "room.toml", bigger)
    assert read_arena(tmp_path / "room.toml").arena == bigger


@pytest.mark.parametrize(
    "text, message",
    [
        ("side_m = 'big'\n", "side_m must be a number"),
        ("sides = 4.0\n", "unknown key 'sides'"),
        ("side_m = -1.0\n", "side_m must be a positive"),
        ("[camera]\nposition_m = [0, 0]\n", r"\[camera\] must give position_m and rotation"),
        (
            "[camera]\nposition_m = [0, 0, 6]\nrotation_world_from_camera = [[1,0,0],[0,1,0],[0,0,2]]\n",
            "rotation",
        ),
        ("side_m = \n", "not valid TOML"),
    ],
)
def test_bad_arena_files_are_refused_by_key(tmp_path, text, message):
    path = tmp_path / "arena.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_arena(path)
