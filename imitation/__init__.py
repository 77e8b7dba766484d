"""The imitation experiment: a student PeopleBot learns by watching the teacher in the simulated
world (``peoplebot_sim``), through its vision (``perception``), with the associator network
(``associator``); the pipeline of ``peoplebot reproduce`` and the ``peoplebot`` command line.

Nothing below this package imports it.
"""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL before anything imports mujoco)
