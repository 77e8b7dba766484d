"""A ChArUco calibration board in the arena, and views of it through the simulator's cameras.

The board is a thin box whose +z face carries the printed board (``perception.board.board_image``)
with a white margin of half a square all round, as a sheet glued on a plate. The calibration scene
is the arena with the student (for its head camera) and the board on a free joint, posed by hand:
nothing is simulated, each view is a kinematic pose and a render.

Board body frame: the centre of the printed pattern; x along its ``squares_x`` squares, y along its
``squares_y`` squares, z out of the printed face (the face a camera must see); metres.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import cv2
import mujoco
import numpy as np
from dm_control import composer, mjcf

from peoplebot_sim import cameras, entities
from peoplebot_sim.rendering import FrameRenderer
from perception.board import DEFAULT_BOARD, BoardSpec, board_image
from perception.camera import PinholeCamera

#: White margin around the printed pattern, in squares (each side).
MARGIN_SQUARES = 0.5
#: Half-thickness of the board plate, metres.
HALF_THICKNESS_M = 0.002
#: Texture pixels per board square.
_PIXELS_PER_SQUARE = 96

#: The cameras a calibration scene renders, by their compiled names.
CAMERA_NAMES = ("overhead", "student/head_camera")


@functools.cache
def board_png(spec: BoardSpec) -> bytes:
    """Returns the board's texture as PNG bytes: the printed pattern and its white margin."""
    square_px = _PIXELS_PER_SQUARE
    dots_per_mm = square_px / (spec.square_m * 1000.0)
    pattern = board_image(spec, dots_per_mm)
    margin = int(round(MARGIN_SQUARES * square_px))
    image = cv2.copyMakeBorder(
        pattern, margin, margin, margin, margin, cv2.BORDER_CONSTANT, value=255
    )
    ok, encoded = cv2.imencode(".png", image)
    if not ok:
        raise RuntimeError(f"could not encode the board {spec} as PNG")
    return encoded.tobytes()


class CalibrationBoard(composer.Entity):
    """A rigid ChArUco board, its printed face on the body's +z side."""

    def _build(self, spec: BoardSpec = DEFAULT_BOARD):
        self._spec = spec
        self._mjcf_root = mjcf.RootElement(model="calibration_board")
        texture = self._mjcf_root.asset.add(
            "texture",
            name="board_tex",
            type="2d",
            file=mjcf.Asset(contents=board_png(spec), extension=".png"),
        )
        # Matte: a specular highlight would wash out squares of a tilted board.
        material = self._mjcf_root.asset.add(
            "material", name="board_mat", texture=texture, specular=0.0, shininess=0.0
        )
        width_m, height_m = spec.size_m
        margin_m = MARGIN_SQUARES * spec.square_m
        body = self._mjcf_root.worldbody.add("body", name="board")
        body.add(
            "geom",
            name="board_plate",
            type="box",
            size=[0.5 * width_m + margin_m, 0.5 * height_m + margin_m, HALF_THICKNESS_M],
            pos=[0.0, 0.0, -HALF_THICKNESS_M],  # the printed face through the body's origin
            material=material,
            contype=0,
            conaffinity=0,
            mass=0.2,
        )
        self._body = body

    @property
    def mjcf_model(self):
        return self._mjcf_root

    @property
    def spec(self) -> BoardSpec:
        """Returns the board's specification."""
        return self._spec

    @property
    def root_body(self):
        return self._body


def calibration_physics(spec: BoardSpec = DEFAULT_BOARD):
    """Returns ``(physics, board)``: the arena, the student at the centre facing +x (head level)
    and a free board, kinematics up to date."""
    arena = entities.Arena()
    student = entities.PeopleBot("student")
    board = CalibrationBoard(spec)
    arena.attach(student).add("freejoint")
    arena.attach(board).add("freejoint")
    physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    student.set_planar_pose(physics, 0.0, 0.0, 0.0)
    board.set_pose(physics, position=np.array([0.0, 0.0, 5.5]), quaternion=np.array([1.0, 0, 0, 0]))
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    return physics, board


def _rotation(axis, angle_rad: float) -> np.ndarray:
    rotation = np.zeros(9)
    quaternion = np.zeros(4)
    mujoco.mju_axisAngle2Quat(quaternion, np.asarray(axis, dtype=float), angle_rad)
    mujoco.mju_quat2Mat(rotation, quaternion)
    return rotation.reshape(3, 3)


