"""Shared tiny fixtures for the experiment tests: a short real teacher stream and an associator
briefly trained on it."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import os

import pytest

from associator import encoding
from associator.network import Associator
from imitation import learning
from imitation.streams import StreamGenerator
from perception.wallframe import ArenaGeometry

ARENA = ArenaGeometry()

#: Control steps of the shared stream (150 s of the teacher looping go-pick-lift).
STREAM_STEPS = 1500


@pytest.fixture(scope="session", autouse=True)
def _no_ray_cluster_from_the_environment():
    """Keeps the tests on Ray instances they start themselves: a ``RAY_ADDRESS`` set where the
    tests run (a CI machine's cluster) would send the sweeps' and transfers' tasks there."""
    address = os.environ.pop("RAY_ADDRESS", None)
    yield
    if address is not None:
        os.environ["RAY_ADDRESS"] = address


@pytest.fixture(scope="session")
def teacher_stream():
    """Returns a real teacher stream of ``STREAM_STEPS`` steps (seed 3; all three words occur)."""
    return StreamGenerator(3).generate(STREAM_STEPS)


def _small_associator(n_steps_total: int, seed: int = 0) -> Associator:
    """Returns an unfitted associator on a small 6 x 12 grid (fast to train)."""
    return Associator(hidden_shape=(6, 12), n_steps_total=n_steps_total, rng=seed)


@pytest.fixture
def small_associator():
    """Returns a factory ``(n_steps_total, seed=0) -> Associator``, unfitted, on a 6 x 12 grid."""
    return _small_associator


@pytest.fixture(scope="session")
def trained_associator(teacher_stream):
    """Returns a small associator fitted once on the shared stream."""
    model = _small_associator(len(teacher_stream))
    return model.fit(
        *learning.encode_stream(
            teacher_stream, encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
        )
    )
