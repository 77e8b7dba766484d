"""The library refuses nonsense with a ValueError that names it: perception's entry points given
non-finite poses, the associators given unknown words, and network files whose counts contradict
each other. (Start poses off the free floor: ``tests/test_sim_env.py``.)"""

import math

import numpy as np
import pytest

from associator import encoding, persistence, synthetic
from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator
from perception import layout
from perception.camera import PinholeCamera, look_at_rotation
from perception.motion import body_rates, infer_directive, infer_directives, infer_directives_batch
from perception.odometry import WheelOdometry
from perception.pantilt import (
    PanTiltController,
    aim_at,
    head_camera,
    head_camera_rotation,
    head_position_world,
)
from perception.pose import fit_planar_pose, fit_robot_pose, robot_to_world
from perception.synthetic import render_markers, true_corners
from perception.tracking import KalmanTrack
from perception.wallframe import (
    ArenaGeometry,
    WallPose,
    nearest_wall,
    wall_to_world,
    world_to_wall,
    world_to_wall_batch,
)

NAN, INF = float("nan"), float("inf")
CAMERA = PinholeCamera.from_fovy(
    64, 48, 60.0, look_at_rotation((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)), (0, 0, 4.0)
)
TOP = layout.default_layout()[0]  # the teacher's top plate
FRONT = next(p for p in layout.default_layout() if p.robot == "teacher" and p.face == "front")