def random_board_pose(
    camera: PinholeCamera,
    spec: BoardSpec,
    rng: np.random.Generator,
    tilt_deg: tuple[float, float] = (10.0, 50.0),
    fill: tuple[float, float] = (0.55, 0.8),
    margin_px: float = 4.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Returns a board pose ``(position_world (3,), rotation_world_from_board (3, 3))`` that
    ``camera`` sees whole.

    The board faces the camera, turned by a uniform angle about its normal and tilted by
    ``tilt_deg`` (degrees, uniform) about a random axis in its plane; the pattern's width is
    ``fill`` (a fraction, uniform) of the image width as seen square on, and its centre lies
    anywhere that keeps the pattern and margin ``margin_px`` inside the image.
    """
    width_m, height_m = spec.size_m
    margin_m = MARGIN_SQUARES * spec.square_m
    hx, hy = 0.5 * width_m + margin_m, 0.5 * height_m + margin_m
    outline = np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])
    camera_axes = camera.rotation_world_from_camera
    # Square on: board x along the image's x, board y up the image, normal towards the camera.
    facing = np.column_stack([camera_axes[:, 0], -camera_axes[:, 1], -camera_axes[:, 2]])
    for _ in range(1000):
        roll = _rotation((0.0, 0.0, 1.0), rng.uniform(-math.pi, math.pi))
        axis_angle = rng.uniform(-math.pi, math.pi)
        tilt = _rotation(
            (math.cos(axis_angle), math.sin(axis_angle), 0.0), math.radians(rng.uniform(*tilt_deg))
        )
        rotation = facing @ roll @ tilt
        depth_m = camera.matrix[0, 0] * width_m / (rng.uniform(*fill) * camera.width)
        pixel = rng.uniform((0.0, 0.0), camera.image_size)
        ray = camera.pixel_rays(pixel[None])[0]
        position = camera.position_world + ray * depth_m / (ray @ camera_axes[:, 2])
        corners = camera.project(position + outline @ rotation.T)
        if np.all(camera.in_image(corners, margin_px)):
            return position, rotation
    raise RuntimeError(f"no board pose fits the image {camera.image_size}; lower fill {fill}")


@dataclasses.dataclass(frozen=True, eq=False)
class BoardViews:
    """Rendered views of the board through one camera.

    Attributes:
      images: RGB frames, each (height, width, 3) uint8.
      camera: the simulator's camera (intrinsics from MuJoCo's fovy, its pose), the ground truth.
      board_poses: per image, ``(position_world (3,), rotation_world_from_board (3, 3))``.
    """

    images: tuple[np.ndarray, ...]
    camera: PinholeCamera
    board_poses: tuple[tuple[np.ndarray, np.ndarray], ...]


def render_board_views(
    camera_name: str = "overhead",
    n_views: int = 25,
    width: int = 320,
    height: int = 240,
    spec: BoardSpec = DEFAULT_BOARD,
    rng=None,
    **pose_options,
) -> BoardViews:
    """Returns ``n_views`` renders of the board at random poses (:func:`random_board_pose`, whose
    keyword options ``pose_options`` passes on) through ``camera_name``, one of ``CAMERA_NAMES``.

    The student stands at the arena's centre facing +x with its head level; ``rng`` is a seed, a
    generator or None.
    """
    if camera_name not in CAMERA_NAMES:
        raise ValueError(f"unknown camera {camera_name!r}; allowed: {', '.join(CAMERA_NAMES)}")
    if isinstance(n_views, bool) or not isinstance(n_views, int) or n_views <= 0:
        raise ValueError(f"n_views must be a positive integer, got {n_views!r}")
    rng = np.random.default_rng(rng)
    physics, board = calibration_physics(spec)
    camera = cameras.camera_model(physics, camera_name, width, height)
    images, poses = [], []
    quaternion = np.zeros(4)
    with FrameRenderer(physics, width, height) as renderer:
        for _ in range(n_views):
            position, rotation = random_board_pose(camera, spec, rng, **pose_options)
            mujoco.mju_mat2Quat(quaternion, rotation.ravel())
            board.set_pose(physics, position=position, quaternion=quaternion)
            mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
            images.append(renderer.render(camera_name))
            poses.append((position, rotation))
    return BoardViews(tuple(images), camera, tuple(poses))
