"""What the experiment measures, on constructed ground truth: the performance success definitions
(``SuccessMonitor``), Table I's confusion matrix (``recognition``) and the directives inferred from
observed motion (``learning.inferred_directives``)."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import math

import numpy as np
import pytest

from associator import encoding
from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator
from imitation import learning, recognition
from imitation.performance import SuccessConfig, SuccessMonitor, dock_pose_at
from imitation.results import PAPER_TABLE_I, ConfusionTable
from imitation.streams import TeacherStream
from peoplebot_sim import directives
from perception.wallframe import ArenaGeometry

ARENA = ArenaGeometry()

DT = 0.1  # control step, s
STEPS_60S = 600
NOMINAL_TURN = math.radians(60.0)  # rad/s


def run_monitor(row: str, wall: str, poses, touching=None) -> SuccessMonitor:
    """Feeds a trace of world poses (n, 3) to a fresh monitor; returns it."""
    monitor = SuccessMonitor(row, wall, DT)
    touching = touching if touching is not None else [False] * len(poses)
    for pose, touch in zip(poses, touching, strict=True):
        monitor.update(pose, touch)
    return monitor


def circle(n: int, radius_m: float = 1.2, speed_mps: float = 0.3) -> np.ndarray:
    """Returns n poses driving counter-clockwise round the arena's centre at ``speed_mps``."""
    angle = speed_mps / radius_m * DT * np.arange(n)
    return np.column_stack(
        [radius_m * np.cos(angle), radius_m * np.sin(angle), angle + math.pi / 2]
    )