# ------------------------------------------------------------------------------------ perception
@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: body_rates((0, 0, NAN), (0, 0, 0), 0.1), r"pose_before must be three finite"),
        (lambda: body_rates((0, 0, 0), (0, 0), 0.1), r"pose_after must be three finite"),
        (lambda: infer_directive((0, 0, 0), (NAN, 0, 0), 0.1), r"pose_after .* got \(nan, 0, 0\)"),
        (lambda: infer_directive((INF, 0, 0), (0, 0, 0), 0.1), "pose_before must be three"),
        (lambda: aim_at((0, NAN, 0), (1, 0, 1)), "observer_pose must be three finite"),
        (lambda: aim_at((0, 0, 0), (1, INF, 1)), r"target_world must be three finite"),
        (lambda: aim_at((0, 0, 0), (1, 0)), r"target_world must be three finite"),
        (lambda: head_position_world((0, 0, INF)), "observer_pose must be three finite"),
        (lambda: head_camera(CAMERA, (0, 0, INF), 0.0, 0.0), "observer_pose must be three"),
        (lambda: head_camera(CAMERA, (0, 0, 0), NAN, 0.0), "pan_deg must be a finite number"),
        (lambda: head_camera_rotation(0.0, 0.0, INF), "tilt_deg must be a finite number, got inf"),
        (lambda: PanTiltController().step((NAN, 0, 0), (1, 0), 0.1), "observer_pose must be"),
        (lambda: PanTiltController().step((NAN, 0, 0), None, 0.1), "observer_pose must be"),
        (lambda: PanTiltController().step((0, 0, 0), (1, NAN), 0.1), "target_xy must be None or"),
        (lambda: PanTiltController(initial_pan_deg=NAN), "initial_pan_deg must be a finite"),
        (lambda: PanTiltController(target_height_m=INF), "target_height_m must be a finite"),
        (lambda: WheelOdometry((0, NAN, 0), 0.0, 0.0), "start_pose must be 3 finite numbers"),
        (lambda: WheelOdometry((0, 0, 0), INF, 0.0), "left_angle and right_angle must be finite"),
        (lambda: WheelOdometry((0, 0, 0), 0.0, 0.0).update(0.0, NAN), "wheel angles must be"),
        (lambda: robot_to_world(0.0, NAN, 0.0), "x_m, y_m and yaw_rad must be finite numbers"),
        (
            lambda: fit_planar_pose((NAN, 0, 0), TOP.corners_robot(), np.zeros((4, 2)), CAMERA),
            "initial must be three finite numbers",
        ),
        (
            lambda: fit_robot_pose([(FRONT.marker_id, np.zeros((4, 2)))], CAMERA, "teacher", None),
            "initial must be three finite numbers",
        ),
        (lambda: world_to_wall(0.0, NAN, 0.0), "pose must be finite"),
        (lambda: world_to_wall_batch([0, 1], [0, NAN], [0, 0]), "y_world must be finite"),
        (lambda: wall_to_world(WallPose(NAN, 0.0, 0.0, "top")), "pose.x_m must be a finite"),
        (lambda: wall_to_world(WallPose(1.0, 0.0, INF, "top")), "pose.phi_deg must be a finite"),
        (lambda: nearest_wall(NAN, 0.0), "x_world must be a finite number, got nan"),
        (lambda: ArenaGeometry().clear_of_table(0.0, INF, 0.5), "y_world must be a finite"),
        (lambda: ArenaGeometry().table_gap_m(NAN, 0.0), "x_world must be a finite"),
        (lambda: look_at_rotation((0, 0, 3), (0, 0, 0), (0, NAN, 0)), "up_world must be three"),
        (lambda: look_at_rotation((INF, 0, 3), (0, 0, 0)), "position_world must be three finite"),
        (
            lambda: PinholeCamera.from_fovy(64, 48, 45.0, position_world=(0, 0, NAN)),
            "position_world must be 3 finite metres",
        ),
        (
            lambda: PinholeCamera.from_fovy(64, 48, 45.0, np.full((3, 3), NAN)),
            "rotation_world_from_camera must be a finite 3x3 matrix",
        ),
        (lambda: CAMERA.with_pose(np.eye(3), (0, INF, 0)), "position_world must be 3 finite"),
        (lambda: KalmanTrack("teacher").predict_pose(NAN), "time_s must be finite"),
        (lambda: KalmanTrack("teacher").step(0.0, (0, NAN, 0)), "measurement must be 3 finite"),
        (
            lambda: render_markers(CAMERA, {"teacher": (0, 0, NAN)}),
            r"robot_poses\['teacher'\] must be three finite numbers",
        ),
        (lambda: true_corners(CAMERA, (INF, 0, 0), TOP), "robot_pose must be three finite"),
    ],
)
def test_perception_refuses_non_finite_poses_naming_the_argument(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_lost_poses_keep_their_documented_meaning():
    """A NaN row (a robot lost) gives no directive around it, as documented, and finite poses give
    the directive they did: 0.35 m forward in 1 s is 'forward' at the drive's speed."""
    poses = np.array([[0, 0, 0], [0.035, 0, 0], [NAN, NAN, NAN], [0.1, 0, 0], [0.135, 0, 0]])
    times = np.arange(5) * 0.1
    assert infer_directives(times, poses) == [None, "forward", None, None, "forward"]
    batch = infer_directives_batch(poses, 0.1)
    assert batch.tolist() == ["forward", "none", "none", "forward"]
    v, w = body_rates((0.0, 0.0, 0.0), (0.035, 0.0, 0.0), 0.1)
    assert (v, w) == pytest.approx((0.35, 0.0))
    assert world_to_wall(0.0, 1.5, math.pi / 2).wall == "top"


# ------------------------------------------------------------------------------------ associator
@pytest.fixture(scope="module")
def small_models(tmp_path_factory):
    """A paper network and a two-level one with its word statistics, trained briefly on a
    synthetic teacher; the two-level one saved; the stream."""
    stream = synthetic.encode_stream(synthetic.teacher_stream(600, rng=4))
    params = dict(hidden_shape=(6, 12), n_steps_total=600, rng=0)
    flat = Associator(**params).fit(*stream)
    model = HierarchicalAssociator(lower=Associator(**params)).fit(*stream)
    model.count_word_statistics(*stream[:3])
    path = persistence.save(model, tmp_path_factory.mktemp("net") / "h.npz")
    return flat, model, path, stream


def test_both_associators_refuse_unknown_words(small_models):
    """Performance takes the network's vocabulary only, in both networks; the error names the
    word and the vocabulary. Recognition takes no word (vision and motor codes only)."""
    flat, model, _, (vision, language, _, _) = small_models
    vocabulary = r"the network's vocabulary: \('go', 'pick', 'lift'\)"
    for network in (flat, model):
        with pytest.raises(ValueError, match=f"unknown word 'jump'; {vocabulary}"):
            network.perform(vision[0], "jump")
        with pytest.raises(ValueError, match=f"unknown word 'jump'; {vocabulary}"):
            network.perform_batch(vision[:2], "jump")
        with pytest.raises(ValueError, match=f"unknown words 'GO', 'jump'; {vocabulary}"):
            network.perform_batch(vision[:3], ["go", "jump", "GO"])
    # The two-level network takes words, never language codes (the paper's also takes codes).
    with pytest.raises(ValueError, match="words must be one word or a sequence of words"):
        model.perform_batch(vision[:2], language[:2])
    with pytest.raises(ValueError, match="word must be a vocabulary word, got int"):
        model.perform(vision[0], 3)
    assert flat.perform_batch(vision[:2], language[:2]).directives.shape == (2,)


def test_word_encoding_refuses_words_it_cannot_pronounce():
    """``encode_word(s)`` take any English word in the paper's lexicon or CMUdict, case ignored;
    ValueError names any other."""
    np.testing.assert_array_equal(encoding.encode_word("GO"), encoding.encode_word("go"))
    with pytest.raises(ValueError, match="unknown word 'blorptangle'"):
        encoding.encode_words(["go", "blorptangle"])
    with pytest.raises(ValueError, match="word must be a non-empty string, got 3"):
        encoding.encode_words(["go", 3])


def _entries(path) -> dict:
    with np.load(path) as archive:
        return {key: archive[key] for key in archive.files}


def _cells(entries):
    """Returns a (word, component) cell counted more than once away from x = 0, and an empty one."""
    samples, sums = entries["word_samples"], entries["word_pose_sums"]
    full = (samples > 1) & (sums[..., 0] > 1.0)
    return tuple(np.argwhere(full)[0]), tuple(np.argwhere(samples == 0)[0])


def _lying(entries) -> dict:
    """Returns name -> (changed entries, expected message) of self-contradicting files."""
    full, empty = _cells(entries)
    n = entries["word_samples"][full]

    def changed(key, cell, value):
        array = entries[key].copy()
        array[cell] = value
        return {key: array}

    links, transitions = entries["word_links"], entries["word_transitions"]
    last_word, last_unit = entries["last_sample"]
    unused = tuple(np.argwhere(links == 0)[0])
    a = tuple(np.argwhere(transitions > 0)[0])
    moved = transitions.copy()  # one transition moved to another row: the total stays
    moved[a] -= 1
    moved[(a[0] + 1) % len(moved), a[1]] += 1
    return {
        "pose sums without samples": (
            changed("word_pose_sums", (*empty, 0), 3.0),
            r"word_pose_sums is not zero at \(word '\w+', component \d+\), where word_samples counts no",
        ),
        "pose squares without samples": (
            changed("word_pose_squares", (*empty, 1), 9.0),
            "word_pose_squares is not zero at",
        ),
        "heading longer than one per sample": (
            changed("word_pose_sums", (*full, 2), 1.5 * n),
            "word_pose_sums has a heading vector longer than its sample count at",
        ),
        "negative variance": (
            changed(
                "word_pose_squares", (*full, 0), 0.5 * entries["word_pose_sums"][full][0] ** 2 / n
            ),
            r"word_pose_squares is smaller .* \(a negative variance\) at \(word",
        ),
        "samples but no directive counts": (
            changed("word_motor_counts", full, 0.0),
            r"word_motor_counts do not add up to word_samples at \(word",
        ),
        "half a sample": (
            changed("word_samples", full, n + 0.5),
            "word_samples has non-whole counts",
        ),
        "links not one per step": (
            changed("word_links", unused, 1.0),
            r"word_links count 601 samples, but n_steps is 600",
        ),
        "last sample without a link": (
            {"last_sample": np.array([unused[0], unused[1]])},
            r"last_sample \[\d+, \d+\] has no count in word_links",
        ),
        "last sample as floats": (
            {"last_sample": np.array([float(last_word), float(last_unit)])},
            "last_sample must hold integers",
        ),
        "transitions leaving the wrong words": (
            {"word_transitions": moved},
            "word_transitions leave the words",
        ),
        "winner transitions under the wrong word": (
            changed("transition_counts", 0, entries["transition_counts"][0] + 1),
            "transition_counts hold",
        ),
        "links not whole": (
            changed("word_links", (last_word, last_unit), links[last_word, last_unit] - 0.5),
            "word_links has non-whole counts",
        ),
    }


_CASES = (
    "pose sums without samples",
    "pose squares without samples",
    "heading longer than one per sample",
    "negative variance",
    "samples but no directive counts",
    "half a sample",
    "links not one per step",
    "last sample without a link",
    "last sample as floats",
    "transitions leaving the wrong words",
    "winner transitions under the wrong word",
    "links not whole",
)


@pytest.mark.parametrize("case", _CASES)
def test_network_file_whose_counts_contradict_themselves_is_refused(small_models, tmp_path, case):
    """Each edit makes a file no ``save`` can write (its counts contradict each other); it is
    refused naming the entry, where it used to load and perform nonsense."""
    _, _, path, _ = small_models
    entries = _entries(path)
    change, message = _lying(entries)[case]
    np.savez(tmp_path / "lying.npz", **{**entries, **change})
    with pytest.raises(ValueError, match=f"not a valid associator file: {message}"):
        persistence.load(tmp_path / "lying.npz")


def test_files_the_code_wrote_still_load(small_models, tmp_path):
    """A file with statistics counted in pieces (float sums in another order), and one without
    statistics, load and perform as the model they were saved from."""
    _, model, path, (vision, language, motor, changed) = small_models
    loaded = persistence.load(path)
    np.testing.assert_array_equal(
        loaded.perform_batch(vision, "go").motor, model.perform_batch(vision, "go").motor
    )
    pieces = HierarchicalAssociator(
        lower=Associator(hidden_shape=(6, 12), n_steps_total=600, rng=1)
    )
    pieces.fit(vision[:250], language[:250], motor[:250], changed[:250])
    pieces.partial_fit(vision[250:], language[250:], motor[250:], changed[250:])
    for lo, hi in ((0, 7), (7, 300), (300, 600)):
        pieces.count_word_statistics(vision[lo:hi], language[lo:hi], motor[lo:hi])
    again = persistence.load(persistence.save(pieces, tmp_path / "pieces.npz"))
    np.testing.assert_array_equal(again.word_pose_squares_, pieces.word_pose_squares_)
    plain = HierarchicalAssociator(lower=Associator(hidden_shape=(6, 12), n_steps_total=600, rng=1))
    plain.fit(vision[:1], language[:1], motor[:1])
    assert not persistence.load(
        persistence.save(plain, tmp_path / "plain.npz")
    ).has_word_statistics_
