"""The PeopleBot imitation world: MuJoCo physics and dm-control tasks.

This is the only package that knows about the simulator. Headless rendering is the default: unless
the user has chosen a backend, ``MUJOCO_GL`` is set to ``egl`` before mujoco is imported.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")


def load(config=None, seed=None, **overrides):
    """Returns the imitation environment (a ``dm_env.Environment``); see ``peoplebot_sim.task.load``.

    Imported lazily so that ``import peoplebot_sim`` stays cheap and sets ``MUJOCO_GL`` first.
    """
    from peoplebot_sim.task import load as _load

    return _load(config, seed, **overrides)
