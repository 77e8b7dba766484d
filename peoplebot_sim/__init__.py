"""The PeopleBot imitation world: MuJoCo physics and dm-control tasks.

This is the only package that knows about the simulator. Headless rendering is the default: unless
the user has chosen a backend, ``MUJOCO_GL`` is set to ``egl`` before mujoco is imported.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
