"""Self-localisation from wall landmarks (``perception.landmarks``, ``perception.localisation``).

Ground truth is constructed: synthetic corner observations are the map's markers projected through
the head camera at a pose we choose, with Gaussian corner noise of known sigma; odometry increments
are the true motion plus noise drawn from the filter's own motion model. Two tests render real
frames from the MJCF at known poses.
"""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import math
import pathlib

import numpy as np
import pytest
from dm_control import mjcf

from peoplebot_sim import cameras
from peoplebot_sim.task import ImitationTask, TaskConfig
from perception.camera import PinholeCamera
from perception.gaze import GazeConfig, GazeController
from perception.landmarks import (
    LandmarkLocator,
    LandmarkMap,
    LandmarkMarker,
    LocatorConfig,
    invert_planar,
    landmark_view,
    read_landmark_map,
)
from perception.localisation import LocalisationEstimate, LocaliserConfig, SelfLocaliser
from perception.pantilt import head_camera
from perception.pose import wrap_radians

MAP_PATH = pathlib.Path(__file__).resolve().parent.parent / "models" / "arena" / "landmarks.toml"
INTRINSICS = PinholeCamera.from_fovx(320, 240, 45.0)
CORNER_SIGMA_PX = 0.5
TILT_DEG = -15.0


def chi2_mean_bounds(dof: int, n: int, p: float = 0.95) -> tuple[float, float]:
    """Returns the two-sided ``p`` interval of the mean of ``n`` chi-square(``dof``) draws
    (Wilson-Hilferty approximation)."""
    k = dof * n
    z = {0.95: 1.959964, 0.99: 2.575829}[p]
    lo = k * (1 - 2 / (9 * k) - z * math.sqrt(2 / (9 * k))) ** 3
    hi = k * (1 - 2 / (9 * k) + z * math.sqrt(2 / (9 * k))) ** 3
    return lo / n, hi / n


@pytest.fixture(scope="module")
def landmark_map() -> LandmarkMap:
    return read_landmark_map(MAP_PATH)


def observe(landmark_map, pose, pan_deg, rng, sigma_px=CORNER_SIGMA_PX, tilt_deg=TILT_DEG):
    """Returns noisy synthetic detections of the map's markers from ``pose`` at the head angles."""
    camera = head_camera(INTRINSICS, pose, pan_deg, tilt_deg)
    return [(i, c + rng.normal(0.0, sigma_px, c.shape)) for i, c in landmark_map.visible(camera)]


def pose_error(estimate, truth) -> tuple[float, float]:
    """Returns (position error m, heading error deg)."""
    d = np.asarray(estimate) - np.asarray(truth)
    return float(np.hypot(d[0], d[1])), abs(math.degrees(float(wrap_radians(d[2]))))


def random_free_pose(rng) -> np.ndarray:
    """Returns a pose at least 0.4 m inside the walls, clear of the table, any heading."""
    while True:
        x, y = rng.uniform(-1.6, 1.6, 2)
        if not (abs(x) < 0.85 and y > 1.2):
            return np.array([x, y, rng.uniform(-math.pi, math.pi)])


def drive(pose, distance, turn):
    """Returns the pose after an odometry step (chord along the mean heading)."""
    half = 0.5 * turn
    chord = distance * (math.sin(half) / half if abs(half) > 1e-9 else 1.0)
    heading = pose[2] + half
    out = pose + np.array([chord * math.cos(heading), chord * math.sin(heading), turn])
    out[2] = float(wrap_radians(out[2]))
    return out


def noisy_odometry(config: LocaliserConfig, distance, turn, rng):
    """Returns the measured ``(distance, turn)``: the truth plus noise of the filter's model."""
    sd = math.sqrt(config.k_distance**2 * abs(distance) + config.floor_distance_m**2)
    st = math.sqrt(
        config.k_turn**2 * abs(turn)
        + config.k_turn_per_distance**2 * abs(distance)
        + config.floor_turn_rad**2
    )
    return distance + rng.normal(0, sd), turn + rng.normal(0, st)


def wander(pose, rng):
    """Returns a control step's true ``(distance m, turn rad)``: forward, turning away from walls."""
    ahead = drive(pose, 0.5, 0.0)
    if np.max(np.abs(ahead[:2])) > 1.55 or (abs(ahead[0]) < 0.85 and ahead[1] > 1.2):
        return 0.0, math.radians(6.0)
    return 0.035, rng.normal(0.0, math.radians(2.0))