def approach(end_pose, n: int = 40, start=(0.0, 0.2)) -> np.ndarray:
    """Returns n poses moving in a straight line from ``start`` to ``end_pose``, with its yaw."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    xy = (1 - t) * np.asarray(start) + t * np.asarray(end_pose[:2])
    return np.column_stack([xy, np.full(n, end_pose[2])])


# ------------------------------------------------------------------------------ 'go'
def test_go_circling_the_arena_succeeds():
    monitor = run_monitor("go", "top", circle(STEPS_60S))
    assert monitor.areas == {"top", "bottom", "left", "right"}
    assert monitor.success()


def test_go_touching_a_wall_once_fails():
    touching = [False] * STEPS_60S
    touching[300] = True
    monitor = run_monitor("go", "top", circle(STEPS_60S), touching)
    assert monitor.touched
    assert not monitor.success()


def test_go_staying_in_one_wall_area_fails():
    """Moving steadily (0.33 m per 10 s) for 60 s, but only along the bottom wall."""
    x = np.linspace(-1.0, 1.0, STEPS_60S)
    poses = np.column_stack([x, np.full_like(x, -1.6), np.zeros_like(x)])
    monitor = run_monitor("go", "top", poses)
    assert monitor.areas == {"bottom"}
    assert not monitor.success()


def test_go_standing_still_for_ten_seconds_fails_five_seconds_passes():
    trace = circle(STEPS_60S)
    for still_steps, expected in ((101, False), (50, True)):
        poses = np.concatenate(
            [trace[:200], np.repeat(trace[200:201], still_steps, axis=0), trace[201:]]
        )
        assert run_monitor("go", "top", poses).success() is expected, still_steps


def test_go_shorter_than_one_window_fails():
    assert not run_monitor("go", "top", circle(90)).success()


# ------------------------------------------------------------------------------ 'pick'
SETTLE_STEPS = 30  # SuccessConfig.dock_settle_s (3 s) at 0.1 s a step


def settle(poses, steps: int = SETTLE_STEPS) -> np.ndarray:
    """Returns ``poses`` followed by ``steps`` more steps standing at the last pose."""
    return np.concatenate([poses, np.repeat(poses[-1:], steps, axis=0)])


def test_pick_reaching_the_dock_within_tolerance_and_staying_succeeds():
    dock = dock_pose_at("top")
    near = (dock[0] + 0.14, dock[1], dock[2] + math.radians(15.0))
    monitor = run_monitor("pick", "top", settle(approach(near)))
    assert monitor.reached and monitor.success()
    assert monitor.verdict()[1].startswith("docked and held the dock for 3 s")


def test_pick_passing_through_the_dock_fails():
    """Driving through the docked pose without stopping is no docking."""
    dock = dock_pose_at("top")
    through = approach((dock[0], dock[1] - 0.4, dock[2]), n=40, start=(dock[0], dock[1] + 0.4))
    monitor = run_monitor("pick", "top", through)
    assert not monitor.success()
    assert 0 < monitor.longest_inside_s < 3.0
    assert "at most" in monitor.verdict()[1]


def test_pick_must_stay_three_seconds_on_end():
    """29 steps (2.9 s) inside, one out, 29 in again fails; 30 steps on end succeeds."""
    dock = np.asarray(dock_pose_at("top"))
    away = dock - (0.0, 0.3, 0.0)

    def trace(*runs):  # alternating runs of steps away from and at the dock, away first
        return np.concatenate(
            [np.repeat([away if i % 2 == 0 else dock], n, axis=0) for i, n in enumerate(runs)]
        )

    assert not run_monitor("pick", "top", trace(5, 29, 1, 29, 5)).success()
    assert run_monitor("pick", "top", trace(5, 30)).success()
    assert not run_monitor("pick", "top", trace(5, 29)).success()
    assert run_monitor("pick", "top", trace(5, 29, 1, 30)).success()


def test_pick_settle_time_zero_counts_the_first_step_inside():
    monitor = SuccessMonitor("pick", "top", DT, SuccessConfig(dock_settle_s=0.0))
    verdicts = [monitor.update(p, False) for p in approach(dock_pose_at("top"), n=40)]
    assert verdicts[-1] and not verdicts[0]


def test_pick_sixteen_centimetres_away_fails():
    dock = dock_pose_at("top")
    for offset in ((0.16, 0.0), (0.0, -0.16), (0.16 / math.sqrt(2), -0.16 / math.sqrt(2))):
        end = (dock[0] + offset[0], dock[1] + offset[1], dock[2])
        assert not run_monitor("pick", "top", approach(end)).success(), offset


def test_pick_at_the_dock_position_with_wrong_heading_fails():
    dock = dock_pose_at("top")
    end = (dock[0], dock[1], dock[2] + math.radians(21.0))
    assert not run_monitor("pick", "top", approach(end)).success()


def test_pick_that_touches_on_the_way_fails():
    poses = settle(approach(dock_pose_at("top")))
    touching = [False] * len(poses)
    touching[5] = True
    monitor = run_monitor("pick", "top", poses, touching)
    assert not monitor.success()
    assert monitor.verdict()[1] == "touched a wall or the table at 0.6 s"


def test_pick_reports_success_on_the_step_it_has_held_the_dock_three_seconds():
    poses = settle(approach(dock_pose_at("top"), n=40))
    monitor = SuccessMonitor("pick", "top", DT)
    verdicts = [monitor.update(p, False) for p in poses]
    inside = [
        math.hypot(p[0] - dock_pose_at("top")[0], p[1] - dock_pose_at("top")[1]) <= 0.15
        for p in poses
    ]
    first_inside = inside.index(True)
    assert verdicts.index(True) == first_inside + SETTLE_STEPS - 1
    assert monitor.reached_at_s == pytest.approx((first_inside + SETTLE_STEPS) * DT)


def test_pick_at_another_wall_is_judged_at_that_walls_dock():
    left = dock_pose_at("left")
    assert run_monitor(
        "pick_other_wall", "left", settle(approach(left, start=(-0.2, 0.0)))
    ).success()
    # Docking at the table's wall is not success when the trial started at the left wall.
    top = settle(approach(dock_pose_at("top")))
    assert not run_monitor("pick_other_wall", "left", top).success()


# ------------------------------------------------------------------------------ 'lift'
def lift_trace(final_yaw: float) -> np.ndarray:
    """Backs 0.7 m away from the docked pose, then turns in place to ``final_yaw``."""
    dock = dock_pose_at("top")
    back = approach((dock[0], dock[1] - 0.7, dock[2]), n=20, start=dock[:2])
    turn = np.column_stack(
        [np.full(20, back[-1, 0]), np.full(20, back[-1, 1]), np.linspace(dock[2], final_yaw, 20)]
    )
    return np.concatenate([back, turn])


def test_lift_backing_off_and_facing_the_centre_succeeds():
    assert run_monitor("lift", "top", lift_trace(-math.pi / 2)).success()


def test_lift_facing_away_from_the_centre_fails():
    """Far enough from the table (0.8 m), but still facing the table, away from the centre."""
    assert not run_monitor("lift", "top", lift_trace(math.pi / 2)).success()
    # 50 deg off the centre direction is beyond the 45 deg tolerance.
    assert not run_monitor("lift", "top", lift_trace(-math.pi / 2 + math.radians(50))).success()


def test_success_config_numbers_are_the_documented_ones():
    c = SuccessConfig()
    assert (c.go_min_wall_areas, c.go_window_s, c.go_min_window_travel_m) == (2, 10.0, 0.2)
    assert (c.dock_position_tol_m, c.dock_heading_tol_deg, c.dock_settle_s) == (0.15, 20.0, 3.0)
    assert (c.lift_min_gap_m, c.lift_heading_tol_deg) == (0.5, 45.0)


# ------------------------------------------------------------------------------ Table I
def test_confusion_counts_and_table_on_constructed_labels():
    go, pick, lift = (directives.word_index(w) for w in ("go", "pick", "lift"))
    true = np.array([go, go, go, go, pick, pick, lift], np.int8)
    recognised = np.array([go, pick, go, lift, pick, pick, go], np.int8)
    counts = recognition.confusion_counts(true, recognised)
    np.testing.assert_array_equal(counts, [[2, 1, 1], [0, 2, 0], [1, 0, 0]])
    t = ConfusionTable.from_counts(counts).to_json()
    assert t["counts"] == {"go": 4, "pick": 2, "lift": 1}
    assert t["confusion"]["go"] == {"go": 0.5, "pick": 0.25, "lift": 0.25}
    assert t["confusion"]["pick"] == {"go": 0.0, "pick": 1.0, "lift": 0.0}
    assert t["confusion"]["lift"] == {"go": 1.0, "pick": 0.0, "lift": 0.0}
    assert t["counts_matrix"]["go"] == {"go": 2, "pick": 1, "lift": 1}
    for row in t["confusion"].values():
        assert sum(row.values()) == pytest.approx(1.0)


def test_table_row_without_samples_is_none_not_nan():
    counts = recognition.confusion_counts(np.array([0, 0, 1]), np.array([0, 1, 1]))
    t = ConfusionTable.from_counts(counts).to_json()
    assert t["counts"]["lift"] == 0
    assert t["confusion"]["lift"] == {"go": None, "pick": None, "lift": None}


def test_paper_table_rows_sum_to_one():
    for word, row in PAPER_TABLE_I.confusion.items():
        assert sum(row.values()) == pytest.approx(1.0, abs=2e-4), word


def test_recognise_stream_matches_the_network_sample_by_sample(trained_associator, teacher_stream):
    """Chunked recognition of a stream equals the network's own read-out of each step."""
    encoder = encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
    recognised = recognition.recognise_stream(
        trained_associator, teacher_stream, encoder, chunk=333
    )
    assert recognised.shape == (len(teacher_stream),)
    vision, _, motor, _ = learning.encode_stream(teacher_stream, encoder)
    for i in range(0, len(teacher_stream), 97):
        word = trained_associator.recognise(vision[i], motor[i]).word
        assert recognised[i] == directives.word_index(word), i
    assert len(np.unique(recognised)) >= 2, "a trained network should not name one word only"


