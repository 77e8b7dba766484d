"""Composer entities: the PeopleBot (attached twice, as teacher and student), the arena, the table
and the object."""

from __future__ import annotations

import math

import numpy as np
from dm_control import composer, mjcf
from dm_control.composer.observation import observable

from peoplebot_sim import assets
from perception import layout
from perception.landmarks import LandmarkMap, read_landmark_map
from perception.wallframe import ArenaGeometry

#: How far the object stands behind the table's front edge, metres.
OBJECT_SETBACK_M = 0.10

#: Radius in metres of the disc, centred on the robot frame's origin, that holds the PeopleBot's base
#: footprint: the half-diagonal of the 0.513 m x 0.425 m chassis (ARIA's ``RobotLength 513``,
#: ``RobotWidth 425``; ``models/peoplebot/README.md``, ``chassis_collision`` in ``peoplebot.xml``).
#: The wheels, casters, column and deck lie inside it; the gripper, which reaches 0.38 m ahead of
#: the axle at its paddles, does not (a docked robot's gripper reaches towards the table).
BASE_RADIUS_M = 0.5 * math.hypot(0.513, 0.425)


def table_position(arena: ArenaGeometry) -> tuple[float, float, float]:
    """Returns where the table model's origin stands: under the centre of its footprint, world
    metres (``models/arena/table.xml`` has its origin on the floor under its centre)."""
    x0, x1, y0, y1 = arena.table_box
    return (0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0)


def object_position(arena: ArenaGeometry) -> tuple[float, float, float]:
    """Returns where the object stands on the table, world metres: on its top, near its front edge."""
    x0, x1, y0, _ = arena.table_box
    # Rounded to a micrometre, as positions in an MJCF file are written.
    return (0.5 * (x0 + x1), round(y0 + OBJECT_SETBACK_M, 6), arena.table_height_m)


class PeopleBot(composer.Entity):
    """An ActivMedia PeopleBot whose marker plates carry the ids of ``role`` ('teacher' or 'student')."""

    def _build(self, role: str):
        if role not in layout.ROBOT_NAMES:
            raise ValueError(
                f"unknown robot role {role!r}; allowed: {', '.join(layout.ROBOT_NAMES)}"
            )
        self._role = role
        self._mjcf_root = mjcf.from_path(str(assets.PEOPLEBOT_XML))
        self._mjcf_root.model = role
        for placement in layout.default_layout():
            if placement.robot != role:
                continue
            name = f"marker_{placement.face}"
            texture = self._mjcf_root.asset.add(
                "texture",
                name=f"{name}_tex",
                type="2d",
                file=assets.marker_texture_asset(placement.marker_id, placement.size_m),
            )
            material = self._mjcf_root.asset.add("material", name=f"{name}_mat", texture=texture)
            self._mjcf_root.find("geom", name).material = material
        self._actuators = {a.name: a for a in self._mjcf_root.find_all("actuator")}

    def _build_observables(self):
        return PeopleBotObservables(self)

    @property
    def mjcf_model(self):
        return self._mjcf_root

    @property
    def role(self) -> str:
        """Returns 'teacher' or 'student'."""
        return self._role

    @property
    def root_body(self):
        return self._mjcf_root.find("body", "base")

    @property
    def actuators(self) -> dict:
        """Returns the MJCF actuators by name: forward, turn, gripper_lift, gripper_paddles, head_pan,
        head_tilt."""
        return self._actuators

    @property
    def head_camera(self):
        return self._mjcf_root.find("camera", "head_camera")

    def planar_pose(self, physics) -> np.ndarray:
        """Returns ``[x, y, yaw]``: world position in metres and heading in radians (CCW from +x)."""
        body = self.body_id(physics)
        xpos = physics.data.xpos[body]
        xmat = physics.data.xmat[body]
        return np.array([xpos[0], xpos[1], np.arctan2(xmat[3], xmat[0])])

    def body_id(self, physics) -> int:
        """Returns the index of the base body in ``physics`` (cached per compiled model)."""
        key = id(physics.model.ptr)
        if getattr(self, "_body_id_key", None) != key:
            self._body_id = int(physics.bind(self.root_body).element_id)
            self._body_id_key = key
        return self._body_id

    def set_planar_pose(self, physics, x: float, y: float, yaw: float) -> None:
        """Puts the robot on the floor at world ``(x, y)`` metres with heading ``yaw`` radians, at rest."""
        quat = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
        self.set_pose(physics, position=np.array([x, y, 0.0]), quaternion=quat)
        self.set_velocity(physics, velocity=np.zeros(3), angular_velocity=np.zeros(3))


class PeopleBotObservables(composer.Observables):
    """The robot's own observables: its head camera frames and its ground-truth planar pose."""

    @composer.observable
    def head_camera(self):
        return observable.MJCFCamera(self._entity.head_camera, width=320, height=240)

    @composer.observable
    def planar_pose(self):
        return observable.Generic(self._entity.planar_pose)


class _FileEntity(composer.Entity):
    """An entity whose model is one MJCF file."""

    def _build(self, path):
        self._mjcf_root = mjcf.from_path(str(path))

    @property
    def mjcf_model(self):
        return self._mjcf_root


class Table(_FileEntity):
    """The table the teacher docks at (``models/arena/table.xml``)."""

    def _build(self):
        super()._build(assets.TABLE_XML)


class GraspObject(_FileEntity):
    """The object on the table (``models/arena/object.xml``)."""

    def _build(self):
        super()._build(assets.OBJECT_XML)

    @property
    def body(self):
        return self._mjcf_root.find("body", "object")


#: Thickness of a wall landmark's plate, metres (its printed face stands this far off the wall).
LANDMARK_PLATE_THICKNESS_M = 0.004


class Arena(_FileEntity):
    """The walled arena with its cameras (``models/arena/arena.xml``) and its wall landmarks
    (``models/arena/landmarks.toml``), added as plates ``landmark_<id>``."""

    def _build(self, landmarks: LandmarkMap | None = None):
        super()._build(assets.ARENA_XML)
        self._landmarks = (
            read_landmark_map(assets.LANDMARKS_TOML) if landmarks is None else landmarks
        )
        half_thickness = 0.5 * LANDMARK_PLATE_THICKNESS_M
        for marker in self._landmarks.markers:
            name = f"landmark_{marker.marker_id}"
            texture = self._mjcf_root.asset.add(
                "texture",
                name=f"{name}_tex",
                type="2d",
                file=assets.marker_texture_asset(
                    marker.marker_id, marker.size_m, self._landmarks.quiet_zone_m
                ),
            )
            material = self._mjcf_root.asset.add("material", name=f"{name}_mat", texture=texture)
            # The box's +z face is the printed face; its x and y axes are the marker's.
            half = 0.5 * marker.size_m + self._landmarks.quiet_zone_m
            self._mjcf_root.worldbody.add(
                "geom",
                name=name,
                type="box",
                size=(half, half, half_thickness),
                pos=marker.position_m - half_thickness * marker.rotation[:, 2],
                xyaxes=np.concatenate([marker.rotation[:, 0], marker.rotation[:, 1]]),
                material=material,
                contype=0,
                conaffinity=0,
                group=2,
            )

    @property
    def landmarks(self) -> LandmarkMap:
        """Returns the wall landmarks the arena carries."""
        return self._landmarks

    @property
    def overhead_camera(self):
        return self._mjcf_root.find("camera", "overhead")

    @property
    def floor(self):
        return self._mjcf_root.find("geom", "floor")

    @property
    def showcase_camera(self):
        return self._mjcf_root.find("camera", "showcase")