# ------------------------------------------------------------------------------------- the map
def test_map_ids_avoid_the_robots_and_every_wall_carries_markers(landmark_map):
    assert set(landmark_map.ids).isdisjoint({0, 1, 2, 3, 4, 10, 11, 12, 13, 14})
    walls = {(round(m.rotation[0, 2]), round(m.rotation[1, 2])) for m in landmark_map.markers}
    assert walls == {(0, -1), (-1, 0), (0, 1), (1, 0)}
    for marker in landmark_map.markers:  # on a wall face, clipped to the 0.5 m wall's top edge
        assert abs(np.max(np.abs(marker.position_m[:2])) - 1.996) < 1e-9
        plate_bottom = marker.position_m[2] - 0.5 * marker.size_m - landmark_map.quiet_zone_m
        assert 0.4 < plate_bottom < 0.5


def test_map_refuses_robot_ids_and_duplicates():
    with pytest.raises(ValueError, match="robot plate"):
        LandmarkMap([LandmarkMarker.facing(3, 0.3, (0, 2, 0.25), (0, -1, 0))])
    marker = LandmarkMarker.facing(20, 0.3, (0, 2, 0.25), (0, -1, 0))
    with pytest.raises(ValueError, match="twice"):
        LandmarkMap([marker, marker])


def test_map_file_errors_name_the_entry(tmp_path):
    path = tmp_path / "map.toml"
    path.write_text("[[marker]]\nid = 20\nsize_m = 0.3\nposition_m = [0, 2, 0.25]\n")
    with pytest.raises(ValueError, match="marker 0: missing 'normal'"):
        read_landmark_map(path)
    path.write_text('dictionary = "DICT_5X5_100"\n')
    with pytest.raises(ValueError, match="DICT_4X4_50"):
        read_landmark_map(path)


def test_two_landmarks_in_view_from_most_poses_at_some_pan(landmark_map):
    """The placement rule: from a grid over the free arena, every heading, some pan within the
    head's limits shows at least two landmarks (all corners in view, face within 65 deg of the line
    of sight, sides >= 12 px). Known exceptions: 6 of 176 poses, all 0.4 m from a wall (the near
    wall's markers are below the tilt's reach, the others too oblique or out of the pan's range)."""
    misses = total = 0
    for x in np.linspace(-1.6, 1.6, 5):
        for y in np.linspace(-1.6, 1.6, 5):
            if abs(x) < 0.85 and y > 1.2:
                continue
            for yaw in np.radians(np.arange(0, 360, 45)):
                total += 1
                best = max(
                    len(landmark_map.visible(head_camera(INTRINSICS, (x, y, yaw), pan, tilt)))
                    for pan in range(-98, 99, 7)
                    for tilt in (-25, -15)
                )
                if best < 2:
                    assert max(abs(x), abs(y)) > 1.5, (x, y, math.degrees(yaw), best)
                    misses += 1
    assert misses <= 0.06 * total


# ------------------------------------------------------------------------------ one-image fixes
def test_fix_from_constructed_corners_is_within_its_covariance(landmark_map):
    rng = np.random.default_rng(1)
    locator = LandmarkLocator(landmark_map, INTRINSICS)
    errors, nees = [], []
    while len(errors) < 60:
        truth = random_free_pose(rng)
        found = []
        for pan in rng.permutation(np.arange(-90, 91, 15)):
            found = observe(landmark_map, truth, pan, rng)
            if len(found) >= 2:
                break
        if len(found) < 2:
            continue
        fix = locator.locate(found, pan, TILT_DEG)
        assert fix is not None
        e = fix.pose - truth
        e[2] = wrap_radians(e[2])
        nees.append(float(e @ np.linalg.solve(fix.covariance, e)))
        errors.append(pose_error(fix.pose, truth))
    position, heading = np.array(errors).T
    assert np.median(position) < 0.01 and np.percentile(position, 95) < 0.06
    assert np.median(heading) < 0.3 and np.percentile(heading, 95) < 1.0
    lo, hi = chi2_mean_bounds(3, len(nees), 0.99)
    assert lo < np.mean(nees) < hi, np.mean(nees)


