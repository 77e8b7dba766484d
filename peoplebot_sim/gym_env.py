"""The student's world as a Gymnasium environment, beside the dm_env one (``peoplebot_sim.task``).

``PeopleBotStudentEnv`` wraps ``task.load()``: the action drives the student, the scripted teacher (when
present) loops go-pick-lift on its own, and the observation is the dm_env observation dict with
Gymnasium spaces. Importing this module registers the ids in ``ENV_IDS`` (``register_envs``)::

    import gymnasium
    import peoplebot_sim.gym_env  # noqa: F401  (registers PeopleBot/...)

    env = gymnasium.make("PeopleBot/StudentWatching-v0", render_mode="rgb_array")

``gymnasium.make("peoplebot_sim.gym_env:PeopleBot/StudentWatching-v0")`` imports it on the way.
Gymnasium is an optional dependency (the ``gym`` extra).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping

import gymnasium
import numpy as np
from gymnasium import spaces

from peoplebot_sim import directives, task
from peoplebot_sim.rendering import FrameRenderer
from perception.wallframe import ArenaGeometry

#: Control steps of a registered episode before TimeLimit truncates it: 60 s at the default 0.1 s per
#: step, the length of one of the experiment's performance trials.
MAX_EPISODE_STEPS = 600

#: The registered ids and their ``TaskConfig`` overrides.
ENV_IDS = {
    "PeopleBot/StudentWatching-v0": {"with_teacher": True},
    "PeopleBot/StudentOverheadCamera-v0": {"with_teacher": True, "cameras": ("overhead",)},
    "PeopleBot/StudentAlone-v0": {"with_teacher": False},
}

#: What ``reset(options=...)`` accepts: start poses ``(x m, y m, yaw rad)`` for this episode.
RESET_OPTIONS = ("student_pose", "teacher_pose")

#: The camera ``render()`` shows: oblique, the whole arena (``models/arena/README.md``).
RENDER_CAMERA = "showcase"


def observation_space(observation_spec: Mapping, arena: ArenaGeometry) -> spaces.Dict:
    """Returns the Gymnasium space of the dm_env observations described by ``observation_spec``
    (name -> ``dm_env.specs.Array``) in ``arena``; ValueError for an observation it has no bounds for.

    Planar poses ``[x m, y m, yaw rad]`` lie in the arena (+-half side) with yaw in [-pi, pi]; wall
    poses ``[x m, y m, phi deg]`` have x in [0, half side], y in +-half side, phi in [-180, 180];
    head angles (rad) lie in [-pi, pi]; wheel angles (rad) accumulate without bound; the teacher's
    word and directive are indices into ``directives.WORDS`` and ``directives.DIRECTIVES``; camera
    frames are uint8 RGB. Float observations are float64, as the world computes them.
    """
    h = arena.half_side_m
    pi = math.pi
    float_bounds = {
        "pose": ([-h, -h, -pi], [h, h, pi]),
        "wall_pose": ([0.0, -h, -180.0], [h, h, 180.0]),
        "wheel_angles": ([-np.inf] * 2, [np.inf] * 2),
        "head_angles": ([-pi] * 2, [pi] * 2),
    }
    counts = {
        "teacher_word": len(directives.WORDS),
        "teacher_directive": len(directives.DIRECTIVES),
    }
    result = {}
    for name, spec in observation_spec.items():
        role, _, quantity = name.partition("_")
        if name in counts:
            result[name] = spaces.Discrete(counts[name])
        elif name.endswith("_camera"):
            result[name] = spaces.Box(0, 255, shape=spec.shape, dtype=np.uint8)
        elif role in ("student", "teacher") and quantity in float_bounds:
            low, high = float_bounds[quantity]
            result[name] = spaces.Box(np.array(low), np.array(high), dtype=np.float64)
        else:
            raise ValueError(f"no observation space for the world's observation {name!r}")
        if result[name].shape != spec.shape:
            raise ValueError(
                f"observation {name!r} has shape {spec.shape}, its space {result[name].shape}"
            )
    return spaces.Dict(result)


def _zero_reward(observation: dict) -> float:
    return 0.0


class PeopleBotStudentEnv(gymnasium.Env):
    """The student PeopleBot in the imitation world, as a ``gymnasium.Env``.

    Action: a float64 Box over the student's actuators in ``task.ACTION_NAMES`` order, with the
    world's bounds: forward speed m/s, turn rate rad/s, gripper lift m, gripper paddles m, head pan
    rad, head tilt rad. An action outside the Box, of the wrong shape or not finite is refused with
    ValueError and the world does not move (wrap in ``gymnasium.wrappers.ClipAction`` to clip).

    Observation: a Dict of the world's observations by name (``observation_space()`` gives the
    bounds): ``student_pose`` [x m, y m, yaw rad], ``student_wall_pose`` [x m, y m, phi deg],
    ``student_wheel_angles`` and ``student_head_angles`` (rad); with the teacher, ``teacher_pose``,
    ``teacher_wall_pose``, ``teacher_word`` and ``teacher_directive``; for each camera of
    ``config.cameras``, ``<camera>_camera`` as (height, width, 3) uint8 frames.

    Reward: ``reward_fn(observation)``, zero by default: this is an imitation world and a task's
    reward is the user's to define. Never terminated; truncated when the world's ``time_limit``
    ends the episode (infinite by default: registered ids truncate after ``MAX_EPISODE_STEPS``
    through TimeLimit). ``info`` holds ``time_s``, the world's clock in seconds.

    ``reset(seed=s)`` reseeds the world's random state with ``s`` (an integer in [0, 2**32)), so it
    starts as ``task.load(seed=s).reset()`` does; ``options`` may give this episode's start poses
    (``RESET_OPTIONS``, checked by ``ImitationTask.set_start``).

    Args:
      config: the world's configuration (``task.TaskConfig``; with the teacher and without cameras
        by default); keyword ``overrides`` replace its fields.
      render_mode: None or "rgb_array" (``render()`` returns a frame of the showcase camera).
      render_width, render_height: the rendered frame's size in pixels.
      reward_fn: ``observation -> float``; None for zero reward.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        config: task.TaskConfig | None = None,
        *,
        render_mode: str | None = None,
        render_width: int = 320,
        render_height: int = 240,
        reward_fn: Callable[[dict], float] | None = None,
        **overrides,
    ):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            allowed = ", ".join(["None", *self.metadata["render_modes"]])
            raise ValueError(f"unknown render_mode {render_mode!r}; allowed: {allowed}")
        if reward_fn is not None and not callable(reward_fn):
            raise ValueError(
                f"reward_fn must be None or a callable observation -> float, got {reward_fn!r}"
            )
        self.config = dataclasses.replace(config or task.TaskConfig(), **overrides)
        self.render_mode = render_mode
        self.reward_fn = reward_fn or _zero_reward
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.config.control_timestep}
        self._env = task.load(self.config)
        # The world compiles its physics at its first reset and keeps it (it never recompiles), so
        # the renderer can hold it from here on.
        self._env.reset()
        spec = self._env.action_spec()
        self.action_space = spaces.Box(spec.minimum, spec.maximum, dtype=np.float64)
        self.observation_space = observation_space(
            self._env.observation_spec(), self._env.task.geometry
        )
        self._renderer = None
        if render_mode == "rgb_array":
            try:
                self._renderer = FrameRenderer(self._env.physics, render_width, render_height)
            except ValueError:
                self.close()
                raise
        self._needs_reset = True

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Starts an episode; returns ``(observation, info)``."""
        env = self._world()
        super().reset(seed=seed)
        options = {} if options is None else options
        if not isinstance(options, Mapping) or set(options) - set(RESET_OPTIONS):
            raise ValueError(
                f"options must be None or a dict with keys from {', '.join(RESET_OPTIONS)}, "
                f"got {options!r}"
            )
        if options.get("teacher_pose") is not None and not self.config.with_teacher:
            raise ValueError("teacher_pose given, but this world has no teacher")
        if seed is not None:
            if not 0 <= seed < 2**32:
                raise ValueError(f"seed must be an integer in [0, 2**32), got {seed!r}")
            env.random_state.seed(seed)
        env.task.set_start(options.get("student_pose"), options.get("teacher_pose"))
        timestep = env.reset()
        self._needs_reset = False
        return self._observation(timestep.observation), self._info()

    def step(self, action):
        """Drives the student one control step; returns ``(observation, reward, terminated,
        truncated, info)``."""
        env = self._world()
        if self._needs_reset:
            raise RuntimeError("call reset() before step(), and after an episode ends")
        timestep = env.step(np.asarray(action, dtype=np.float64))  # ValueError outside the Box
        observation = self._observation(timestep.observation)
        terminated = truncated = False
        if timestep.last():
            self._needs_reset = True
            terminated = timestep.discount == 0.0
            truncated = not terminated
        reward = float(self.reward_fn(observation))
        return observation, reward, terminated, truncated, self._info()

    def render(self):
        """Returns an (height, width, 3) uint8 frame of the showcase camera ("rgb_array"), or None
        (with a warning) when the environment was made without a render mode."""
        self._world()
        if self._renderer is None:
            gymnasium.logger.warn("render() called without a render_mode; returning None")
            return None
        return self._renderer.render(RENDER_CAMERA)

    def close(self):
        """Frees the renderer and the world; closing again does nothing."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._env is not None:
            self._env.close()
            self._env = None

    def _world(self):
        if self._env is None:
            raise RuntimeError("the environment is closed")
        return self._env

    def _observation(self, raw: Mapping) -> dict:
        """Returns the world's observation as members of the observation space, each a new object."""
        result = {}
        for name, space in self.observation_space.spaces.items():
            if isinstance(space, spaces.Discrete):
                result[name] = np.int64(raw[name])
            else:
                result[name] = np.array(raw[name], dtype=space.dtype)
        return result

    def _info(self) -> dict:
        return {"time_s": float(self._env.physics.time())}


def register_envs() -> None:
    """Registers the ids of ``ENV_IDS`` with Gymnasium (those already registered are left alone)."""
    for env_id, kwargs in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point="peoplebot_sim.gym_env:PeopleBotStudentEnv",
                max_episode_steps=MAX_EPISODE_STEPS,
                kwargs=dict(kwargs),
            )


register_envs()
