"""``peoplebot register``: the overhead camera's pose from its photo of the floor markers, written
into an arena file, end to end on the simulator's photo; its refusals."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import cv2
import numpy as np
import pytest

from imitation.cli import main
from imitation.observers import Calibration
from peoplebot_sim import assets, registration
from peoplebot_sim.task import TaskConfig, load
from perception import camerainfo
from perception.arenafile import read_arena


@pytest.fixture(scope="module")
def overhead():
    env = load(TaskConfig(with_teacher=False, cameras=("overhead",)), seed=0)
    env.reset()
    camera = Calibration(env.physics, 320, 240).overhead
    env.close()
    return camera


def _files(tmp_path, camera, image):
    photo = tmp_path / "floor.png"
    cv2.imwrite(str(photo), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    info = camerainfo.write(tmp_path / "camera_info.yaml", camera, "overhead")
    return [
        "register",
        str(photo),
        "--camera-info",
        str(info),
        "--markers",
        str(assets.FLOOR_MARKERS_TOML),
        "--arena",
        str(assets.ARENA_TOML),
    ]


def test_register_writes_the_arena_with_the_fitted_camera(tmp_path, overhead, capsys):
    out = tmp_path / "room.toml"
    args = _files(tmp_path, overhead, registration.registration_frame(320, 240))
    assert main([*args, "--out", str(out)]) == 0
    assert "registered on 9 of 9 markers" in capsys.readouterr().out
    room = read_arena(out)
    assert room.arena == read_arena(assets.ARENA_TOML).arena
    position = np.asarray(room.camera_position_m)
    assert np.linalg.norm(position[:2] - overhead.position_world[:2]) < 0.01
    assert abs(position[2] - overhead.position_world[2]) < 0.06  # 4 cm high: see perception.md
    cosine = (
        np.trace(np.asarray(room.camera_rotation).T @ overhead.rotation_world_from_camera) - 1
    ) / 2
    assert np.degrees(np.arccos(min(1.0, cosine))) < 0.1


def test_register_refuses_a_photo_of_another_size_or_without_the_markers(
    tmp_path, overhead, capsys
):
    out = str(tmp_path / "room.toml")
    small = cv2.resize(registration.registration_frame(320, 240), (160, 120))
    assert main([*_files(tmp_path, overhead, small), "--out", out]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(
        "floor.png is 160x120 pixels but "
        + str(tmp_path / "camera_info.yaml")
        + " describes 320x240: photograph at the resolution the camera was "
        "calibrated at"
    )
    blank = np.full((240, 320, 3), 200, np.uint8)
    assert main([*_files(tmp_path, overhead, blank), "--out", out]) == 2
    assert "registration needs at least 4 of the map's 9 markers in view, found 0" in (
        capsys.readouterr().err
    )
    assert not (tmp_path / "room.toml").exists()