def test_recognise_stream_over_time_carries_the_belief_across_chunks_and_gaps(teacher_stream):
    """Over-time recognition of a stream in chunks, with steps not seen (NaN poses), equals the
    network's one call on the seen steps; unseen steps get -1 and bad masks are refused."""
    encoder = encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
    n = len(teacher_stream)
    model = HierarchicalAssociator(lower=Associator(hidden_shape=(6, 12), n_steps_total=n, rng=0))
    model.fit(*learning.encode_stream(teacher_stream, encoder))
    seen = np.ones(n, bool)
    seen[5:40] = False
    seen[-1] = False
    gappy = teacher_stream.rows(slice(None))
    gappy.pose_wall = gappy.pose_wall.copy()
    gappy.pose_wall[~seen] = np.nan
    recognised = recognition.recognise_stream(
        model, gappy, encoder, chunk=111, over_time=True, seen=seen
    )
    vision, _, motor, _ = learning.encode_stream(teacher_stream.rows(seen), encoder)
    words = model.recognise_sequence(vision, motor, seen=seen).words
    np.testing.assert_array_equal(recognised[seen], [directives.word_index(w) for w in words[seen]])
    assert np.all(recognised[~seen] == -1)
    with pytest.raises(ValueError, match="one entry per step"):
        recognition.recognise_stream(model, gappy, encoder, over_time=True, seen=seen[:-1])
    with pytest.raises(ValueError, match="motor_source 'teacher'"):
        recognition.recognise_stream(model, gappy, encoder, "vision", seen=seen)
    # One step at a time, the seen steps are recognised alone and the others get -1.
    one_step = recognition.recognise_stream(model, gappy, encoder, chunk=111, seen=seen)
    words = model.recognise_batch(vision, motor).words
    np.testing.assert_array_equal(one_step[seen], [directives.word_index(w) for w in words])
    assert np.all(one_step[~seen] == -1)
    # Through a camera: both motor sources, over time and one step, on the steps seen only.
    observed = recognition.ObservedStream(teacher_stream, gappy, seen)
    outs = {}
    for motor_source in ("teacher", "vision"):
        for over_time in (False, True):
            out = recognition.recognise_observed(
                model, observed, encoder, motor_source, over_time=over_time
            )
            assert out.seen_fraction == pytest.approx(seen.mean())
            for table in (out.vision, out.truth_same_steps):
                assert sum(table.totals().values()) == seen.sum(), motor_source
        outs[motor_source] = out
    truth = recognition.recognise_stream(model, teacher_stream, encoder, over_time=True, seen=seen)[
        seen
    ]
    expected = recognition.table(teacher_stream.word[seen], truth)
    assert expected == outs["teacher"].truth_same_steps


