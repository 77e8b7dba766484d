"""The Gymnasium environment (``peoplebot_sim.gym_env``): Gymnasium's own checker on every registered
id, seeded determinism, refused actions, reset options, rendering and closing."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import warnings

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

# isort: split
from dm_env import specs  # noqa: E402
from gymnasium.utils.env_checker import check_env  # noqa: E402

from peoplebot_sim import gym_env, task  # noqa: E402
from perception.wallframe import ArenaGeometry  # noqa: E402

#: The warnings check_env gives by design: the action Box is in physical units (not [-1, 1]), and
#: wheel angles accumulate without bound.
EXPECTED_WARNINGS = (
    "we recommend using a symmetric and normalized space",
    "observation space minimum value is -infinity",
    "observation space maximum value is infinity",
)


@pytest.fixture
def make():
    """Returns ``make(env_id, **kwargs)`` (``gymnasium.make``); closes what it made afterwards."""
    made = []

    def _make(env_id="PeopleBot/StudentWatching-v0", **kwargs):
        env = gymnasium.make(env_id, **kwargs)
        made.append(env)
        return env

    yield _make
    for env in made:
        env.close()


def rollout(env, seed: int, n_steps: int = 20) -> list[dict]:
    """Returns the observations of a seeded reset and ``n_steps`` seeded random actions."""
    env.action_space.seed(seed)
    observations = [env.reset(seed=seed)[0]]
    for _ in range(n_steps):
        observations.append(env.step(env.action_space.sample())[0])
    return observations


# ------------------------------------------------------------------------------ registration
@pytest.mark.parametrize("env_id", sorted(gym_env.ENV_IDS))
def test_check_env_passes_with_only_the_expected_warnings(make, env_id):
    env = make(env_id)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=False)
    unexpected = [
        str(w.message) for w in caught if not any(e in str(w.message) for e in EXPECTED_WARNINGS)
    ]
    assert unexpected == []


@pytest.mark.parametrize("env_id", sorted(gym_env.ENV_IDS))
def test_make_gives_the_registered_world(make, env_id):
    env = make(env_id)
    assert env.spec.max_episode_steps == gym_env.MAX_EPISODE_STEPS
    assert isinstance(env.unwrapped, gym_env.PeopleBotStudentEnv)
    observation, info = env.reset(seed=0)
    assert observation in env.observation_space
    assert info["time_s"] == 0.0
    teacher = env_id != "PeopleBot/StudentAlone-v0"
    assert ("teacher_pose" in observation) == teacher
    assert ("teacher_directive" in observation) == teacher
    camera = env_id == "PeopleBot/StudentOverheadCamera-v0"
    assert ("overhead_camera" in observation) == camera
    if camera:
        frame = observation["overhead_camera"]
        assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8 and frame.std() > 0
    assert env.action_space.shape == (len(task.ACTION_NAMES),)


def test_the_time_limit_truncates_and_ids_load_their_module(make):
    env = make("peoplebot_sim.gym_env:PeopleBot/StudentAlone-v0", max_episode_steps=3)
    env.reset(seed=0)
    still = np.zeros(env.action_space.shape)
    ends = [env.step(still)[2:4] for _ in range(3)]
    assert ends == [(False, False), (False, False), (False, True)]


def test_the_worlds_own_time_limit_truncates_then_asks_for_a_reset(make):
    env = make("PeopleBot/StudentAlone-v0", time_limit=0.3).unwrapped
    env.reset(seed=0)
    still = np.zeros(env.action_space.shape)
    ends = [env.step(still)[2:4] for _ in range(3)]
    assert ends == [(False, False), (False, False), (False, True)]
    with pytest.raises(RuntimeError, match="reset"):
        env.step(still)
    env.reset()
    env.step(still)


def test_register_envs_is_idempotent():
    before = {env_id: gymnasium.registry[env_id] for env_id in gym_env.ENV_IDS}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gym_env.register_envs()
        gym_env.register_envs()
    assert {env_id: gymnasium.registry[env_id] for env_id in gym_env.ENV_IDS} == before


# ------------------------------------------------------------------------------ spaces
def test_spaces_have_the_worlds_bounds_and_units(make):
    env = make().unwrapped
    world = task.load()
    spec = world.action_spec()
    world.close()
    np.testing.assert_array_equal(env.action_space.low, spec.minimum)
    np.testing.assert_array_equal(env.action_space.high, spec.maximum)
    assert env.action_space.dtype == np.float64
    half = ArenaGeometry().half_side_m
    pose = env.observation_space["student_pose"]
    np.testing.assert_array_equal(pose.high, [half, half, np.pi])
    wall = env.observation_space["teacher_wall_pose"]
    np.testing.assert_array_equal(wall.low, [0.0, -half, -180.0])
    assert env.observation_space["teacher_word"].n == 3
    assert env.observation_space["teacher_directive"].n == 4


def test_observation_space_refuses_an_observation_it_has_no_bounds_for():
    spec = {"student_speed": specs.Array((2,), np.float64, "student_speed")}
    with pytest.raises(ValueError, match="student_speed"):
        gym_env.observation_space(spec, ArenaGeometry())


# ------------------------------------------------------------------------------ seeding
def test_same_seed_same_observations_over_20_random_actions(make):
    first = rollout(make("PeopleBot/StudentOverheadCamera-v0", width=64, height=48), seed=5)
    env = make("PeopleBot/StudentOverheadCamera-v0", width=64, height=48)
    again = rollout(env, seed=5)
    other = rollout(env, seed=6)
    for a, b in zip(first, again, strict=True):
        assert a.keys() == b.keys()
        assert a in env.observation_space
        for name in a:
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    assert not np.allclose(first[0]["teacher_pose"], other[0]["teacher_pose"])
    # The student moved under the random actions.
    assert np.ptp([o["student_head_angles"][0] for o in first]) > 0.1


def test_reset_seed_is_the_worlds_seed(make):
    env = make()
    observation, _ = env.reset(seed=11)
    world = task.load(seed=11)
    expected = world.reset().observation
    world.close()
    for name, value in observation.items():
        np.testing.assert_array_equal(value, expected[name], err_msg=name)


def test_a_seed_outside_the_worlds_range_is_refused(make):
    with pytest.raises(ValueError, match="2\\*\\*32"):
        make().reset(seed=2**32)


# ------------------------------------------------------------------------------ actions
def test_actions_outside_the_space_are_refused_and_the_world_stays(make):
    env = make().unwrapped
    env.reset(seed=0)
    high = env.action_space.high
    _, _, _, _, info = env.step(high)  # the bounds themselves are allowed
    for i, name in enumerate(task.ACTION_NAMES):
        action = high.copy()
        action[i] += 0.01
        with pytest.raises(ValueError, match=name):
            env.step(action)
    for bad in (np.zeros(5), np.full(6, np.nan)):
        with pytest.raises(ValueError):
            env.step(bad)
    assert env.step(np.zeros(6))[4]["time_s"] == pytest.approx(info["time_s"] + 0.1)


def test_clip_action_clips_instead(make):
    env = gymnasium.wrappers.ClipAction(make())
    env.reset(seed=0)
    observation = env.step(np.full(6, 10.0))[0]
    assert observation in env.observation_space


def test_step_before_reset_is_refused():
    env = gym_env.PeopleBotStudentEnv(with_teacher=False)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(6))
    env.close()


# ------------------------------------------------------------------------------ reset options
def test_reset_options_set_the_start_poses_for_one_episode(make):
    env = make()
    student, teacher = (0.0, -1.0, 0.5), (1.0, 0.5, -2.0)
    observation, _ = env.reset(seed=0, options={"student_pose": student, "teacher_pose": teacher})
    np.testing.assert_allclose(observation["student_pose"], student, atol=1e-6)
    np.testing.assert_allclose(observation["teacher_pose"], teacher, atol=1e-6)
    observation, _ = env.reset(seed=0)
    np.testing.assert_allclose(observation["student_pose"], task.STUDENT_WATCH_POSE, atol=1e-6)
    with pytest.raises(ValueError, match="overlaps"):
        env.reset(options={"student_pose": student, "teacher_pose": (0.1, -1.0, 0.0)})
    with pytest.raises(ValueError, match="student_pose, teacher_pose"):
        env.reset(options={"student_start": student})
    with pytest.raises(ValueError, match="no teacher"):
        make("PeopleBot/StudentAlone-v0").reset(options={"teacher_pose": teacher})


# ------------------------------------------------------------------------------ reward
def test_reward_is_zero_unless_a_reward_fn_is_given(make):
    env = make()
    env.reset(seed=0)
    assert env.step(np.zeros(6))[1] == 0.0
    env = make(reward_fn=lambda observation: -float(observation["student_pose"][0]))
    env.reset(seed=0)
    observation, reward, *_ = env.step(np.zeros(6))
    assert reward == -observation["student_pose"][0]
    with pytest.raises(ValueError, match="reward_fn"):
        gym_env.PeopleBotStudentEnv(reward_fn=0.0)


# ------------------------------------------------------------------------------ render and close
def test_render_returns_showcase_frames_of_the_configured_size(make):
    env = make(render_mode="rgb_array")
    assert env.metadata["render_fps"] == pytest.approx(10)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8 and frame.std() > 0
    env = make(render_mode="rgb_array", render_width=160, render_height=120)
    env.reset(seed=0)
    assert env.render().shape == (120, 160, 3)
    with pytest.warns(UserWarning, match="render_mode"):
        assert make().unwrapped.render() is None
    with pytest.raises(ValueError, match="rgb_array"):
        gym_env.PeopleBotStudentEnv(render_mode="human")
    with pytest.raises(ValueError, match="width"):
        gym_env.PeopleBotStudentEnv(render_mode="rgb_array", render_width=0)


def test_close_is_idempotent_and_final(make):
    env = make("PeopleBot/StudentOverheadCamera-v0", render_mode="rgb_array").unwrapped
    env.reset(seed=0)
    env.render()
    env.close()
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.reset()
