"""Camera models of the simulator's cameras, for perception (which never reads the simulator).

MuJoCo cameras look along their -z axis with +y up; OpenCV cameras look along +z with +y down, so
``R_opencv = R_mujoco @ diag(1, -1, -1)``. MuJoCo's ``fovy`` is the vertical field of view and the
renderer uses square pixels, which is what ``PinholeCamera.from_fovy`` builds.
"""

from __future__ import annotations

import numpy as np

from perception.camera import PinholeCamera

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