# ------------------------------------------------------------------------------ inferred motor
def drive(commands, start=(0.3, -0.2, 0.4), linear=0.35, turn=NOMINAL_TURN) -> np.ndarray:
    """Returns the poses (n + 1, 3) of a robot obeying n directives (None: stand still) at the
    nominal speeds for one control step each, integrated exactly (arcs)."""
    unit = {
        "forward": (1, 0),
        "backward": (-1, 0),
        "turn_left": (0, 1),
        "turn_right": (0, -1),
        None: (0, 0),
    }
    poses = [np.asarray(start, dtype=float)]
    for c in commands:
        x, y, yaw = poses[-1]
        v, w = unit[c][0] * linear, unit[c][1] * turn
        poses.append(
            np.array(
                [
                    x + v * DT * math.cos(yaw + w * DT / 2),
                    y + v * DT * math.sin(yaw + w * DT / 2),
                    yaw + w * DT,
                ]
            )
        )
    return np.array(poses)


def test_inferred_directives_recover_the_commands_one_step_late():
    commands = (
        ["forward"] * 5
        + ["turn_left"] * 5
        + ["backward"] * 5
        + ["turn_right"] * 5
        + [None]
        + ["forward"] * 3
        + [None, None]
        + ["turn_left"] * 2
    )
    inferred = learning.inferred_directives(drive(commands), DT)
    assert inferred.dtype == np.int8 and inferred.shape == (len(commands) + 1,)
    expected, last = [], None
    for c in commands:
        last = c if c is not None else last
        expected.append(directives.DIRECTIVES.index(last))
    # Step t holds the motion from t - 1 to t; step 0 copies step 1.
    expected = [expected[0]] + expected
    np.testing.assert_array_equal(inferred, expected)


def test_following_directives_give_the_command_at_each_pose_in_any_chunks():
    """The motion out of each pose is the command executed there: the commands themselves (the
    last pose, with no motion after it, keeps the motion into it), whatever the chunks."""
    commands = ["forward"] * 4 + ["turn_left"] * 3 + ["backward"] * 4 + ["turn_right"] * 3
    poses = drive(commands)
    n = len(poses)
    stream = TeacherStream(
        pose_world=poses.astype(np.float32),
        pose_wall=np.zeros((n, 3), np.float32),
        word=np.zeros(n, np.int8),
        directive=np.zeros(n, np.int8),
        motor_changed=np.zeros(n, bool),
    )
    expected = [directives.DIRECTIVES.index(c) for c in commands + commands[-1:]]
    for chunk in (n, 5, 3):
        got = np.concatenate(
            [
                learning.following_directives(stream, DT, a, min(a + chunk, n))
                for a in range(0, n, chunk)
            ]
        )
        np.testing.assert_array_equal(got, expected)


def test_inferred_directives_hold_through_a_still_step_after_each_directive():
    for directive in directives.DIRECTIVES:
        inferred = learning.inferred_directives(drive([directive, directive, None, None]), DT)
        np.testing.assert_array_equal(inferred, [directives.DIRECTIVES.index(directive)] * 5)


def test_inferred_directives_are_causal():
    """Changing the future does not change the past."""
    commands = ["forward"] * 4 + ["turn_right"] * 4
    a = learning.inferred_directives(drive(commands + ["backward"] * 3), DT)
    b = learning.inferred_directives(drive(commands + ["turn_left"] * 3), DT)
    np.testing.assert_array_equal(a[:9], b[:9])
    assert a[10] != b[10]
