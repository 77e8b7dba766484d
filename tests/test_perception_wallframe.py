"""Properties of the paper's wall frame (perception.wallframe)."""

import numpy as np
import pytest

from perception.wallframe import (
    WALL_NAMES,
    ArenaGeometry,
    WallPose,
    nearest_wall,
    wall_to_world,
    world_to_wall,
    wrap_degrees,
)

ARENA = ArenaGeometry(4.0)


@pytest.mark.parametrize(
    "x, y, wall",
    [(0.0, 1.5, "top"), (1.5, 0.0, "right"), (0.0, -1.5, "bottom"), (-1.5, 0.0, "left")],
)
def test_each_area_facing_its_wall(x, y, wall):
    yaw = np.arctan2(np.sign(y), np.sign(x)) if x or y else 0.0
    pose = world_to_wall(x, y, yaw, ARENA)
    assert pose.wall == wall
    assert pose.x_m == pytest.approx(0.5)
    assert pose.y_m == pytest.approx(0.0)
    assert pose.phi_deg == pytest.approx(0.0)


def test_y_positive_to_the_right_of_an_observer_facing_the_wall():
    # Facing the top wall (north), right is east.
    assert world_to_wall(0.3, 1.5, np.pi / 2, ARENA).y_m == pytest.approx(0.3)
    # Facing the right wall (east), right is south.
    assert world_to_wall(1.5, -0.3, 0.0, ARENA).y_m == pytest.approx(0.3)


def test_phi_positive_counter_clockwise_and_180_faces_away():
    assert world_to_wall(0.0, 1.5, np.pi / 2 + 0.1, ARENA).phi_deg == pytest.approx(np.degrees(0.1))
    assert world_to_wall(0.0, 1.5, -np.pi / 2, ARENA).phi_deg == pytest.approx(-180.0)


def test_rotating_the_arena_by_90_degrees_keeps_the_wall_pose():
    rng = np.random.default_rng(0)
    for _ in range(200):
        x, y = rng.uniform(-2, 2, 2)
        yaw = rng.uniform(-np.pi, np.pi)
        base = world_to_wall(x, y, yaw, ARENA)
        for k in range(1, 4):
            a = k * np.pi / 2
            xr, yr = np.cos(a) * x - np.sin(a) * y, np.sin(a) * x + np.cos(a) * y
            rotated = world_to_wall(xr, yr, yaw + a, ARENA)
            if abs(abs(x) - abs(y)) < 1e-9:
                continue  # on a diagonal: ties break by name order
            np.testing.assert_allclose(rotated.as_array()[:2], base.as_array()[:2], atol=1e-9)
            assert wrap_degrees(rotated.phi_deg - base.phi_deg) == pytest.approx(0.0, abs=1e-9)
            assert WALL_NAMES.index(rotated.wall) != WALL_NAMES.index(base.wall) or k == 0


def test_angle_wrap():
    assert wrap_degrees(180.0) == -180.0
    assert wrap_degrees(-180.0) == -180.0
    assert wrap_degrees(540.0 + 30.0) == pytest.approx(-150.0)
    pose = world_to_wall(0.0, 1.5, np.pi / 2 + 4 * np.pi + 0.2, ARENA)
    assert pose.phi_deg == pytest.approx(np.degrees(0.2))


def test_round_trip_world_wall_world():
    rng = np.random.default_rng(1)
    for _ in range(500):
        x, y = rng.uniform(-2, 2, 2)
        yaw = rng.uniform(-np.pi, np.pi)
        wall = world_to_wall(x, y, yaw, ARENA)
        assert 0.0 <= wall.x_m <= 2.0 + 1e-12 and -2.0 <= wall.y_m <= 2.0
        xb, yb, yawb = wall_to_world(wall, ARENA)
        np.testing.assert_allclose([xb, yb], [x, y], atol=1e-12)
        assert np.cos(yawb - yaw) == pytest.approx(1.0)


def test_diagonal_ties_go_to_first_wall_and_bad_input_raises():
    assert nearest_wall(1.0, 1.0) == "top"
    with pytest.raises(ValueError, match="allowed"):
        wall_to_world(WallPose(1.0, 0.0, 0.0, "ceiling"), ARENA)
    with pytest.raises(ValueError, match="finite"):
        world_to_wall(np.nan, 0.0, 0.0, ARENA)
    with pytest.raises(ValueError, match="side_m"):
        ArenaGeometry(-1.0)
