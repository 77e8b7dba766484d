"""Camera models of the simulator's cameras, for perception (which never reads the simulator).

MuJoCo cameras look along their -z axis with +y up; OpenCV cameras look along +z with +y down, so
``R_opencv = R_mujoco @ diag(1, -1, -1)``. MuJoCo's ``fovy`` is the vertical field of view and the
renderer uses square pixels, which is what ``PinholeCamera.from_fovy`` builds.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from perception.camera import PinholeCamera, look_at_rotation

_MUJOCO_TO_OPENCV = np.diag([1.0, -1.0, -1.0])


def camera_model(physics, camera, width: int, height: int) -> PinholeCamera:
    """Returns the posed pinhole model of a MuJoCo camera at the physics' current state.

    Args:
      physics: a ``dm_control`` physics (its kinematics must be up to date, as after a step).
      camera: the camera's MJCF element, or its full name in the compiled model (e.g. "overhead",
        "student/head_camera"); works for fixed and moving cameras alike.
      width, height: the rendered image size in pixels.
    """
    if isinstance(camera, str):
        try:
            camera_id = physics.model.name2id(camera, "camera")
        except ValueError:
            names = [physics.model.id2name(i, "camera") for i in range(physics.model.ncam)]
            raise ValueError(f"unknown camera {camera!r}; allowed: {', '.join(names)}") from None
    else:
        camera_id = physics.bind(camera).element_id
    rotation = physics.data.cam_xmat[camera_id].reshape(3, 3) @ _MUJOCO_TO_OPENCV
    position = physics.data.cam_xpos[camera_id].copy()
    fovy = float(physics.model.cam_fovy[camera_id])
    return PinholeCamera.from_fovy(width, height, fovy, rotation, position)


def free_camera_model(physics, camera: mujoco.MjvCamera, width: int, height: int) -> PinholeCamera:
    """Returns the posed pinhole model of a MuJoCo free camera (``peoplebot_sim.viewpoints``) as
    ``FrameRenderer`` renders it: it looks at ``lookat`` from ``distance`` metres along the compass
    ``azimuth`` and ``elevation`` (degrees; MuJoCo's ``mjv_updateCamera``: forward ``(cos el cos az,
    cos el sin az, sin el)``), world z up in the image, the model's ``visual/global/fovy``."""
    if not isinstance(camera, mujoco.MjvCamera) or camera.type != mujoco.mjtCamera.mjCAMERA_FREE:
        raise ValueError(f"camera must be a free mujoco.MjvCamera, got {camera!r}")
    az, el = math.radians(camera.azimuth), math.radians(camera.elevation)
    forward = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    lookat = np.array(camera.lookat, dtype=float)
    position = lookat - camera.distance * forward
    rotation = look_at_rotation(position, lookat)
    fovy = float(physics.model.vis.global_.fovy)
    return PinholeCamera.from_fovy(width, height, fovy, rotation, position)
