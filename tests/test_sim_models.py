"""The MJCF models (``models/``): they compile, every element is named, random controls raise no
MuJoCo warning, the marker plates sit where ``perception/layout.py`` says, and the drive tendons
move the robot at the commanded speeds."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import math
import re

import mujoco
import numpy as np
import pytest
from dm_control import mjcf

from peoplebot_sim import assets, directives, entities
from peoplebot_sim.task import ImitationTask, TaskConfig
from perception import landmarks, layout
from perception.wallframe import ArenaGeometry

MODEL_FILES = {
    "peoplebot": assets.PEOPLEBOT_XML,
    "arena": assets.ARENA_XML,
    "table": assets.TABLE_XML,
    "object": assets.OBJECT_XML,
}
#: Element kinds that must be named, with their counts in an ``MjModel``.
NAMED_KINDS = {
    "body": "nbody",
    "joint": "njnt",
    "geom": "ngeom",
    "site": "nsite",
    "camera": "ncam",
    "actuator": "nu",
    "tendon": "ntendon",
}
SNAKE_CASE = re.compile(r"[a-z][a-z0-9_]*")


def composed_scene(seed: int = 0, **config) -> tuple[ImitationTask, mjcf.Physics]:
    """Returns the imitation task and its compiled physics, the episode initialised."""
    task = ImitationTask(TaskConfig(**config))
    physics = mjcf.Physics.from_mjcf_model(task.root_entity.mjcf_model)
    task.initialize_episode(physics, np.random.RandomState(seed))
    return task, physics


def element_names(model: mujoco.MjModel, kind: str) -> list[str]:
    """Returns the names of every element of ``kind`` (the world body excluded)."""
    first = 1 if kind == "body" else 0
    count = getattr(model, NAMED_KINDS[kind])
    return [
        mujoco.mj_id2name(model, getattr(mujoco.mjtObj, f"mjOBJ_{kind.upper()}"), i) or ""
        for i in range(first, count)
    ]


def warning_counts(data: mujoco.MjData) -> dict[str, int]:
    """Returns the non-zero MuJoCo warning counters by warning name."""
    return {
        mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(data.warning) if w.number
    }


# ------------------------------------------------------------------------------- one geometry
def test_the_models_agree_with_the_arena_geometry():
    """The walls' inner faces, the table's footprint and top, and the object in the compiled scene
    are where ``ArenaGeometry`` (the one definition, which the teacher, the success rules and the
    figures read) puts them."""
    task, physics = composed_scene()
    arena = task.geometry
    assert arena == ArenaGeometry()
    h = arena.half_side_m
    walls = {"top": (1, +1), "bottom": (1, -1), "right": (0, +1), "left": (0, -1)}
    for wall, (axis, sign) in walls.items():
        geom = physics.named.model.geom_size[f"wall_{wall}"]
        centre = physics.named.data.geom_xpos[f"wall_{wall}"]
        inner_face = centre[axis] - sign * geom[axis]
        assert inner_face == pytest.approx(sign * h, abs=1e-9), wall
    # The table's footprint: the union of its geoms' boxes, seen from above.
    x0, x1, y0, y1 = arena.table_box
    table = [n for n in element_names(physics.model.ptr, "geom") if n.startswith("table/")]
    lows = np.min(
        [physics.named.data.geom_xpos[n] - physics.named.model.geom_size[n] for n in table], 0
    )
    highs = np.max(
        [physics.named.data.geom_xpos[n] + physics.named.model.geom_size[n] for n in table], 0
    )
    np.testing.assert_allclose([lows[0], highs[0], lows[1], highs[1]], [x0, x1, y0, y1], atol=1e-9)
    assert highs[2] == pytest.approx(arena.table_height_m, abs=1e-9)
    # The object stands on the table's top, on its footprint.
    x, y, _ = physics.named.data.xpos["object/object"]
    assert x0 < x < x1 and y0 < y < y1


# ---------------------------------------------------------------------------------------- compile
@pytest.mark.parametrize("name", sorted(MODEL_FILES))
def test_model_file_compiles_alone(name):
    model = mujoco.MjModel.from_xml_path(str(MODEL_FILES[name]))
    assert model.nbody >= 2 or name == "arena"
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data)
    assert not warning_counts(data)


def test_composed_scene_compiles_with_both_robots_table_and_object():
    _, physics = composed_scene()
    names = set(element_names(physics.model.ptr, "body"))
    assert {"student/base", "teacher/base", "table/table", "object/object"} <= names
    assert physics.model.opt.timestep == pytest.approx(0.01)


# ------------------------------------------------------------------------------------------ names
@pytest.mark.parametrize("kind", sorted(NAMED_KINDS))
def test_every_element_of_the_robot_file_has_a_snake_case_name(kind):
    model = mujoco.MjModel.from_xml_path(str(assets.PEOPLEBOT_XML))
    names = element_names(model, kind)
    assert all(SNAKE_CASE.fullmatch(n) for n in names), names
    assert len(set(names)) == len(names)


@pytest.mark.parametrize("kind", sorted(NAMED_KINDS))
def test_every_element_of_the_composed_scene_has_a_unique_name(kind):
    """Names are ``scope/local``; composer's attachment frames (and their free joints) are named by
    their scope alone, e.g. ``student/``."""
    _, physics = composed_scene()
    names = element_names(physics.model.ptr, kind)
    assert all(names), f"unnamed {kind}: {names}"
    assert len(set(names)) == len(names), f"duplicate {kind} names: {names}"
    for name in names:
        local = name.rsplit("/", 1)[-1]
        if local == "" and kind in ("body", "joint"):
            continue  # an attachment frame or its free joint
        assert SNAKE_CASE.fullmatch(local), f"{kind} {name!r} is not snake_case"


# --------------------------------------------------------------------------------------- stepping
def _random_control_rollout(model, data, seconds: float, rng) -> None:
    """Steps ``seconds`` of simulated time under uniform random controls within ``ctrlrange``,
    redrawn every 0.1 s; fails on any MuJoCo warning or non-finite state."""
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    assert np.all(model.actuator_ctrllimited)
    substeps = int(round(0.1 / model.opt.timestep))
    for _ in range(int(round(seconds / 0.1))):
        data.ctrl[:] = rng.uniform(low, high)
        mujoco.mj_step(model, data, substeps)
        assert not warning_counts(data), f"t={data.time:.2f} s: {warning_counts(data)}"
        for field in ("qpos", "qvel", "qacc", "act", "sensordata"):
            assert np.all(np.isfinite(getattr(data, field))), f"{field} not finite at {data.time}"


def test_robot_alone_steps_under_random_controls_without_warnings():
    model = mujoco.MjModel.from_xml_path(str(assets.PEOPLEBOT_XML))
    data = mujoco.MjData(model)
    _random_control_rollout(model, data, seconds=3.0, rng=np.random.default_rng(0))


@pytest.mark.parametrize("seed", [0, 1])
def test_composed_scene_steps_under_random_controls_without_warnings(seed):
    _, physics = composed_scene(seed)
    model, data = physics.model.ptr, physics.data.ptr
    _random_control_rollout(model, data, seconds=5.0, rng=np.random.default_rng(seed))
    # The robots stay upright on the floor (no tipping, no sinking, no flying).
    for robot in ("student", "teacher"):
        body = physics.model.name2id(f"{robot}/base", "body")
        up = data.xmat[body].reshape(3, 3)[:, 2]
        assert up[2] > math.cos(math.radians(5.0)), f"{robot} tilted: up axis {up}"
        assert abs(data.xpos[body][2]) < 0.01, f"{robot} base height {data.xpos[body][2]}"


# ---------------------------------------------------------------------------------- marker plates
def plate_mismatches(model: mujoco.MjModel) -> list[str]:
    """Returns how the marker plates of a compiled robot model (``peoplebot.xml`` alone, base at the
    world origin) differ from ``perception.layout``; empty when they agree.

    A plate is a box geom ``marker_<face>``: its +z face carries the marker, so that face's centre
    must be the placement's ``position_m``, the geom frame's axes the columns of its ``rotation``,
    and its half-sides half the marker plus the white quiet zone.
    """
    problems = []
    base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base")
    for placement in layout.default_layout():
        name = f"marker_{placement.face}"
        geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
        if geom < 0:
            problems.append(f"{name}: no such geom")
            continue
        if model.geom_bodyid[geom] != base:
            problems.append(f"{name}: not on the base body")
        rotation = np.empty(9)
        mujoco.mju_quat2Mat(rotation, model.geom_quat[geom])
        rotation = rotation.reshape(3, 3)
        half = model.geom_size[geom]
        face_centre = model.geom_pos[geom] + half[2] * rotation[:, 2]
        if not np.allclose(face_centre, placement.position_m, atol=1e-4):
            problems.append(
                f"{name} ({placement.robot}): face centre {face_centre} != layout "
                f"{placement.position_m}"
            )
        if not np.allclose(rotation, placement.rotation, atol=1e-5):
            problems.append(
                f"{name} ({placement.robot}): axes\n{rotation}\n!= layout\n{placement.rotation}"
            )
        plate_half = 0.5 * placement.size_m + layout.QUIET_ZONE_M
        if not np.allclose(half[:2], plate_half, atol=1e-6):
            problems.append(f"{name}: half-sides {half[:2]} != marker/2 + quiet zone {plate_half}")
    return problems


def _robot_model_with_edited_plate(face: str, attribute: str, value: str) -> mujoco.MjModel:
    """Returns the robot model compiled after replacing one attribute of one marker plate."""
    text = assets.PEOPLEBOT_XML.read_text()
    pattern = rf'(<geom name="marker_{face}"[^>]*?\b{attribute}=")[^"]*(")'
    edited, count = re.subn(pattern, rf"\g<1>{value}\g<2>", text, flags=re.DOTALL)
    assert count == 1, f"marker_{face} has no {attribute} to edit"
    return mujoco.MjModel.from_xml_string(edited)


def test_marker_plates_sit_where_the_layout_says():
    model = mujoco.MjModel.from_xml_path(str(assets.PEOPLEBOT_XML))
    assert plate_mismatches(model) == []


@pytest.mark.parametrize(
    "face, attribute, value",
    [
        ("back", "pos", "-0.172 0 0.72"),  # moved 1 cm
        ("top", "pos", "-0.06 0.005 1.117"),  # moved 5 mm sideways
        ("left", "quat", "0.7071068 0.7071068 0 0"),  # turned to face right
        ("front", "size", "0.14 0.14 0.002"),  # shrunk
    ],
)
def test_plate_check_fails_when_a_plate_is_moved(face, attribute, value):
    problems = plate_mismatches(_robot_model_with_edited_plate(face, attribute, value))
    assert problems and all(f"marker_{face}" in p for p in problems), problems


def test_composed_robots_carry_their_own_marker_textures():
    _, physics = composed_scene()
    model = physics.model
    for placement in layout.default_layout():
        geom = model.name2id(f"{placement.robot}/marker_{placement.face}", "geom")
        material = model.id2name(model.geom_matid[geom], "material")
        assert material == f"{placement.robot}/marker_{placement.face}_mat"


# ----------------------------------------------------------------------------------- wall landmarks
def landmark_mismatches(model, landmark_map) -> list[str]:
    """Returns how the wall landmark plates of a compiled arena differ from ``landmark_map``; empty
    when they agree.

    A plate is a box geom ``landmark_<id>`` on the world body with the material
    ``landmark_<id>_mat``: its +z face's centre must be the marker's ``position_m``, its axes the
    marker's, its half-sides half the marker plus the quiet zone; and no other plate may exist.
    """
    problems = []
    names = [model.id2name(i, "geom") or "" for i in range(model.ngeom)]
    plates = {n.rsplit("/", 1)[-1] for n in names if n.rsplit("/", 1)[-1].startswith("landmark_")}
    expected = {f"landmark_{m.marker_id}" for m in landmark_map.markers}
    problems += [f"{name}: not in the map" for name in sorted(plates - expected)]
    for marker in landmark_map.markers:
        name = f"landmark_{marker.marker_id}"
        if name not in plates:
            problems.append(f"{name}: no such geom")
            continue
        geom = model.name2id(name, "geom")
        if model.geom_bodyid[geom] != 0:
            problems.append(f"{name}: not on the world body")
        rotation = np.empty(9)
        mujoco.mju_quat2Mat(rotation, model.geom_quat[geom])
        rotation = rotation.reshape(3, 3)
        half = model.geom_size[geom]
        face_centre = model.geom_pos[geom] + half[2] * rotation[:, 2]
        if not np.allclose(face_centre, marker.position_m, atol=1e-4):
            problems.append(f"{name}: face centre {face_centre} != map {marker.position_m}")
        if not np.allclose(rotation, marker.rotation, atol=1e-5):
            problems.append(f"{name}: axes\n{rotation}\n!= map\n{marker.rotation}")
        plate_half = 0.5 * marker.size_m + landmark_map.quiet_zone_m
        if not np.allclose(half[:2], plate_half, atol=1e-6):
            problems.append(f"{name}: half-sides {half[:2]} != marker/2 + quiet zone {plate_half}")
        material = model.id2name(model.geom_matid[geom], "material") or ""
        if not material.endswith(f"{name}_mat"):
            problems.append(f"{name}: material {material!r}")
    return problems


def test_wall_landmarks_sit_where_the_map_says():
    landmark_map = landmarks.read_landmark_map(assets.LANDMARKS_TOML)
    _, physics = composed_scene()
    assert landmark_mismatches(physics.model, landmark_map) == []


def test_landmark_check_fails_when_the_map_and_the_plates_differ():
    landmark_map = landmarks.read_landmark_map(assets.LANDMARKS_TOML)
    first, *rest = landmark_map.markers
    moved = landmarks.LandmarkMarker.facing(
        first.marker_id, first.size_m, first.position_m + (0.05, 0, 0), first.rotation[:, 2]
    )
    arena = entities.Arena(landmarks=landmarks.LandmarkMap([moved, *rest[:-1]]))
    physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    problems = landmark_mismatches(physics.model, landmark_map)
    assert any(f"landmark_{first.marker_id}: face centre" in p for p in problems), problems
    assert any(f"landmark_{rest[-1].marker_id}: no such geom" in p for p in problems), problems


def test_floor_markers_lie_where_their_file_says_and_the_overhead_camera_sees_them_all():
    """The registration photo's scene carries the wall landmarks and the floor markers as the files
    say (ids apart), and the overhead camera finds all nine floor markers in it."""
    from peoplebot_sim import registration
    from perception.markers import MarkerDetector

    walls = landmarks.read_landmark_map(assets.LANDMARKS_TOML)
    floor = registration.floor_markers()
    assert not set(walls.ids) & set(floor.ids)
    both = landmarks.LandmarkMap(walls.markers + floor.markers, quiet_zone_m=walls.quiet_zone_m)
    physics = mjcf.Physics.from_mjcf_model(entities.Arena(landmarks=both).mjcf_model)
    assert landmark_mismatches(physics.model, both) == []
    found = MarkerDetector().detect_all_corners(registration.registration_frame(320, 240))
    assert sorted(i for i, _ in found if i in floor) == list(floor.ids)


# ------------------------------------------------------------------------------------------ drive
def _drive(ctrl_forward: float, ctrl_turn: float, seconds: float = 2.5, window_s: float = 1.0):
    """Drives the lone student from rest (west of the centre, facing +x) with constant servo
    targets; returns its mean ``(speed along heading m/s, sideways speed m/s, yaw rate rad/s)`` over
    the last ``window_s`` of ``seconds`` (from 1.5 s to 2.5 s by default: after 2 s, averaged over
    any rocking)."""
    task, physics = composed_scene(with_teacher=False)
    task.student.set_planar_pose(physics, -0.8, 0.0, 0.0)
    model, data = physics.model.ptr, physics.data.ptr
    mujoco.mj_forward(model, data)
    physics.named.data.ctrl["student/forward"] = ctrl_forward
    physics.named.data.ctrl["student/turn"] = ctrl_turn
    n_before = int(round((seconds - window_s) / model.opt.timestep))
    n_window = int(round(window_s / model.opt.timestep))
    mujoco.mj_step(model, data, n_before)
    x0, y0, yaw0 = task.student.planar_pose(physics)
    yaws = [yaw0]
    for _ in range(n_window):
        mujoco.mj_step(model, data)
        yaws.append(task.student.planar_pose(physics)[2])
    x1, y1, _ = task.student.planar_pose(physics)
    heading = 0.5 * (yaws[0] + yaws[-1]) if ctrl_turn == 0 else yaws[-1]
    dx, dy = x1 - x0, y1 - y0
    along = (dx * math.cos(heading) + dy * math.sin(heading)) / window_s
    sideways = (-dx * math.sin(heading) + dy * math.cos(heading)) / window_s
    yaw_rate = float(np.sum(np.diff(np.unwrap(yaws)))) / window_s
    assert not warning_counts(data)
    return along, sideways, yaw_rate


@pytest.mark.parametrize("speed", [0.35, -0.35, 0.75])
def test_forward_actuator_drives_at_the_commanded_speed(speed):
    # Fails if the casters drag (their contact friction must not be the floor's).
    along, sideways, yaw_rate = _drive(speed, 0.0)
    assert along == pytest.approx(speed, rel=0.03)
    assert abs(sideways) < 0.02
    assert abs(yaw_rate) < math.radians(2.0)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_turn_actuator_rotates_counter_clockwise_at_the_commanded_rate(sign):
    _, rate = directives.DriveSpeeds().command("turn_left")
    along, sideways, yaw_rate = _drive(0.0, sign * rate)
    assert yaw_rate == pytest.approx(sign * rate, rel=0.15)
    assert abs(along) < 0.02 and abs(sideways) < 0.02
