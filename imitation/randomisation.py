"""Domain randomisation while the student learns by watching: the ``[randomisation]`` section of
the run configuration.

The student learns from the recorded teacher stream (``imitation.streams``), not through its
camera, so the perturbations that can act while it watches are those of the poses its perception
reports (``perturbations.PerceptionFaults``: the families ``pose_noise``, ``latency``, ``dropout``
and ``occlusion``). With randomisation on, the training stream is seen as a student with such
faults would see it: the stream is cut into segments of ``segment_s`` seconds, each segment draws
every named family's level uniformly between 0 and the family's level ``upper_level`` of its grid
(``perturbations.FAMILIES``; every key of the level scaled by one draw), and its teacher poses
pass through ``PoseCorruptor`` with those faults. A step where the teacher is not seen repeats the
last pose seen (a tracker's last estimate), so the stream keeps its length and the learning its
schedule; the words and the teacher's directives are unchanged. One generator, from the run seed
(``perturbations.rng_for(seed, "randomisation")``), draws the levels and the faults.

On by default since version 0.7.0 (``pose_noise`` and ``latency`` up to level 3: the setting
chosen on the tuning seeds, docs/results.md); ``families = []`` (``--randomise none``) turns it
off. Everything else (the test-time perturbations, the camera, the trials) is unchanged: a
randomised run is tested like any other.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from imitation.observers import pose_or_nan
from imitation.perturbations import FAMILIES, PerceptionFaults, PoseCorruptor, rng_for
from imitation.streams import TeacherStream

#: The families randomised by default (chosen on the tuning seeds 0 and 1; docs/results.md).
DEFAULT_FAMILIES = ("pose_noise", "latency")

#: The sections of the perturbations that act on what the student sees while it watches.
WATCHING_SECTIONS = ("perception",)


def watching_families() -> tuple[str, ...]:
    """Returns the families that can be randomised while the student watches."""
    return tuple(
        family
        for family, levels in FAMILIES.items()
        if all(key.split(".", 1)[0] in WATCHING_SECTIONS for level in levels for key in level)
    )


def parse_families(text: str) -> tuple[str, ...]:
    """Returns the families of ``"pose_noise,latency"`` (``"all"``: every watching family;
    ``"none"``: no randomisation); ValueError listing the allowed ones."""
    allowed = watching_families()
    if text.strip() == "all":
        return allowed
    if text.strip() == "none":
        return ()
    names = tuple(name.strip() for name in text.split(",") if name.strip())
    for name in names:
        if name not in allowed:
            raise ValueError(
                f"--randomise: {name!r} cannot be randomised while the student watches; allowed: "
                f"{', '.join(allowed)}, all or none"
            )
    if not names:
        raise ValueError("--randomise needs at least one family (or all, or none)")
    return names


@dataclasses.dataclass(frozen=True)
class RandomisationConfig:
    """Domain randomisation of the training stream (off when ``families`` is empty; the defaults
    are the setting chosen on the tuning seeds).

    Attributes:
      families: the families randomised (see ``watching_families``), e.g. ("pose_noise",
        "latency").
      upper_level: the index, in each family's grid, of the highest level drawn (a grid shorter
        than that: its last level); 0 draws nothing.
      segment_s: seconds of the training stream that share one draw of the levels.
    """

    families: tuple = DEFAULT_FAMILIES
    upper_level: int = 3
    segment_s: float = 60.0

    def __post_init__(self):
        allowed = watching_families()
        for family in self.families:
            if family not in allowed:
                raise ValueError(
                    f"randomisation.families: {family!r} cannot be randomised while the student "
                    f"watches; allowed: {', '.join(allowed)}"
                )
        if len(set(self.families)) != len(self.families):
            raise ValueError(f"randomisation.families names a family twice: {self.families}")
        if isinstance(self.upper_level, bool) or not (
            isinstance(self.upper_level, int) and self.upper_level >= 0
        ):
            raise ValueError(
                f"randomisation.upper_level must be a level number >= 0, got {self.upper_level!r}"
            )
        if not (math.isfinite(self.segment_s) and self.segment_s > 0):
            raise ValueError(
                f"randomisation.segment_s must be a number of seconds > 0, got {self.segment_s!r}"
            )

    @property
    def active(self) -> bool:
        """Returns whether any family is randomised."""
        return bool(self.families)

    def upper(self, family: str) -> dict:
        """Returns ``family``'s highest level drawn (dotted keys under ``perturbations``)."""
        grid = FAMILIES[family]
        return grid[min(self.upper_level, len(grid) - 1)]


def draw_faults(config: RandomisationConfig, rng: np.random.Generator) -> PerceptionFaults:
    """Returns one segment's faults: every family's upper level scaled by one uniform draw in
    [0, 1) per family."""
    values = {}
    for family in config.families:
        scale = float(rng.uniform(0.0, 1.0))
        for key, value in config.upper(family).items():
            values[key.split(".", 1)[1]] = float(value) * scale
    return PerceptionFaults(**values)


def randomised_stream(
    stream: TeacherStream, config: RandomisationConfig, dt: float, seed: int
) -> tuple[TeacherStream, list[PerceptionFaults]]:
    """Returns the training ``stream`` as the randomised student sees it (see the module notes)
    and the faults of each segment; ``stream`` itself (and no segments) when randomisation is
    off. ``dt``: seconds per step; ``seed``: the run seed."""
    if not config.active:
        return stream, []
    rng = rng_for(seed, "randomisation")
    steps = max(1, round(config.segment_s / dt))
    truth = stream.pose_world.astype(float)
    seen = np.array(truth)
    drawn = []
    last = truth[0]
    for start in range(0, len(stream), steps):
        faults = draw_faults(config, rng)
        drawn.append(faults)
        corruptor = PoseCorruptor(faults, dt, rng, ("teacher",))
        for i in range(start, min(start + steps, len(stream))):
            pose = pose_or_nan(corruptor.step({"teacher": truth[i]})["teacher"])
            if np.all(np.isfinite(pose)):
                last = pose
            seen[i] = last
    return stream.with_world_poses(seen), drawn