def test_the_tilt_offset_is_found_from_the_landmarks(landmark_map):
    """A head whose tilt reads 0.8 deg above the truth (a pan-tilt zero offset): believed, the
    fits from two or more landmarks miss the corners by more than the 2 px gate or lie far off;
    searched, the correction found is within 0.2 deg of the offset and every fix within 5 cm.
    With a true reading the correction stays 0 and nothing changes."""
    rng = np.random.default_rng(3)
    views = []
    while len(views) < 12:
        truth = random_free_pose(rng)
        for pan in rng.permutation(np.arange(-90, 91, 15)):
            found = observe(landmark_map, truth, pan, rng, tilt_deg=TILT_DEG)
            if len(found) >= 2:
                views.append((truth, pan, found))
                break
    believed = LandmarkLocator(landmark_map, INTRINSICS, config=LocatorConfig(tilt_search_deg=0.0))
    searched = LandmarkLocator(landmark_map, INTRINSICS)
    honest = LandmarkLocator(landmark_map, INTRINSICS)
    far = []
    for truth, pan, found in views:
        fix = believed.locate(found, pan, TILT_DEG + 0.8)
        far.append(fix is None or pose_error(fix.pose, truth)[0] > 0.05)
        fix = searched.locate(found, pan, TILT_DEG + 0.8)
        assert fix is not None and pose_error(fix.pose, truth)[0] < 0.05, (truth, pan)
        assert honest.locate(found, pan, TILT_DEG) is not None
    assert np.mean(far) > 0.5
    assert len(searched.tilt_votes) == 12
    assert searched.tilt_correction_deg == pytest.approx(-0.8, abs=0.2)
    assert honest.tilt_correction_deg == pytest.approx(0.0, abs=0.1)
    with pytest.raises(ValueError, match="tilt_search_deg"):
        LocatorConfig(tilt_search_deg=-1.0)


def test_invert_planar_round_trips():
    pose = np.array([0.7, -1.2, 2.5])
    assert np.allclose(invert_planar(invert_planar(pose)), pose)


