"""The scripted teacher: the paper's go-pick-lift loop (Elshaw et al., section III).

The teacher acts only through the four motor directives the student will use, one per control step;
physics moves it through its wheels. It reads its own pose (and the student's, to avoid it) from the
simulator: it is the demonstrator, not a learner.

- 'go' drives forward; reaching a wall (or the table, or the student) it turns away until its heading
  is ``turn_away_deg`` (jittered) from the obstacle's direction, then takes its first step forward.
- It switches to 'pick' near the docking target in front of the table at the middle of the top wall
  when ``-45 < phi < 45`` deg (the paper's condition).
- 'pick' docks: it lines up with the target, faces the table and drives in until it stands square to the
  table in front of the object.
- 'lift' backs away from the table, then turns to face the middle of the arena; then 'go' again.

Disturbances (``slip_rate_per_s``): now and then the robot's wheels do something other than the
teacher commands for a while (an unwanted turn, or rolling on when it should turn), as a real
robot's do; the teacher's commands, which the student is given, stay those of its controller at the
true pose, so the demonstrations also show how to recover from where a disturbance leaves it: the
demonstrator noise of DART (Laskey et al., 2017). ``directive`` is what the teacher commands,
``executed`` what its wheels do.

A watchdog ends any behaviour that makes no progress (no movement while driving, or a behaviour that
lasts too long), logs it and recovers by backing off and turning away in 'go'.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from associator.encoding import DIRECTIVES
from peoplebot_sim.hardware import braking_travel
from perception.wallframe import ArenaGeometry, world_to_wall, wrap_degrees

#: How the teacher's 'pick' reaches the dock (``TeacherConfig.docking``).
DOCKINGS = ("funnel", "lane", "phased")
#: How the docked teacher makes its final alignment (``TeacherConfig.settle``).
SETTLES = ("align", "pattern")


@dataclasses.dataclass(frozen=True)
class TeacherConfig:
    """The teacher's behaviour parameters (metres, degrees, seconds).

    Attributes:
      turn_radius_m: clearance the robot needs to turn in place (its farthest point, the gripper's
        corner, is 0.39 m from its centre) plus a margin.
      lookahead_m: extra clearance wanted straight ahead, scaled by the cosine of the obstacle's
        bearing, so that a robot driving into a wall turns earlier than one passing along it.
      turn_away_deg, turn_away_jitter_deg: after a turn the heading is this far from the obstacle's
        direction (uniform jitter); 180 would reverse, 90 would run along the wall.
      student_radius_m: the student is avoided as a disc of this radius.
      pick_trigger_x_m, pick_max_abs_y_m, pick_max_abs_phi_deg: the 'pick' trigger, in the top
        wall's frame (the paper: close to the target, -45 < phi < 45): closer to the wall than a
        depth drawn each cycle uniformly from the ``pick_trigger_x_m`` (min, max) range, so that
        'pick' is shown from every depth where it is asked for.
      pick_trigger_probability: each time 'go' enters the trigger region it switches to 'pick'
        with this probability; otherwise 'go' goes on there (turning away from the table as from
        any obstacle) until it has left the region, so that 'go' is also shown in front of the
        table.
      dock_x_m: docked distance of the robot's centre from the top wall: table depth 0.40 m, a 6 cm
        gap, then the gripper's 0.365 m reach.
      predock_gap_m: 'pick' lines up this far in front of the docked pose before driving in.
      lateral_tol_m, heading_tol_deg, dock_heading_tol_deg: docking tolerances.
      approach_lead_m, approach_heading_tol_deg: the final approach steers at a point this far
        beyond the docked pose on its centre line, within this heading tolerance.
      settle_pattern: the docked robot's final alignment, small turns in place that cancel out;
        with ``settle = "align"`` only its length counts.
      settle: 'pattern' turns as ``settle_pattern`` says whatever the heading; 'align' turns
        towards square to the table at each step (so the turns alternate about square, and a
        robot docked askew is shown turning back).
      docking: how 'pick' reaches the dock: 'phased' (line up at the pre-dock point, face the
        table, drive in: phases latched once entered) or 'lane' (a function of the pose: inside
        the docking lane it drives in; outside it lines up at the pre-dock point, backing up to it
        when it is nearer the table than that point).
      lane_ratio: the docking lane's half-width over the distance to the approach's aim point
        (``approach_lead_m`` beyond the dock): steering at that point keeps this ratio, so a robot
        inside the lane stays inside it as it drives in.
      funnel_lookahead_m: the 'funnel' docking steers at the centre line this far ahead of the
        robot's depth, or at the dock when it is nearer: a pure pursuit whose lateral offset
        shrinks by e per lookahead driven.
      funnel_tolerance_m: the 'funnel' has arrived when its lateral offset at the dock's depth is
        at most this.
      funnel_miss_m: each 'funnel' docking first pursues a line beside the centre line, its
        offset drawn uniformly within +- this, until its depth in front of the dock is below a
        depth drawn uniformly within (0, ``funnel_miss_depth_fraction`` x
        ``funnel_lookahead_m``); then it steers at the dock, so the demonstrations show how to
        correct a sideways miss near the table (0: never).
      funnel_miss_depth_fraction: see ``funnel_miss_m``, in (0, 1]; below 1 the misses end nearer
        the table, so more dockings arrive at the dock's depth off to the side and show the
        correction along the table (0.5 since version 0.13.0; 1 before).
      funnel_overshoot_s: each 'funnel' docking, on arriving at the dock, rolls on forward for a
        time drawn uniformly within (0, this) seconds (a disturbance: its wheels drive on while
        it commands what its controller says at the true pose), and a robot more than
        ``funnel_tolerance_m`` past the dock's depth, also while it squares up and settles, backs
        out square to the table, so the demonstrations show how to come back from beyond the
        dock (0: never, and no check).
      robot_linear_accel_mps2, robot_yaw_accel_degps2: the robot's firmware limits on the change
        of its speed set-points (0: none, the speeds change at once, as in the simulated robot by
        default). Given, the funnel docking and the squaring stop commanding motion once the
        robot, braking at that limit from its measured speed, would come to rest at the dock or
        square, and 'go' wants, ahead of the robot, the clearance to an obstacle plus the
        distance braking takes (a real controller configured for its robot). The teacher's own
        robot has these limits (``task.teacher_actuation``: in the task and in the recorded
        streams, so demonstrations can be recorded under them); ``imitation.trials`` gives the
        reference teacher the limits of the robot it drives, the student's.
      lift_backoff_m: 'lift' backs away this far from the docked pose.
      face_centre_tol_deg: 'lift' turns until the centre is this close to straight ahead.
      slip_rate_per_s: disturbances per second of each behaviour (a Poisson rate; 0: none). In
        'pick' (while it lines up, faces the table or drives in, not while it settles) a
        disturbance is a turn; in 'go' a turn or rolling forward.
      slip_seconds: a disturbance's turn lasts a time drawn uniformly from this (min, max) range;
        rolling forward at most ``slip_forward_max_s``; its kind is drawn evenly.
      stuck_seconds, stuck_distance_m: the watchdog fires when a robot commanded to drive moves less
        than ``stuck_distance_m`` in ``stuck_seconds``.
      max_seconds: the watchdog also fires when one behaviour lasts longer than this.
    """

    turn_radius_m: float = 0.47
    lookahead_m: float = 0.30
    turn_away_deg: float = 130.0
    turn_away_jitter_deg: float = 35.0
    student_radius_m: float = 0.40
    pick_trigger_x_m: tuple = (1.2, 1.6)
    pick_trigger_probability: float = 0.75
    pick_max_abs_y_m: float = 1.2
    pick_max_abs_phi_deg: float = 45.0
    dock_x_m: float = 0.825
    predock_gap_m: float = 0.45
    lateral_tol_m: float = 0.03
    approach_lead_m: float = 0.5
    settle_pattern: tuple = ("turn_left", "turn_right", "turn_right", "turn_left") * 2
    settle: str = "align"
    approach_heading_tol_deg: float = 4.0
    docking: str = "funnel"
    lane_ratio: float = 0.16
    funnel_lookahead_m: float = 0.3
    funnel_tolerance_m: float = 0.05
    funnel_miss_m: float = 0.25
    funnel_miss_depth_fraction: float = 0.5
    funnel_overshoot_s: float = 0.0
    heading_tol_deg: float = 10.0
    dock_heading_tol_deg: float = 3.0
    robot_linear_accel_mps2: float = 0.0
    robot_yaw_accel_degps2: float = 0.0
    lift_backoff_m: float = 0.9
    face_centre_tol_deg: float = 10.0
    stuck_seconds: float = 4.0
    stuck_distance_m: float = 0.05
    max_seconds: dict = dataclasses.field(
        default_factory=lambda: {"go": 900.0, "pick": 60.0, "lift": 30.0}
    )
    slip_rate_per_s: dict = dataclasses.field(
        default_factory=lambda: {"go": 0.0, "pick": 0.15, "lift": 0.0}
    )
    slip_seconds: tuple = (0.5, 2.0)
    slip_forward_max_s: float = 1.0

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, float) and not (math.isfinite(value) and value >= 0):
                raise ValueError(
                    f"teacher.{field.name} must be a finite number >= 0, got {value!r}"
                )
        if not 0 < self.pick_trigger_probability <= 1:
            raise ValueError(
                "teacher.pick_trigger_probability must be in (0, 1], got "
                f"{self.pick_trigger_probability!r}"
            )
        if not 0 < self.funnel_miss_depth_fraction <= 1:
            raise ValueError(
                "teacher.funnel_miss_depth_fraction must be in (0, 1], got "
                f"{self.funnel_miss_depth_fraction!r}"
            )
        for name in ("funnel_lookahead_m", "funnel_tolerance_m"):
            if getattr(self, name) <= 0:
                raise ValueError(f"teacher.{name} must be > 0 m, got {getattr(self, name)!r}")
        for name in ("slip_seconds", "pick_trigger_x_m"):
            _check_range(f"teacher.{name}", getattr(self, name))
        rates = self.slip_rate_per_s
        if (
            not isinstance(rates, dict)
            or set(rates) != {"go", "pick", "lift"}
            or not all(
                isinstance(v, (int, float)) and math.isfinite(v) and v >= 0 for v in rates.values()
            )
        ):
            raise ValueError(
                "teacher.slip_rate_per_s must give a rate >= 0 per second for go, pick and lift, "
                f"got {rates!r}"
            )
        if self.settle not in SETTLES:
            raise ValueError(
                f"unknown teacher.settle {self.settle!r}; allowed: {', '.join(SETTLES)}"
            )
        if self.docking not in DOCKINGS:
            raise ValueError(
                f"unknown teacher.docking {self.docking!r}; allowed: {', '.join(DOCKINGS)}"
            )
        unknown = [d for d in self.settle_pattern if d not in DIRECTIVES]
        if unknown:
            raise ValueError(
                f"teacher.settle_pattern holds unknown directives {unknown}; allowed: "
                f"{', '.join(DIRECTIVES)}"
            )
        if set(self.max_seconds) != {"go", "pick", "lift"} or not all(
            isinstance(v, (int, float)) and v > 0 for v in self.max_seconds.values()
        ):
            raise ValueError(
                "teacher.max_seconds must give a positive number of seconds for go, pick and "
                f"lift, got {self.max_seconds!r}"
            )

    def undisturbed(self) -> TeacherConfig:
        """Returns these settings without disturbances or drawn misses: the controller alone, as
        the reference row performs."""
        return dataclasses.replace(
            self,
            slip_rate_per_s={"go": 0.0, "pick": 0.0, "lift": 0.0},
            funnel_miss_m=0.0,
            funnel_overshoot_s=0.0,
        )


def _check_range(name: str, low_high) -> None:
    """Raises ValueError unless ``low_high`` is a (min, max) pair with 0 < min <= max."""
    if not (
        isinstance(low_high, (tuple, list))
        and len(low_high) == 2
        and all(isinstance(v, (int, float)) and math.isfinite(v) for v in low_high)
        and 0 < low_high[0] <= low_high[1]
    ):
        raise ValueError(f"{name} must be (min, max) with 0 < min <= max, got {low_high!r}")


@dataclasses.dataclass(frozen=True)
class WatchdogEvent:
    """A logged watchdog recovery: simulated time (s), behaviour, reason, teacher world pose."""

    time_s: float
    behaviour: str
    reason: str
    pose: tuple


class Teacher:
    """The go-pick-lift teacher as a state machine stepped once per control step.

    Args:
      config: behaviour parameters.
      arena: the arena's geometry.
      rng: seed or ``np.random.Generator`` for the jitter of turn angles and directions.
    """

    def __init__(
        self,
        config: TeacherConfig = TeacherConfig(),
        arena: ArenaGeometry = ArenaGeometry(),
        rng=None,
    ):
        self.config = config
        self.arena = arena
        self.reset(rng)

    # ------------------------------------------------------------------ state
    def reset(self, rng=None) -> None:
        """Starts a fresh 'go' behaviour."""
        self._rng = np.random.default_rng(rng)
        self._settle_steps = 0
        self.loop = True
        self.finished = False
        self.word = "go"
        self.directive = "forward"
        self.executed = "forward"
        self._slip_steps = 0
        self._slip_directive = "forward"
        self._miss_m = self._miss_depth_m = self._roll_on_s = 0.0
        self._roll_on_steps = 0
        self._last_pose = None
        self._speed_mps = self._yaw_rate_degps = 0.0
        self.time_s = 0.0
        self.cycles_completed = 0
        self.events: list[WatchdogEvent] = []
        self._enter("go", "drive")
        self._turn_sign = 0.0
        self._turn_target_deg = 0.0
        self._obstacle_bearing = 0.0

    _STATE_FIELDS = (
        "word",
        "directive",
        "time_s",
        "cycles_completed",
        "phase",
        "loop",
        "finished",
        "_settle_steps",
        "_behaviour_start_s",
        "_progress_anchor",
        "_turn_sign",
        "_turn_target_deg",
        "_obstacle_bearing",
        "executed",
        "_slip_steps",
        "_slip_directive",
        "_trigger_x_m",
        "_in_trigger_region",
        "_pick_on_entry",
        "_miss_m",
        "_miss_depth_m",
        "_roll_on_s",
        "_roll_on_steps",
        "_last_pose",
        "_speed_mps",
        "_yaw_rate_degps",
    )

    def get_state(self) -> dict:
        """Returns the controller's full state as plain JSON-able values (for checkpoints)."""
        state = {name: getattr(self, name) for name in self._STATE_FIELDS}
        state["_progress_anchor"] = (
            None if self._progress_anchor is None else [float(v) for v in self._progress_anchor]
        )
        state["events"] = [dataclasses.asdict(e) for e in self.events]
        state["rng"] = self._rng.bit_generator.state
        return state

    def set_state(self, state: dict) -> None:
        """Restores a state from ``get_state``; the controller then continues identically."""
        state = {"_roll_on_s": 0.0, "_roll_on_steps": 0, **state}  # saved before the overshoot
        missing = set(self._STATE_FIELDS) - set(state)
        if missing:
            raise ValueError(f"teacher state lacks {sorted(missing)}")
        for name in self._STATE_FIELDS:
            setattr(self, name, state[name])
        if self._progress_anchor is not None:
            self._progress_anchor = tuple(self._progress_anchor)
        self.events = [
            WatchdogEvent(e["time_s"], e["behaviour"], e["reason"], tuple(e["pose"]))
            for e in state.get("events", [])
        ]
        self._rng = np.random.default_rng()
        self._rng.bit_generator.state = state["rng"]

    def begin(self, word: str, loop: bool = False) -> None:
        """Starts behaviour ``word`` now (as a demonstration of that word alone, when ``loop`` is
        False: 'go' then never switches to 'pick', and a finished 'pick' or 'lift' is reported by
        ``finished`` instead of moving on)."""
        if word not in ("go", "pick", "lift"):
            raise ValueError(f"unknown word {word!r}; allowed: go, pick, lift")
        self.loop = True  # entering the first behaviour is not a transition
        self._enter(word, {"go": "drive", "pick": "line_up", "lift": "back"}[word])
        self.loop = loop
        self.finished = False

    def _enter(self, word: str, phase: str) -> None:
        if not getattr(self, "loop", True) and word != getattr(self, "word", word):
            self.finished = True  # a single behaviour is done: hold it instead of moving on
            self.phase = "done"
            return
        if word == "go":
            self._trigger_x_m = float(self._rng.uniform(*self.config.pick_trigger_x_m))
            self._in_trigger_region = self._pick_on_entry = False
        if word == "pick":
            c = self.config
            self._miss_m = self._miss_depth_m = 0.0
            if c.docking == "funnel" and c.funnel_miss_m > 0:
                self._miss_m = float(self._rng.uniform(-c.funnel_miss_m, c.funnel_miss_m))
                self._miss_depth_m = float(
                    self._rng.uniform(0.0, c.funnel_miss_depth_fraction * c.funnel_lookahead_m)
                )
            self._roll_on_s = 0.0
            if c.docking == "funnel" and c.funnel_overshoot_s > 0:
                self._roll_on_s = float(self._rng.uniform(0.0, c.funnel_overshoot_s))
        self._roll_on_steps = 0
        self.word = word
        self.phase = phase
        self._behaviour_start_s = getattr(self, "time_s", 0.0)
        self._progress_anchor = None

    @property
    def dock_pose(self) -> tuple[float, float, float]:
        """Returns the docked pose ``(x, y, yaw)``: world metres and radians, facing the table."""
        return 0.0, self.arena.half_side_m - self.config.dock_x_m, math.pi / 2

    # ------------------------------------------------------------------ geometry
    def _obstacles(self, x, y, student):
        """Yields ``(distance from the robot's centre to the obstacle's surface, bearing rad)``."""
        h = self.arena.half_side_m
        yield h - x, 0.0
        yield h + x, math.pi
        yield h - y, math.pi / 2
        yield h + y, -math.pi / 2
        x0, x1, y0, y1 = self.arena.table_box
        px, py = min(max(x, x0), x1), min(max(y, y0), y1)
        dx, dy = px - x, py - y
        yield math.hypot(dx, dy), math.atan2(dy, dx)
        if student is not None:
            dx, dy = student[0] - x, student[1] - y
            yield math.hypot(dx, dy) - self.config.student_radius_m, math.atan2(dy, dx)

    def _stopping_distance_m(self) -> float:
        """Returns how far the robot rolls on, metres, braking now from its measured forward speed
        at ``robot_linear_accel_mps2`` (0 without a limit: the speeds change at once)."""
        return max(0.0, braking_travel(self._speed_mps, self.config.robot_linear_accel_mps2))

    def _blocking_obstacle(self, x, y, yaw, student):
        """Returns the bearing of the most pressing obstacle the robot must turn away from, or None
        (ahead of the robot the clearance wanted grows by the distance it needs to stop)."""
        c = self.config
        worst, bearing = 0.0, None
        ahead = c.lookahead_m + self._stopping_distance_m()
        for distance, b in self._obstacles(x, y, student):
            need = c.turn_radius_m + ahead * max(0.0, math.cos(b - yaw))
            if distance < need and need - distance > worst:
                worst, bearing = need - distance, b
        return bearing

    def _turn_towards(self, heading_error_deg: float) -> str:
        return "turn_left" if heading_error_deg > 0 else "turn_right"

    # ------------------------------------------------------------------ the loop
    def step(self, pose, student_pose=None, dt: float = 0.1) -> str:
        """Advances the teacher by one control step.

        Args:
          pose: the teacher's ``(x, y, yaw)``: world metres and radians.
          student_pose: the student's ``(x, y, yaw)`` to avoid, or None.
          dt: control period in seconds.

        Returns:
          The directive for this step (also in ``self.directive``; the word is ``self.word``).
        """
        x, y, yaw = (float(v) for v in pose)
        self.time_s += dt
        if self._last_pose is not None and dt > 0:  # measured speeds, for braking ahead
            x0, y0, yaw0 = self._last_pose
            self._speed_mps = ((x - x0) * math.cos(yaw) + (y - y0) * math.sin(yaw)) / dt
            self._yaw_rate_degps = wrap_degrees(math.degrees(yaw - yaw0)) / dt
        self._last_pose = [x, y, yaw]
        self._watchdog(x, y)
        if getattr(self, "finished", False):
            return self.directive  # a single finished behaviour holds its last directive
        handler = {"go": self._go, "pick": self._pick, "lift": self._lift}[self.word]
        self.directive = handler(x, y, yaw, student_pose)
        self.executed = self._disturbed(self.directive, dt)
        return self.directive

    def _disturbed(self, directive: str, dt: float) -> str:
        """Returns what the wheels do for the commanded ``directive``: a disturbance's while one
        lasts, else the directive."""
        c = self.config
        if self._roll_on_s > 0 and self.phase == "square":
            # the drawn overshoot: arrived at the dock, the wheels roll on
            self._roll_on_steps = max(1, int(round(self._roll_on_s / dt)))
            self._roll_on_s = 0.0
        if self._roll_on_steps > 0:
            self._roll_on_steps -= 1
            return "forward"
        rate = c.slip_rate_per_s[self.word]
        if rate <= 0 or self.phase in ("settle", "done", "backoff"):
            self._slip_steps = 0
            return directive
        if self._slip_steps == 0 and self._rng.random() < 1.0 - math.exp(-rate * dt):
            kinds = ["turn_left", "turn_right"] + (["forward"] if self.word == "go" else [])
            self._slip_directive = str(self._rng.choice(kinds))
            seconds = self._rng.uniform(*c.slip_seconds)
            if self._slip_directive == "forward":
                seconds = min(seconds, c.slip_forward_max_s)
            self._slip_steps = max(1, int(round(seconds / dt)))
        if self._slip_steps == 0:
            return directive
        self._slip_steps -= 1
        return self._slip_directive

    def _escape_direction(self, x, y, student) -> float:
        """Returns the heading (rad) pointing away from the nearby obstacles, each weighted by how
        close it is: in a corner it points out of the corner, not along the next wall."""
        c = self.config
        reach = c.turn_radius_m + c.lookahead_m + 0.3
        ex = ey = 0.0
        for distance, bearing in self._obstacles(x, y, student):
            if distance < reach:
                weight = (reach - distance) / reach
                ex -= weight * math.cos(bearing)
                ey -= weight * math.sin(bearing)
        return math.atan2(ey, ex)

    def _start_turn_away(self, x, y, yaw, bearing, student):
        c = self.config
        relative = wrap_degrees(math.degrees(self._escape_direction(x, y, student) - yaw))
        if abs(relative) > 175.0:
            self._turn_sign = float(self._rng.choice([-1.0, 1.0]))
        else:
            self._turn_sign = 1.0 if relative > 0 else -1.0
        self._obstacle_bearing = bearing
        jitter = self._rng.uniform(-c.turn_away_jitter_deg, c.turn_away_jitter_deg)
        self._turn_target_deg = min(175.0, c.turn_away_deg + jitter)
        self.phase = "turn_away"

    def _go(self, x, y, yaw, student):
        c = self.config
        wall = world_to_wall(x, y, yaw, self.arena)
        inside = (
            wall.wall == "top"
            and wall.x_m < self._trigger_x_m
            and abs(wall.y_m) < c.pick_max_abs_y_m
            and abs(wall.phi_deg) < c.pick_max_abs_phi_deg
        )
        if inside and not self._in_trigger_region:  # entering: 'pick' now, or not this time
            self._pick_on_entry = bool(self._rng.random() < c.pick_trigger_probability)
        self._in_trigger_region = inside
        if getattr(self, "loop", True) and inside and self._pick_on_entry:
            self._enter("pick", "line_up")
            return self._pick(x, y, yaw, student)
        if self.phase == "backoff":
            if self.time_s - self._behaviour_start_s < 1.5:
                return "backward"
            self.phase = "drive"
        bearing = self._blocking_obstacle(x, y, yaw, student)
        if self.phase == "turn_away":
            away = abs(wrap_degrees(math.degrees(yaw - self._obstacle_bearing)))
            if away < self._turn_target_deg or bearing is not None:
                if bearing is not None and away >= self._turn_target_deg:
                    self._obstacle_bearing = (
                        bearing  # a corner: keep turning away from the next wall
                    )
                return "turn_left" if self._turn_sign > 0 else "turn_right"
            self.phase = "drive"
            return "forward"
        if bearing is not None:
            self._start_turn_away(x, y, yaw, bearing, student)
            return "turn_left" if self._turn_sign > 0 else "turn_right"
        return "forward"

    def _pick(self, x, y, yaw, student):
        c = self.config
        dock_x, dock_y, dock_yaw = self.dock_pose
        heading_error = wrap_degrees(math.degrees(dock_yaw - yaw))
        if c.docking in ("lane", "funnel") and self.phase in ("line_up", "approach", "back_up"):
            docking = self._lane_docking if c.docking == "lane" else self._funnel_docking
            directive = docking(x, y, yaw)
            if directive is not None:
                return directive
            self.phase = "square"
        elif (
            c.docking == "funnel" and self.phase in ("square", "settle") and self._rolled_past(y)
        ):  # back out, square to the table
            return self._funnel_docking(x, y, yaw)
        if self.phase == "line_up":
            if abs(x - dock_x) <= c.lateral_tol_m and y <= dock_y:
                self.phase = "face"
            else:
                gx, gy = dock_x, dock_y - c.predock_gap_m
                if math.hypot(gx - x, gy - y) < 0.04:
                    self.phase = "face"
                else:
                    error = wrap_degrees(math.degrees(math.atan2(gy - y, gx - x) - yaw))
                    if abs(error) > c.heading_tol_deg:
                        return self._turn_towards(error)
                    return "forward"
        if self.phase == "face":
            if abs(heading_error) > c.dock_heading_tol_deg:
                return self._turn_towards(heading_error)
            self.phase = "approach"
        if self.phase == "approach":
            if y < dock_y - 0.015:
                # Steer at a point beyond the dock on its centre line: lateral offsets shrink as it
                # drives in, instead of being carried to the table.
                aim = math.atan2(dock_y + c.approach_lead_m - y, dock_x - x)
                error = wrap_degrees(math.degrees(aim - yaw))
                if abs(error) > c.approach_heading_tol_deg:
                    return self._turn_towards(error)
                return "forward"
            self.phase = "square"
        # 'square': stand square to the table.
        if c.robot_yaw_accel_degps2 > 0:  # square and settle: where a turn braked now would end
            heading_error -= braking_travel(self._yaw_rate_degps, c.robot_yaw_accel_degps2)
        if self.phase == "approach" or self.phase == "square":
            if abs(heading_error) > c.dock_heading_tol_deg:
                self.phase = "square"
                return self._turn_towards(heading_error)
            self.phase = "settle"
            self._settle_steps = 0
        # 'settle': the docking's final alignment, small alternating turns in place (the paper's
        # student, told 'pick', "approaches the middle of the top wall and then alternates between
        # left and right turns"); then the pick is done.
        if self._settle_steps < len(c.settle_pattern):
            directive = c.settle_pattern[self._settle_steps]
            if c.settle == "align" and heading_error != 0:
                directive = self._turn_towards(heading_error)
            self._settle_steps += 1
            return directive
        self._enter("lift", "back")
        if self.finished:
            return self.directive
        return self._lift(x, y, yaw, student)

    def _lane_docking(self, x, y, yaw) -> str | None:
        """Returns the 'lane' docking's directive at a pose, or None once it stands at the dock's
        depth inside the lane (then it squares up and settles, as the phased docking does).

        Inside the lane (lateral offset at most ``lane_ratio`` x the distance to the aim point
        ``approach_lead_m`` beyond the dock) it steers at that point and drives in; outside it
        goes to the pre-dock point, forwards when it is farther from the table than that point,
        else backwards (its rear towards the point), so that it never turns its back to the
        table near it."""
        c = self.config
        dock_x, dock_y, _ = self.dock_pose
        lateral = x - dock_x
        to_aim = dock_y + c.approach_lead_m - y
        # Once driving in, a little more room (x 1.25): heading errors within the approach's
        # tolerance move the robot about the lane's edge.
        ratio = c.lane_ratio * (1.25 if self.phase == "approach" else 1.0)
        if abs(lateral) <= ratio * max(to_aim, 0.0):
            if y >= dock_y - 0.015:
                return None
            self.phase = "approach"
            error = wrap_degrees(math.degrees(math.atan2(to_aim, dock_x - x) - yaw))
            if abs(error) > c.approach_heading_tol_deg:
                return self._turn_towards(error)
            return "forward"
        self.phase = "line_up"
        gx, gy = dock_x, dock_y - c.predock_gap_m
        bearing = math.atan2(gy - y, gx - x)
        if y <= gy:
            error = wrap_degrees(math.degrees(bearing - yaw))
            if abs(error) > c.heading_tol_deg:
                return self._turn_towards(error)
            return "forward"
        error = wrap_degrees(math.degrees(bearing - yaw - math.pi))  # the rear's bearing
        if abs(error) > c.heading_tol_deg:
            return self._turn_towards(error)
        return "backward"

    def _rolled_past(self, y) -> bool:
        """Returns whether a robot at world ``y`` (m) stands beyond the dock by more than
        ``funnel_tolerance_m``: checked only with ``funnel_overshoot_s``, which rolls it there."""
        c = self.config
        return c.funnel_overshoot_s > 0 and y > self.dock_pose[1] + c.funnel_tolerance_m

    def _funnel_docking(self, x, y, yaw) -> str | None:
        """Returns the 'funnel' docking's directive at a pose, or None once it stands at the dock
        (at its depth, its lateral offset within ``funnel_tolerance_m``; then it squares up and
        settles).

        It steers at the point of the centre line ``funnel_lookahead_m`` ahead of its depth, or at
        the dock when that is nearer (a pure pursuit: the offset shrinks as exp(-depth driven /
        lookahead)); off the centre line near the table it drives along the table to the dock. The
        heading it wants changes smoothly with the pose; only a robot nearer the table than the
        dock backs out, square to it."""
        c = self.config
        dock_x, dock_y, _ = self.dock_pose
        lateral, depth = x - dock_x, dock_y - y
        if depth <= 0.015 and abs(lateral) <= c.funnel_tolerance_m and not self._rolled_past(y):
            return None
        reach = self._stopping_distance_m()
        if reach > 0:  # braking now, the robot rolls on this far: done if it rests at the dock
            for f in np.linspace(0.0, 1.0, 11)[1:]:
                lx, d = lateral + f * reach * math.cos(yaw), depth - f * reach * math.sin(yaw)
                if d <= 0.015 and abs(lx) <= c.funnel_tolerance_m:
                    return None
        if depth < -0.015:
            self.phase = "back_up"
            error = wrap_degrees(math.degrees(math.pi / 2 - yaw))
            if abs(error) > c.heading_tol_deg:
                return self._turn_towards(error)
            return "backward"
        self.phase = "approach"
        if depth > self._miss_depth_m:  # the drawn miss: pursue a line beside the centre line
            lateral -= self._miss_m
        aim = math.atan2(min(c.funnel_lookahead_m, max(depth, 0.0)), -lateral)
        error = wrap_degrees(math.degrees(aim - yaw))
        if abs(error) > c.approach_heading_tol_deg:
            return self._turn_towards(error)
        return "forward"

    def _lift(self, x, y, yaw, student):
        c = self.config
        _, dock_y, _ = self.dock_pose
        if self.phase == "back":
            if y > dock_y - c.lift_backoff_m:
                return "backward"
            self.phase = "face_centre"
            self._turn_sign = float(self._rng.choice([-1.0, 1.0]))
        error = wrap_degrees(math.degrees(math.atan2(-y, -x) - yaw))
        if abs(error) > c.face_centre_tol_deg:
            return "turn_left" if self._turn_sign > 0 else "turn_right"
        self.cycles_completed += 1
        self._enter("go", "drive")
        return "forward"

    # ------------------------------------------------------------------ watchdog
    def _watchdog(self, x, y):
        c = self.config
        elapsed = self.time_s - self._behaviour_start_s
        reason = None
        if elapsed > c.max_seconds[self.word]:
            reason = f"'{self.word}' lasted over {c.max_seconds[self.word]:.0f} s"
        elif self.directive in ("forward", "backward") and self.executed == self.directive:
            if self._progress_anchor is None:
                self._progress_anchor = (self.time_s, x, y)
            else:
                t0, x0, y0 = self._progress_anchor
                if math.hypot(x - x0, y - y0) >= c.stuck_distance_m:
                    self._progress_anchor = (self.time_s, x, y)
                elif self.time_s - t0 > c.stuck_seconds:
                    reason = (
                        f"moved under {c.stuck_distance_m} m in {c.stuck_seconds} s while driving"
                    )
        else:
            self._progress_anchor = None
        if reason is not None:
            self.events.append(WatchdogEvent(self.time_s, self.word, reason, (x, y)))
            self._enter("go", "backoff")
