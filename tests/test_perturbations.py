"""Perturbations toward real robots (issue 16): each does what it says at a tiny scale, a level of
0 changes nothing, and the configuration round-trips and refuses bad values by their keys."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import dataclasses
import math

import numpy as np
import pytest

from imitation import config as run_config
from imitation import performance, recognition, trials
from imitation import perturbations as pt
from imitation.cli import reproduce_config
from imitation.observers import Calibration, StudentVision
from imitation.reproduce import SHARED_LEARNING_SECTIONS
from imitation.runstate import RunState
from peoplebot_sim import hardware
from peoplebot_sim.appearance import Appearance
from peoplebot_sim.task import TaskConfig, load
from perception import degrade
from perception.odometry import WheelOdometry

DT = 0.1


def _still_stream(corruptor, n, pose=(1.0, -0.5, 0.3)):
    """Returns the reports of ``n`` steps of one robot standing at ``pose`` (None as NaN)."""
    out = np.full((n, 3), np.nan)
    for i in range(n):
        got = corruptor.step({"teacher": np.array(pose)})["teacher"]
        if got is not None:
            out[i] = got
    return out


# ----------------------------------------------------------------------------- perception output
def test_pose_noise_of_a_known_sigma_has_that_sigma():
    faults = pt.PerceptionFaults(position_noise_cm=2.0, heading_noise_deg=3.0)
    reports = _still_stream(pt.PoseCorruptor(faults, DT, np.random.default_rng(0)), 4000)
    assert np.std(reports[:, 0] - 1.0) == pytest.approx(0.02, rel=0.05)
    assert np.std(reports[:, 1] + 0.5) == pytest.approx(0.02, rel=0.05)
    assert np.degrees(np.std(reports[:, 2] - 0.3)) == pytest.approx(3.0, rel=0.05)
    assert abs(np.mean(reports[:, 0]) - 1.0) < 0.002


@pytest.mark.parametrize("k", [1, 3])
def test_latency_of_k_steps_shifts_the_signal_by_k(k):
    corruptor = pt.PoseCorruptor(
        pt.PerceptionFaults(latency_ms=k * DT * 1000), DT, np.random.default_rng(0)
    )
    got = [
        corruptor.step({"student": np.array([0.01 * i, 0.0, 0.0])})["student"] for i in range(20)
    ]
    assert all(g is None for g in got[:k])
    assert [round(g[0], 9) for g in got[k:]] == [round(0.01 * i, 9) for i in range(20 - k)]


def test_latency_of_half_a_step_reports_the_midpoint():
    corruptor = pt.PoseCorruptor(pt.PerceptionFaults(latency_ms=50), DT, np.random.default_rng(0))
    got = [corruptor.step({"student": np.array([0.1 * i, 0.0, 0.0])})["student"] for i in range(5)]
    assert got[0] is None
    assert [round(g[0], 9) for g in got[1:]] == [0.05, 0.15, 0.25, 0.35]


def test_dropout_of_p_drops_about_p_of_frames():
    corruptor = pt.PoseCorruptor(
        pt.PerceptionFaults(dropout_fraction=0.3), DT, np.random.default_rng(1)
    )
    reports = _still_stream(corruptor, 5000)
    lost = np.mean(np.isnan(reports[:, 0]))
    assert lost == pytest.approx(0.3, abs=0.02)
    assert corruptor.dropped == int(round(lost * 5000))


def test_burst_occlusion_hides_the_fraction_in_bursts_of_the_stated_length():
    faults = pt.PerceptionFaults(occlusion_fraction=0.2, occlusion_burst_s=1.0)
    hidden = np.isnan(_still_stream(pt.PoseCorruptor(faults, DT, np.random.default_rng(2)), 20000))
    hidden = hidden[:, 0]
    assert np.mean(hidden) == pytest.approx(0.2, abs=0.03)
    starts = np.flatnonzero(hidden[1:] & ~hidden[:-1])
    assert np.sum(hidden) / len(starts) == pytest.approx(10, rel=0.15)  # 1 s = 10 steps


# ----------------------------------------------------------------------------- images
def test_image_degradations_do_what_they_say():
    grey = np.full((120, 160, 3), 128, np.uint8)
    rng = np.random.default_rng(0)
    noisy = degrade.pixel_noise(grey, 5.0, rng)
    assert np.std(noisy.astype(float) - 128) == pytest.approx(5.0, rel=0.03)
    assert np.array_equal(degrade.exposure(grey, 1.0), np.full_like(grey, 255))
    assert np.array_equal(degrade.exposure(np.full_like(grey, 50), 1.0), np.full_like(grey, 100))
    dot = np.zeros((41, 41), np.uint8)
    dot[20, 20] = 255
    blurred = degrade.motion_blur(dot, 9, 0.0)
    assert np.count_nonzero(blurred[20]) == 9 and np.count_nonzero(blurred) == 9
    checker = (np.indices((120, 160)).sum(axis=0) // 8 % 2 * 255).astype(np.uint8)
    assert not np.array_equal(degrade.jpeg(checker, 10), checker)
    bent = degrade.radial_distortion(checker, -0.1)
    assert np.array_equal(bent[60, 78:82], checker[60, 78:82])  # the centre stays
    assert not np.array_equal(bent, checker)
    off = degrade.ImageDegradation()
    assert not off.active and np.array_equal(off.apply(checker, rng), checker)


def _overhead_frame(appearance=Appearance()):
    env = load(
        TaskConfig(
            cameras=("overhead",),
            student_pose=(0.5, 0.0, 0.0),
            teacher_pose=(-0.5, 0.5, 1.0),
            appearance=appearance,
        ),
        seed=0,
    )
    frame = env.reset().observation["overhead_camera"]
    env.close()
    return frame


def test_lighting_shadows_and_colours_change_the_frames_and_level_zero_does_not():
    nominal = _overhead_frame()
    assert np.array_equal(_overhead_frame(Appearance(light_fraction=0.0)), nominal)
    darker = _overhead_frame(Appearance(light_fraction=-0.5))
    assert darker.mean() < 0.85 * nominal.mean()
    shadowed = _overhead_frame(Appearance(shadows=True, light_tilt_deg=60.0))
    assert np.mean(shadowed.astype(int) < nominal.astype(int) - 30) > 0.02  # long shadows
    tinted = _overhead_frame(Appearance(surface_tint_fraction=1.0))
    assert tinted[..., 2].mean() < 0.7 * nominal[..., 2].mean()  # brown: far less blue


# ----------------------------------------------------------------------------- calibration
def test_calibration_error_moves_the_estimated_pose_by_the_expected_amount():
    """The student believes the overhead camera 5 cm from where it is: a robot under the camera
    is estimated displaced by the believed offset's horizontal part (the same image, the camera
    believed elsewhere)."""
    env = load(
        TaskConfig(with_teacher=False, cameras=("overhead",), student_pose=(0.0, 0.0, 0.4)), seed=0
    )
    timestep = env.reset()
    world = Calibration(env.physics, 320, 240)
    error = pt.CalibrationError(position_cm=5.0)
    believed = pt.believed_calibration(world, error, np.random.default_rng(7))
    offset = np.asarray(believed.overhead.position_world) - np.asarray(
        world.overhead.position_world
    )
    assert np.linalg.norm(offset) == pytest.approx(0.05)
    estimates = []
    for calibration in (world, believed):
        vision = StudentVision("overhead", calibration, watch_teacher=False)
        estimates.append(vision.update(timestep.observation, 0.0, DT)["student"])
    env.close()
    moved = estimates[1][:2] - estimates[0][:2]
    assert np.allclose(moved, offset[:2], atol=0.002)
    assert abs(estimates[1][2] - estimates[0][2]) < math.radians(0.5)
    assert pt.believed_calibration(world, pt.CalibrationError(), None) is world


def test_floor_marker_registration_replaces_the_believed_mount_pose():
    """With ``overhead_registration='floor_markers'`` the overhead camera's pose is fitted to its
    photo of the nine floor markers: the preset's mount error is gone (a robot's top plate read
    within 3 cm anywhere in the arena, the believed pose's 5 cm and 2 deg reading 8-16 cm off),
    whichever mount error the seed drew; only the believed intrinsics are kept."""
    env = load(TaskConfig(with_teacher=False, cameras=("overhead",)), seed=0)
    env.reset()
    world = Calibration(env.physics, 320, 240)
    env.close()
    error = pt.CalibrationError(position_cm=5.0, rotation_deg=2.0)
    plates = np.array([[x, y, 1.115] for x in np.linspace(-1.7, 1.7, 5) for y in (-1.7, 0, 1.7)])
    pixels = world.overhead.project(plates)

    def plate_error_m(camera):
        return np.linalg.norm(camera.intersect_plane_z(pixels, 1.115) - plates, axis=1).max()

    def overhead_camera(seed, registration):
        perturbed = pt.PerturbationConfig(calibration=error)
        vision = pt.student_vision(
            "overhead", world, perturbed, DT, seed, False, overhead_registration=registration
        )
        return vision.calibration.overhead

    registered = []
    for seed in (0, 1):
        assert plate_error_m(overhead_camera(seed, "believed")) > 0.08
        camera = overhead_camera(seed, "floor_markers")
        assert plate_error_m(camera) < 0.03
        registered.append(camera.position_world)
    np.testing.assert_allclose(registered[0], registered[1], atol=1e-9)  # the draw is forgotten
    with pytest.raises(
        ValueError, match="unknown overhead registration 'tape'; allowed: believed, floor_markers"
    ):
        pt.student_vision(
            "overhead", world, pt.PerturbationConfig(), DT, 0, overhead_registration="tape"
        )


# ----------------------------------------------------------------------------- actuation and body
def _drive(
    actuation=hardware.Actuation(), body=hardware.Body(), steps=20, command=(0.35, 1.0), settle=0
):
    """Returns the wheels' forward speed (m/s) and yaw rate (rad/s) after each step (the servos'
    tendons), the true poses at the start and after each step, and the last wheel encoder
    readings."""
    env = load(
        TaskConfig(
            with_teacher=False, student_pose=(0.0, -1.0, 0.0), actuation=actuation, body=body
        ),
        seed=0,
    )
    timestep = env.reset()
    for _ in range(settle):  # the robot settles on its wheels and casters
        timestep = env.step(np.zeros(6))
    action = np.zeros(6)
    action[:2] = command
    speeds, poses = [], [np.array(timestep.observation["student_pose"])]
    for _ in range(steps):
        timestep = env.step(action)
        tendons = env.physics.named.data.ten_velocity
        speeds.append((float(tendons["student/forward"]), float(tendons["student/turn"])))
        poses.append(np.array(timestep.observation["student_pose"]))
    env.close()
    return np.array(speeds), np.array(poses), timestep.observation["student_wheel_angles"]


def test_acceleration_limits_cap_the_measured_acceleration():
    """From rest, told 0.35 m/s and 1 rad/s at once: with ARIA's limits the wheels' measured
    accelerations stay at 0.3 m/s^2 and 100 deg/s^2 (within the servos' lag), and the body's yaw
    rate grows at 100 deg/s^2; without them they jump."""
    aria = hardware.Actuation(linear_accel_mps2=0.3, yaw_accel_degps2=100.0)
    for actuation, capped in ((hardware.Actuation(), False), (aria, True)):
        speeds, poses, _ = _drive(actuation, settle=10)
        linear, yaw = (np.diff(np.r_[[[0.0, 0.0]], speeds], axis=0) / DT).T
        yaw = np.degrees(yaw)
        body_yaw_rate = np.degrees(np.diff(np.unwrap(poses[:, 2]))) / DT
        if capped:
            assert np.max(np.abs(linear)) <= 0.3 * 1.15
            assert np.max(np.abs(yaw)) <= 100.0 * 1.15
            assert speeds[4, 0] == pytest.approx(0.3 * 0.5, abs=0.02)  # 0.3 m/s^2 for 0.5 s
            # The body's yaw rate grows at 100 deg/s^2 while the set-point ramps (to 0.57 s).
            assert (body_yaw_rate[4] - body_yaw_rate[1]) / 0.3 == pytest.approx(100.0, rel=0.15)
        else:
            assert np.max(linear) > 2.0 and np.max(yaw) > 300.0


def test_command_latency_of_one_control_step_shifts_the_motion_by_one_step():
    plain, _, _ = _drive(steps=10, settle=10)
    late, _, _ = _drive(hardware.Actuation(command_latency_ms=100.0), steps=10, settle=10)
    assert np.all(np.abs(late[0]) < 0.01)
    assert np.allclose(late[1:], plain[:-1], atol=0.01)


def test_wheel_radius_mismatch_turns_the_robot_and_biases_its_odometry():
    """A left wheel 5% larger and a right one 5% smaller: driving 'straight' at 0.35 m/s turns
    clockwise at v (r_r - r_l) / r / track; the odometry (nominal radius) believes it went
    straight."""
    body = hardware.Body(left_wheel_radius_fraction=0.05, right_wheel_radius_fraction=-0.05)
    env = load(TaskConfig(with_teacher=False, student_pose=(0.0, -1.0, 0.0), body=body), seed=0)
    timestep = env.reset()
    odometry = WheelOdometry((0.0, -1.0, 0.0), *timestep.observation["student_wheel_angles"])
    for _ in range(20):
        timestep = env.step(np.array([0.35, 0.0, 0.0, 0.0, 0.0, 0.0]))
        believed = odometry.update(*timestep.observation["student_wheel_angles"])
    env.close()
    turned = float(timestep.observation["student_pose"][2])
    assert turned == pytest.approx(0.35 * -0.1 / 0.34 * 2.0, rel=0.2)
    assert abs(believed[2]) < 0.01


def test_encoder_noise_of_a_known_sigma_reaches_the_odometry_with_that_sigma():
    seen = []

    class Recorder:
        mode, head_command = "head", (0.0, 0.0)

        def reset(self, start_pose=None, wheel_angles=None):
            pass

        def update(self, observation, time_s, dt):
            seen.append(observation["student_wheel_angles"])
            return {"student": None}

    config = pt.PerturbationConfig(
        proprioception=pt.ProprioceptionFaults(wheel_encoder_noise_deg=0.5)
    )
    vision = pt.PerturbedVision(Recorder(), config, DT, [0])
    for _ in range(3000):
        vision.update({"student_wheel_angles": np.array([1.0, 2.0])}, 0.0, DT)
    noise = np.degrees(np.array(seen) - [1.0, 2.0])
    assert np.std(noise, axis=0) == pytest.approx([0.5, 0.5], rel=0.05)


# ----------------------------------------------------------------------------- level 0
def test_level_zero_of_every_family_is_the_unperturbed_configuration():
    base = run_config.RunConfig.quick()
    for family, levels in pt.FAMILIES.items():
        zero = base.replace({f"perturbations.{k}": v for k, v in levels[0].items()})
        assert zero == base, family
        explicit = base.replace(
            {
                f"perturbations.{k}": False if isinstance(v, bool) else 0
                for level in levels
                for k, v in level.items()
            }
        )
        assert explicit == base and not explicit.perturbations.active, family
    assert type(pt.student_vision("truth", None, base.perturbations, DT, 0)) is StudentVision


def _lift_trace(config):
    env = trials.student_environment(config)
    item = trials.PlannedTrial(
        "lift", "teacher", 0, trials.trial_plan(config, ("teacher",))[-1].start, "top"
    )
    result = trials.run_planned_trial(config, env, item, "teacher", None, None)
    env.close()
    return result.trace


def test_level_zero_is_bit_identical_and_a_level_changes_the_trial():
    base = run_config.RunConfig.quick().replace({"performance.trial_seconds": 5.0})
    zero = base.replace(
        {"perturbations.body.mass_fraction": 0.0, "perturbations.actuation.command_latency_ms": 0}
    )
    assert np.array_equal(_lift_trace(base), _lift_trace(zero))
    aria = base.replace({f"perturbations.{k}": v for k, v in pt.ARIA_ACCELERATION.items()})
    assert not np.array_equal(_lift_trace(base), _lift_trace(aria))


def test_perception_faults_reach_truth_mode_recognition_and_the_teacher_reference(
    teacher_stream,
):
    config = pt.PerturbationConfig(perception=pt.PerceptionFaults(dropout_fraction=0.5))
    observed = recognition.perturbed_truth(teacher_stream, 400, config, DT, 5)
    assert len(observed.seen) == 400 and 0.4 < observed.seen.mean() < 0.6
    seen = observed.seen
    assert np.allclose(observed.observed.pose_world[seen], observed.truth.pose_world[seen])
    assert pt.teacher_vision(pt.PerturbationConfig(), DT, [0]) is None
    vision = pt.teacher_vision(config, DT, [0, 1, 2])
    reports = [vision.update({"student_pose": np.zeros(3)}, 0.0, DT)["student"] for _ in range(400)]
    assert 0.4 < np.mean([r is None for r in reports]) < 0.6


# ----------------------------------------------------------------------------- configuration
def test_the_realistic_preset_round_trips_through_toml(tmp_path):
    config = dataclasses.replace(run_config.RunConfig(), perturbations=pt.preset("realistic"))
    run_config.dump(config, tmp_path / "config.toml")
    assert run_config.load(tmp_path / "config.toml") == config
    assert "[perturbations.actuation]" in (tmp_path / "config.toml").read_text()


@pytest.mark.parametrize(
    "key, value",
    [
        ("perturbations.perception.dropout_fraction", 1.0),
        ("perturbations.perception.latency_ms", -5.0),
        ("perturbations.image.jpeg_quality", 101),
        ("perturbations.image.distortion_k1", 2.0),
        ("perturbations.calibration.focal_fraction", -1.0),
        ("perturbations.actuation.linear_accel_mps2", -0.3),
        ("perturbations.body.mass_fraction", -1.5),
        ("perturbations.body.caster_friction", "high"),
    ],
)
def test_bad_perturbations_are_refused_naming_the_dotted_key(key, value):
    with pytest.raises(ValueError, match=key.replace(".", r"\.")) as error:
        run_config.RunConfig().replace({key: value})
    assert "\n" not in str(error.value)


def test_an_unknown_preset_or_family_key_is_refused():
    with pytest.raises(ValueError, match="unknown preset 'lab'; allowed: realistic"):
        pt.preset("lab")
    with pytest.raises(ValueError, match="perturbations.actuation.latency_ms"):
        run_config.RunConfig().replace({"perturbations.actuation.latency_ms": 50})


def test_a_run_folder_with_other_perturbations_is_not_reused(tmp_path):
    config = run_config.RunConfig.quick()
    RunState(tmp_path, config.to_dict()).close()
    other = config.replace({"perturbations.perception.latency_ms": 50.0})
    with pytest.raises(ValueError, match="perturbations.perception.latency_ms"):
        RunState(tmp_path, other.to_dict())
    RunState(tmp_path, config.to_dict()).close()
    # Trained networks are shared across perturbations (transfer tests reuse them).
    assert "perturbations" not in SHARED_LEARNING_SECTIONS


def test_reproduce_takes_the_realistic_preset():
    from imitation.cli import build_parser

    args = build_parser().parse_args(["reproduce", "--quick", "--preset", "realistic"])
    assert reproduce_config(args).perturbations == pt.PRESETS["realistic"]
    args = build_parser().parse_args(["reproduce", "--quick"])
    assert not reproduce_config(args).perturbations.active


@pytest.mark.parametrize("flag, value", [(None, True), ("on", True), ("off", False)])
def test_reproduce_takes_brake_ahead(flag, value):
    """``--brake-ahead on|off`` sets ``performance.brake_ahead`` (a performing setting: the
    networks are shared with runs without it), default the configuration's."""
    from imitation.cli import build_parser

    extra = [] if flag is None else ["--brake-ahead", flag]
    args = build_parser().parse_args(["reproduce", "--quick", *extra])
    assert reproduce_config(args).performance.brake_ahead is value
    assert "performance" not in SHARED_LEARNING_SECTIONS
    with pytest.raises(SystemExit):
        build_parser().parse_args(["reproduce", "--brake-ahead", "yes"])


STUDENT_OPTIONS = [
    # flag, value, its config key, the key's default, the folder suffix, a refused value
    (
        "--overhead-registration",
        "floor_markers",
        "vision.overhead_registration",
        "believed",
        "-overhead-floor-markers",
        "tape",
    ),
    (
        "--brake-limits",
        "estimated",
        "performance.brake_limits",
        "told",
        "-brake-limits-estimated",
        "guessed",
    ),
    (
        "--support-speeds",
        "nominal",
        "performance.support_speeds",
        "measured_forward",
        "-support-speeds-nominal",
        "guessed",
    ),
]


@pytest.mark.parametrize("command", ["reproduce", "transfer"])
@pytest.mark.parametrize("flag, value, key, default, suffix, bad", STUDENT_OPTIONS)
def test_student_options_set_their_config_key_and_name_the_folder(
    command, flag, value, key, default, suffix, bad
):
    """``--overhead-registration``, ``--brake-limits`` and ``--support-speeds`` set their key
    (default the configuration's) and name the default output folder; none is a learning
    setting (runs share their networks); an unknown value is refused."""
    from imitation.cli import _options_suffix, build_parser, student_changes

    source = [] if command == "reproduce" else ["--reuse-from", "RUN"]
    args = build_parser().parse_args([command, *source, flag, value])
    assert _options_suffix(args) == suffix
    assert student_changes(args) == {key: value}
    section, name = key.split(".")
    if command == "reproduce":
        assert getattr(getattr(reproduce_config(args), section), name) == value
        plain = reproduce_config(build_parser().parse_args(["reproduce"]))
        assert getattr(getattr(plain, section), name) == default
    assert section not in SHARED_LEARNING_SECTIONS
    with pytest.raises(SystemExit):
        build_parser().parse_args([command, *source, flag, bad])


def test_demo_with_the_realistic_preset_records_degraded_frames_and_the_believed_calibration(
    tmp_path,
):
    from imitation.demo import DemoConfig, run_demo
    from perception import camerainfo

    with pytest.raises(ValueError, match="unknown preset 'lab'; allowed: realistic"):
        DemoConfig(preset="lab")
    common = {"seconds": 0.5, "width": 160, "height": 120, "camera": "overhead", "shadows": False}
    plain = run_demo(DemoConfig(**common), tmp_path / "plain.mp4", progress=False)
    real = run_demo(DemoConfig(**common, preset="realistic"), tmp_path / "real.mp4", progress=False)
    nominal = camerainfo.read(plain["recording"]["camera_info"])
    believed = camerainfo.read(real["recording"]["camera_info"])
    assert believed.camera.matrix[0, 0] == pytest.approx(nominal.camera.matrix[0, 0] * 1.02)
    assert (tmp_path / "plain.mp4").read_bytes() != (tmp_path / "real.mp4").read_bytes()
    # The recording's floor photo registers its camera (``peoplebot register``): a top plate
    # anywhere in the arena is read within 3 cm (160x120), more than 5 cm off as believed.
    from imitation import register
    from peoplebot_sim import assets
    from perception.arenafile import read_arena
    from perception.camera import PinholeCamera

    recording = real["recording"]
    fitted = register.run(
        recording["floor_photo"],
        recording["camera_info"],
        assets.FLOOR_MARKERS_TOML,
        recording["arena"],
        tmp_path / "room.toml",
    )
    assert len(fitted["markers"]) == 9

    def camera(arena_path, info):
        room = read_arena(arena_path)
        return PinholeCamera(
            info.camera.matrix,
            info.camera.distortion,
            info.camera.image_size,
            room.camera_rotation,
            room.camera_position_m,
        )

    plates = np.array([[x, y, 1.115] for x in (-1.7, 0.0, 1.7) for y in (-1.7, 0.0, 1.7)])
    pixels = camera(plain["recording"]["arena"], nominal).project(plates)

    def plate_error_m(arena_path):
        back = camera(arena_path, believed).intersect_plane_z(pixels, 1.115)
        return np.linalg.norm(back - plates, axis=1).max()

    assert plate_error_m(recording["arena"]) > 0.05
    assert plate_error_m(tmp_path / "room.toml") < 0.03


def test_results_md_names_the_perturbations_a_run_turned_on():
    from imitation.report import perturbed_settings

    assert perturbed_settings(run_config.RunConfig().to_dict()) == []
    config = dataclasses.replace(run_config.RunConfig(), perturbations=pt.preset("realistic"))
    keys = perturbed_settings(config.to_dict())
    assert "actuation.linear_accel_mps2 = 0.3" in keys and len(keys) == 14


def _teacher_told_and_blind(level: dict, row: str, index: int):
    """Returns the reference teacher's trial of ``row``'s start ``index`` on a robot with the
    acceleration ``level``, told the limits and told none (as before version 0.5.0)."""
    base = run_config.RunConfig().replace({f"perturbations.{k}": v for k, v in level.items()})
    env = trials.student_environment(base)
    item = [p for p in trials.trial_plan(base, ("teacher",)) if p.row == row][index]
    told = trials.run_planned_trial(base, env, item, "teacher", None, None)
    rng = [0, performance.ROWS.index(row), item.index]
    blind = trials.make_agent(base, "teacher", row, env, None, None, rng=rng)
    blind.teacher_config = dataclasses.replace(
        blind.teacher_config, robot_linear_accel_mps2=0.0, robot_yaw_accel_degps2=0.0
    )
    blind.reset()
    untold = performance.run_trial(env, blind, row, item.start, item.wall)
    env.close()
    return told, untold


def test_the_reference_teacher_docks_under_aria_accelerations_by_braking_ahead():
    """Told the robot's acceleration limits (``trials.reference_teacher_config``), the teacher's
    funnel docking stops commanding motion once braking would bring the robot to rest at the dock
    and square; told none it rolls past the dock (0.35 m/s braked at 0.3 m/s^2 rolls 0.2 m) from
    the same start. Without limits the controller is as before."""
    base = run_config.RunConfig().replace(
        {f"perturbations.{k}": v for k, v in pt.ARIA_ACCELERATION.items()}
    )
    told = trials.reference_teacher_config(base)
    assert (told.robot_linear_accel_mps2, told.robot_yaw_accel_degps2) == (0.3, 100.0)
    assert trials.reference_teacher_config(run_config.RunConfig()) == run_config.RunConfig().teacher
    # Demonstrations recorded under limits, a nominal student robot: the reference is told none.
    recorded = run_config.RunConfig().replace({"teacher.robot_linear_accel_mps2": 0.3})
    assert trials.reference_teacher_config(recorded).robot_linear_accel_mps2 == 0.0
    # Start 9: a straight approach, at full speed into the dock.
    braking, rolled = _teacher_told_and_blind(pt.ARIA_ACCELERATION, "pick", 9)
    assert braking.success, braking.reason
    assert not rolled.success, rolled.reason


def test_the_reference_teacher_goes_under_half_aria_accelerations_by_braking_before_walls():
    """In 'go' the teacher told the robot's acceleration limits wants, ahead of it, the clearance
    to a wall plus the distance it rolls on while braking (0.35 m/s at 0.15 m/s^2: 0.41 m), so it
    turns away in time; told none, from the same start it rolls into the wall's clearance, where
    every heading is blocked, and turns in place until the trial ends."""
    braking, stuck = _teacher_told_and_blind(pt.FAMILIES["acceleration"][3], "go", 0)
    assert braking.success, braking.reason
    assert not stuck.success
    assert stuck.reason.startswith("drove under 0.2 m"), stuck.reason


# ----------------------------------------------------------------------- demonstrations under limits
def _teacher_accelerations(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Returns the forward (m/s^2) and yaw (deg/s^2) accelerations, from one control step to the
    next, of a robot's world poses (n, 3) sampled each control step."""
    step = np.diff(poses[:, :2], axis=0)
    heading = poses[:-1, 2]
    forward = (step[:, 0] * np.cos(heading) + step[:, 1] * np.sin(heading)) / DT
    yaw_rate = np.degrees(np.diff(np.unwrap(poses[:, 2]))) / DT
    return np.diff(forward) / DT, np.diff(yaw_rate) / DT


def test_demonstrations_are_recorded_on_a_teacher_robot_with_its_firmware_limits():
    """A teacher told ARIA's limits (``teacher.robot_*_accel``) drives a robot that has them, in
    the recorded stream and in the task alike (the same motion): its measured accelerations stay
    within 0.3 m/s^2 and 100 deg/s^2 (15% for the averaging over a control step) but at the
    switches between driving and turning, where the servos' lag lets one control step reach
    about twice that; the nominal teacher's jump past 2 m/s^2 and 600 deg/s^2."""
    from imitation.streams import StreamGenerator

    limited = dataclasses.replace(
        TaskConfig().teacher, robot_linear_accel_mps2=0.3, robot_yaw_accel_degps2=100.0
    )
    for teacher, capped in ((TaskConfig().teacher, False), (limited, True)):
        config = TaskConfig(teacher=teacher)
        recorded = StreamGenerator(4, config).generate(400).pose_world.astype(float)
        env = load(config, seed=4)
        env.reset()
        watched = [env.step(np.zeros(6)).observation["teacher_pose"] for _ in range(400)]
        env.close()
        np.testing.assert_allclose(np.asarray(watched)[:-1], recorded[1:], atol=1e-4)
        linear, yaw = _teacher_accelerations(recorded)
        if capped:
            assert np.mean(np.abs(linear) <= 0.3 * 1.15) >= 0.9
            assert np.mean(np.abs(yaw) <= 100.0 * 1.15) >= 0.9
            assert np.max(np.abs(linear)) <= 0.3 * 2.5 and np.max(np.abs(yaw)) <= 100.0 * 2.5
        else:
            assert np.max(np.abs(linear)) > 2.0 and np.max(np.abs(yaw)) > 600.0