# -------------------------------------------------------------------------------------- filter
def run_filter(landmark_map, truth, localiser, rng, steps, kidnap_at=None, kidnap_to=None):
    """Drives ``truth`` for ``steps`` control steps, sweeping the head; returns per-step
    ``(truth, estimate)`` pairs."""
    config = localiser.config
    history = []
    aimed = False
    for k in range(steps):
        if kidnap_at is not None and k == kidnap_at:
            truth = np.array(kidnap_to, dtype=float)
        distance, turn = wander(truth, rng)
        truth = drive(truth, distance, turn)
        localiser.predict(*noisy_odometry(config, distance, turn, rng))
        tilt = TILT_DEG
        if localiser.pose_ is None:  # searching: slow pan sweeps, alternately lower
            pan, aimed = 85.0 * math.sin(0.35 * k), False
            tilt = TILT_DEG if (k // 18) % 2 == 0 else TILT_DEG - 12.0
        elif not aimed or k % 5 == 0:  # look where the estimate says most landmarks are
            pan, _, _ = landmark_view(landmark_map, INTRINSICS, localiser.pose_, (TILT_DEG,))
            aimed = True
        found = observe(landmark_map, truth, pan, rng, tilt_deg=tilt)
        estimate = localiser.correct(found, pan, tilt)
        history.append((truth.copy(), estimate))
    return history


def test_filter_is_consistent_nees_and_nis_within_chi_square_bounds(landmark_map):
    """20 seeded runs of 60 steps from a known start, the filter's noise model the truth's (corner
    sigma 0.5 px, no fix floor): the NEES averaged over the runs lies inside the two-sided 95%
    chi-square band on most steps (>= 80%; neighbouring steps are correlated, so the fraction
    scatters between seeds; 0.95 on seeds 7-9), its overall mean is 3 +- 0.5, and its 95th
    percentile is near chi-square's (7.8); the NIS of accepted fixes has a mean inside its band."""
    rng = np.random.default_rng(7)
    runs, steps = 20, 60
    nees = np.zeros((runs, steps))
    nis = []
    rejected = 0
    for run in range(runs):
        truth = random_free_pose(rng)
        localiser = SelfLocaliser(
            LandmarkLocator(
                landmark_map, INTRINSICS, config=LocatorConfig(corner_sigma_px=CORNER_SIGMA_PX)
            ),
            config=LocaliserConfig(fix_floor_sigma=(0.0, 0.0, 0.0)),  # the corners' noise only
        )
        localiser.reset(truth, np.diag([1e-4, 1e-4, 1e-4]))
        for k, (t, estimate) in enumerate(run_filter(landmark_map, truth, localiser, rng, steps)):
            e = estimate.pose - t
            e[2] = wrap_radians(e[2])
            nees[run, k] = e @ np.linalg.solve(estimate.covariance, e)
            if estimate.accepted:
                nis.append(estimate.nis)
            rejected += estimate.accepted is False
    lo, hi = chi2_mean_bounds(3, runs)
    per_step = nees.mean(axis=0)
    assert np.mean((per_step > lo) & (per_step < hi)) >= 0.8, per_step
    assert 2.5 < nees.mean() < 3.5, nees.mean()
    assert np.percentile(nees, 95) < 1.25 * 7.81, np.percentile(nees, 95)
    lo, hi = chi2_mean_bounds(3, len(nis), 0.99)
    assert lo < np.mean(nis) < hi, np.mean(nis)
    assert rejected <= 0.01 * runs * steps


def test_global_initialisation_from_random_starts(landmark_map):
    """Put down anywhere with no start pose, driving: after 5 s (50 steps) of sweeping the head and
    then looking at landmarks the filter has found itself: every start within 5 cm and 3 deg, the
    median within 1 cm and 0.5 deg (measured: docs/perception.md, "Self-localisation")."""
    rng = np.random.default_rng(3)
    errors = []
    for _ in range(12):
        truth = random_free_pose(rng)
        localiser = SelfLocaliser(LandmarkLocator(landmark_map, INTRINSICS))
        t, estimate = run_filter(landmark_map, truth, localiser, rng, 50)[-1]
        assert estimate.status == "tracking", t
        errors.append(pose_error(estimate.pose, t))
    position, heading = np.array(errors).T
    assert position.max() < 0.05 and heading.max() < 3.0, errors
    assert np.median(position) < 0.01 and np.median(heading) < 0.5, errors


def test_kidnapped_robot_recovers(landmark_map):
    """Carried 1.5 m and turned 120 deg between two steps (odometry knows nothing): the fixes are
    rejected, then the filter re-initialises and is back within 3 cm and 1.5 deg in 40 steps."""
    rng = np.random.default_rng(5)
    truth = np.array([-1.0, -1.0, 0.3])
    localiser = SelfLocaliser(LandmarkLocator(landmark_map, INTRINSICS))
    localiser.reset(truth)
    history = run_filter(
        landmark_map, truth, localiser, rng, 70, kidnap_at=30, kidnap_to=(0.6, 0.2, 2.4)
    )
    after = [e for _, e in history[30:]]
    assert any(e.accepted is False for e in after)
    assert any(e.reinitialised for e in after)
    t, estimate = history[-1]
    position, heading = pose_error(estimate.pose, t)
    assert position < 0.03 and heading < 1.5, (t, estimate.pose)


def test_bad_input_is_refused_by_name(landmark_map):
    with pytest.raises(ValueError, match="gate_nis"):
        LocaliserConfig(gate_nis=0.0)
    with pytest.raises(ValueError, match="reinit_after"):
        LocaliserConfig(reinit_after=0)
    with pytest.raises(ValueError, match="corner_sigma_px"):
        LocatorConfig(corner_sigma_px=-1.0)
    locator = LandmarkLocator(landmark_map, INTRINSICS)
    with pytest.raises(ValueError, match="marker 20: corners must be 4 finite pixels"):
        locator.locate([(20, np.zeros((3, 2))), (21, np.zeros((4, 2)))], 0.0, 0.0)
    with pytest.raises(ValueError, match="tilt_deg"):
        locator.locate([], 0.0, float("nan"), prior=(0.0, 0.0, 0.0))
    localiser = SelfLocaliser(locator)
    with pytest.raises(ValueError, match="wheel_angles"):
        localiser.predict_wheels((0.0, float("nan")))
    with pytest.raises(ValueError, match="start_pose"):
        localiser.reset((0.0, 1.0))


# ------------------------------------------------------------------------------ rendered frames
@pytest.fixture(scope="module")
def rendered_scene():
    """Returns ``(task, physics, head intrinsics)`` of the lone student in the MJCF arena."""
    task = ImitationTask(TaskConfig(with_teacher=False))
    physics = mjcf.Physics.from_mjcf_model(task.root_entity.mjcf_model)
    task.initialize_episode(physics, np.random.RandomState(0))
    return task, physics, cameras.camera_model(physics, "student/head_camera", 320, 240)


def render_head(rendered_scene, pose, pan_deg, tilt_deg) -> np.ndarray:
    """Returns the 320x240 head-camera frame of the student standing at ``pose``."""
    task, physics, _ = rendered_scene
    task.student.set_planar_pose(physics, *pose)
    physics.named.data.qpos["student/head_pan"] = math.radians(pan_deg)
    physics.named.data.qpos["student/head_tilt"] = math.radians(tilt_deg)
    physics.forward()
    return physics.render(240, 320, camera_id="student/head_camera")


#: Known poses (x_m, y_m, yaw_deg) spread over the arena, each with the pan that shows the most
#: landmarks from it.
RENDERED_POSES = ((0.3, -0.5, 100.0), (-1.2, 0.9, -30.0), (1.3, -1.4, 160.0), (0.9, 0.6, -100.0))


def test_rendered_frames_locate_the_student(rendered_scene, landmark_map):
    """Real MuJoCo frames at known poses: detection + multi-marker fit within 2 cm and 0.5 deg,
    and the truth inside the fix's 99.9% covariance ellipsoid with the filter's fix floor."""
    _, _, intrinsics = rendered_scene
    locator = LandmarkLocator(landmark_map, intrinsics)
    floor = np.diag(np.square(LocaliserConfig().fix_floor_sigma))
    for x, y, yaw_deg in RENDERED_POSES:
        truth = np.array([x, y, math.radians(yaw_deg)])
        pan, _, n = landmark_view(landmark_map, intrinsics, truth, (TILT_DEG,))
        found = locator.detect(render_head(rendered_scene, truth, pan, TILT_DEG))
        assert len(found) >= min(n, 2), (truth, pan, n, found)
        fix = locator.locate(found, pan, TILT_DEG)
        position, heading = pose_error(fix.pose, truth)
        assert position < 0.02 and heading < 0.5, (truth, fix.pose, fix.marker_ids)
        e = fix.pose - truth
        e[2] = wrap_radians(e[2])
        assert e @ np.linalg.solve(fix.covariance + floor, e) < 16.27


def test_rendered_frames_initialise_the_filter_from_nothing(rendered_scene, landmark_map):
    """Searching, one rendered frame with two or more landmarks puts the filter within 2 cm."""
    _, _, intrinsics = rendered_scene
    localiser = SelfLocaliser(LandmarkLocator(landmark_map, intrinsics))
    truth = np.array([-0.4, -1.0, math.radians(60.0)])
    pan, _, _ = landmark_view(landmark_map, intrinsics, truth, (TILT_DEG,))
    image = render_head(rendered_scene, truth, pan, TILT_DEG)
    estimate = localiser.correct(localiser.locator.detect(image), pan, TILT_DEG)
    assert estimate.reinitialised and estimate.status == "tracking"
    position, heading = pose_error(estimate.pose, truth)
    assert position < 0.02 and heading < 0.5


# -------------------------------------------------------------------------------- active gaze
def test_gaze_shares_the_head_between_teacher_and_landmarks(landmark_map):
    """Searching sweeps at alternate tilts; performing alone looks at landmarks; watching follows
    the teacher until the own position's sigma passes the glance threshold (or a fix is rejected),
    glances at the landmarks, and comes back when a fix has shrunk it (or after the longest
    glance); a glance with no fix turns into a sweep."""
    config = GazeConfig(
        glance_sigma_m=0.03,
        glance_sigma_deg=3.0,
        glance_max_steps=4,
        sweep_after_steps=3,
        sweep_max_steps=2,
    )
    gaze = GazeController(landmark_map, INTRINSICS, config)
    pose = np.array([0.0, -1.0, math.pi / 2])  # facing the table, the top wall 3 m ahead
    teacher = (0.0, 0.5)

    def estimate(sigma_m, accepted=True, rejections=0, sigma_deg=0.5):
        covariance = np.diag([sigma_m**2, sigma_m**2, math.radians(sigma_deg) ** 2])
        return LocalisationEstimate(
            pose, covariance, "tracking", accepted=accepted, rejections=rejections
        )

    searching = LocalisationEstimate(None, None, "searching")
    commands = [gaze.step(searching, None, 0.1) for _ in range(40)]
    assert gaze.target_ == "search"
    assert {c.tilt_deg for c in commands} >= set(config.tilts_deg)
    for _ in range(30):
        command = gaze.step(estimate(0.01), None, 0.1, watching=False)
    assert gaze.target_ == "landmarks"
    pan, tilt, n = landmark_view(landmark_map, INTRINSICS, pose, config.tilts_deg)
    assert n >= 2 and (command.pan_deg, command.tilt_deg) == pytest.approx((pan, tilt))
    gaze.step(estimate(0.01), teacher, 0.1)
    assert gaze.target_ == "teacher"
    gaze.step(estimate(0.05), teacher, 0.1)
    assert gaze.target_ == "landmarks" and gaze.glances_ == 1
    gaze.step(estimate(0.01), teacher, 0.1)  # a fix shrank sigma below half the threshold: back
    assert gaze.target_ == "teacher"
    gaze.step(estimate(0.01, accepted=False, rejections=1), teacher, 0.1)
    assert gaze.target_ == "landmarks" and gaze.glances_ == 2
    targets = [gaze.step(estimate(0.05, None), teacher, 0.1) and gaze.target_ for _ in range(6)]
    assert targets[:2] == ["landmarks"] * 2 and targets[2:5] == ["sweep"] * 3
    assert targets[5] == "teacher"
    gaze.step(estimate(0.01, sigma_deg=5.0), teacher, 0.1)  # the heading alone is doubtful
    assert gaze.target_ == "landmarks" and gaze.glances_ == 3


def test_estimate_is_held_inside_the_arena_and_one_landmark_initialises_in_the_end(landmark_map):
    """Odometry driving through a wall (the wheels slipping against it) leaves the estimate at the
    arena's edge; searching longer than ``single_init_after_steps``, one landmark initialises."""
    config = LocaliserConfig(free_half_side_m=1.8, single_init_after_steps=3)
    localiser = SelfLocaliser(LandmarkLocator(landmark_map, INTRINSICS), config=config)
    localiser.reset((1.6, 0.0, 0.0))
    for _ in range(20):
        localiser.predict(0.035, 0.0)
    assert localiser.pose_[0] == pytest.approx(1.8) and localiser.pose_[1] == pytest.approx(0.0)
    localiser.reset()
    rng = np.random.default_rng(0)
    truth = np.array([0.0, -0.5, math.pi / 2])
    one = observe(landmark_map, truth, 20.0, rng, tilt_deg=-12.0)[:1]
    assert len(one) == 1
    states = [localiser.correct(one, 20.0, -12.0).status for _ in range(5)]
    assert states[:3] == ["searching"] * 3 and states[-1] == "tracking"
    position, heading = pose_error(localiser.pose_, truth)
    assert position < 0.1 and heading < 2.0


def test_contact_with_a_wall_makes_the_filter_doubt_the_wheels(landmark_map):
    """Pushing into a wall, the encoders count 3.5 cm a step while the base stays put: with the
    contact model (the footprint at the estimated pose touches the wall) the covariance grows
    with the slip and the true pose's fix passes the gate; without it the filter stays confident
    and rejects it. Out of contact, the model changes nothing."""
    start = np.array([1.6, 0.0, 0.0])  # facing the +x wall at 2 m: the paddles 3.5 cm from it
    plain = LocaliserConfig()
    contact = LocaliserConfig(wall_half_side_m=2.0, footprint_m=(0.365, 0.2565, 0.2125))
    rng = np.random.default_rng(4)
    pan, tilt, _ = landmark_view(landmark_map, INTRINSICS, start, (-10.0, -20.0))
    found = observe(landmark_map, start, pan, rng, tilt_deg=tilt)
    assert len(found) >= 2
    outcomes = {}
    for name, config in (("plain", plain), ("contact", contact)):
        localiser = SelfLocaliser(LandmarkLocator(landmark_map, INTRINSICS), config=config)
        localiser.reset(start, np.diag([1e-4, 1e-4, 1e-5]))
        for _ in range(10):  # 1 s pushing: 35 cm counted, none moved
            localiser.predict(0.035, 0.0)
        sigma = math.sqrt(localiser.covariance_[0, 0])
        outcomes[name] = (sigma, localiser.correct(found, pan, tilt))
    sigma, estimate = outcomes["plain"]
    assert not estimate.contact and estimate.accepted is False and sigma < 0.03
    sigma, estimate = outcomes["contact"]
    assert estimate.contact and estimate.accepted and sigma > 0.05
    position, _ = pose_error(estimate.pose, start)
    assert position < 0.03
    # Turning in place against the wall, stuck: the heading's sigma grows with the turn.
    localiser = SelfLocaliser(LandmarkLocator(landmark_map, INTRINSICS), config=contact)
    localiser.reset(start, np.diag([1e-4, 1e-4, 1e-5]))
    for _ in range(5):
        localiser.predict(0.0, math.radians(6.0))
    assert localiser.contact_ and math.degrees(math.sqrt(localiser.covariance_[2, 2])) > 10.0
    # In the middle of the arena the two configurations agree exactly.
    a = SelfLocaliser(LandmarkLocator(landmark_map, INTRINSICS), config=plain)
    b = SelfLocaliser(LandmarkLocator(landmark_map, INTRINSICS), config=contact)
    for localiser in (a, b):
        localiser.reset((0.0, -0.5, 0.3))
        for _ in range(10):
            localiser.predict(0.035, 0.02)
    assert not b.contact_
    np.testing.assert_array_equal(a.pose_, b.pose_)
    np.testing.assert_array_equal(a.covariance_, b.covariance_)


def test_contact_with_the_table_and_the_other_robot_and_doubt_after_a_rejection(landmark_map):
    """The footprint near the table's box or the other robot's disc is contact (not a metre
    away); after a rejected fix the wheels are doubted: a step grows the covariance as in
    contact, until ``doubt_fixes`` fixes are accepted."""
    config = LocaliserConfig(
        wall_half_side_m=2.0,
        footprint_m=(0.365, 0.2565, 0.2125),
        obstacle_boxes_m=((-0.5, 0.5, 1.6, 2.0),),
    )
    localiser = SelfLocaliser(LandmarkLocator(landmark_map, INTRINSICS), config=config)
    localiser.reset((0.0, 1.21, math.pi / 2))  # the paddles 2.5 cm from the table
    assert localiser.in_contact(0.01, 0.0)
    localiser.reset((0.0, 0.5, math.pi / 2))
    assert not localiser.in_contact(0.01, 0.0)
    localiser.reset((0.0, 0.0, 0.0))
    assert localiser.in_contact(0.01, 0.0, movers=((0.7, 0.0, 0.33),))
    assert not localiser.in_contact(0.01, 0.0, movers=((1.0, 0.0, 0.33),))
    with pytest.raises(ValueError, match="obstacle_boxes_m"):
        LocaliserConfig(obstacle_boxes_m=((1.0, 0.0, 0.0, 1.0),))

    truth = np.array([0.0, -0.5, math.pi / 2])
    rng = np.random.default_rng(6)
    pan, tilt, _ = landmark_view(landmark_map, INTRINSICS, truth, (-10.0, -20.0))
    found = observe(landmark_map, truth, pan, rng, tilt_deg=tilt)
    localiser = SelfLocaliser(
        LandmarkLocator(landmark_map, INTRINSICS), config=LocaliserConfig(doubt_fixes=2)
    )

    def growth() -> float:
        before = localiser.covariance_[2, 2]
        localiser.predict(0.0, 0.1)
        return localiser.covariance_[2, 2] - before

    localiser.reset(truth + np.array([0.0, 0.0, math.radians(20.0)]), np.diag([1e-6] * 3))
    plain = growth()
    estimate = localiser.correct(found, pan, tilt)
    assert estimate.accepted is False and estimate.doubting
    assert growth() > 0.1**2 > 10 * plain  # the slip's (0.1 rad)^2 on top
    localiser.reset(truth, np.diag([1e-4] * 3))
    localiser.doubt_ = 2
    for _ in range(2):
        estimate = localiser.correct(found, pan, tilt)
        assert estimate.accepted
    assert not estimate.doubting and growth() == pytest.approx(plain)
