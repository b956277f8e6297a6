"""What an episode asks for, and how a step is scored: pure, without a SITL.

Every score is computed from the simulated truth, whatever the policy observes, so a policy
cannot earn it by fooling the FC's estimate.  Per step:

    reward = exp(-distance_m) - 0.1 * tilt_rad - 0.01 * |roll, pitch, yaw sticks|^2

``exp(-distance_m)`` is 1 at the target and 0.37 a metre away; the tilt term asks for a calm
attitude, the stick term for little effort (throttle is not charged: holding height needs
it).  An episode **terminates** when the vehicle crashes (tilted past ``CRASH_TILT_DEG``, or
back on the ground after it had flown), when the FC disarms (a failsafe, its own crash
detection), or when it leaves the bounds (``MAX_DISTANCE_M`` from the target, or above
``MAX_ALT_M``); each of those costs ``FAILURE_REWARD`` once.  It is **truncated** at the
time limit.

:class:`Waypoints` is a course to fly fast, not a point to hold, so it pays progress instead:

    reward = 10 * (metres closed on the current point) - 0.01 * |roll, pitch, yaw sticks|^2

and ``WAYPOINT_BONUS`` for each point reached within ``REACHED_M``; it ends (terminated, a
success) at the last one.  Tilt is free, since speed needs it.  Nothing is charged per step:
the learner's discount already makes progress sooner worth more, and a charge per step would
make an early crash (a one-off ``FAILURE_REWARD``) cheaper than a long, slow lap (docs/gym.md
has the run that tried one).  The points are drawn per episode like :class:`Hover`'s, or
given once as a fixed ``course``.

:class:`Recover` starts from a throw (:mod:`~bfsitl.gym.throws`), upside down perhaps, so
tilt ends nothing there: the ground, a disarm and the bounds do.  Its target is the point the
hand let go at; the episode goes on after the recovery (the hover must hold).  It counts a
**recovery** at the first step the quad is upright within ``RECOVERED_TILT_DEG``, slower than
``RECOVERED_SPEED_M_S`` and turning slower than ``RECOVERED_RATE_RAD_S`` (all at once: a
swing through level is not a hover), and the **height lost**: the throw's height minus the
lowest the quad fell to; ``info`` carries ``recovered``, ``recovered_step`` (steps after the
throw, -1 before) and ``height_lost_m``, and the ``throw`` drawn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bfsitl.gym.snapshot import TrueView, Vec3
from bfsitl.gym.throws import Throw, ThrownState
from bfsitl.mission.crash_check import CRASH_TILT_DEG

MAX_DISTANCE_M = 10.0
MAX_ALT_M = 20.0
FAILURE_REWARD = -10.0
WAYPOINT_BONUS = 5.0
#: Waypoints' pay per metre closed on the current point.
PROGRESS_PER_M = 10.0
#: A waypoint counts as reached within this distance of it.
REACHED_M = 0.5
#: Off the ground after take-off means above this height.
AIRBORNE_M = 0.3
#: A recovery: upright, slow and calm, all at the same step (module docstring).
RECOVERED_TILT_DEG = 20.0
RECOVERED_SPEED_M_S = 1.0
RECOVERED_RATE_RAD_S = 1.0


def distance_m(truth: TrueView, target: Vec3) -> float:
    return math.dist((truth.north_m, truth.east_m, truth.alt_m), target)


def step_reward(truth: TrueView, target: Vec3, action: np.ndarray) -> float:
    """The per-step reward of the module docstring."""
    roll, pitch, _throttle, yaw = (float(v) for v in action)
    tilt_rad = math.radians(truth.tilt_deg)
    return (
        math.exp(-distance_m(truth, target))
        - 0.1 * tilt_rad
        - 0.01 * (roll * roll + pitch * pitch + yaw * yaw)
    )


def failure(
    truth: TrueView, target: Vec3, *, armed: bool, has_flown: bool, tilt_ends: bool = True
) -> str | None:
    """Why the episode must end now (None: it goes on); ``tilt_ends=False`` for a task that
    starts tilted (:class:`Recover`)."""
    if tilt_ends and truth.tilt_deg > CRASH_TILT_DEG:
        return f"crashed: tilted {truth.tilt_deg:.0f} deg"
    if has_flown and truth.on_ground:
        return "crashed: back on the ground"
    if not armed:
        return "the FC disarmed"
    if distance_m(truth, target) > MAX_DISTANCE_M:
        return f"out of bounds: more than {MAX_DISTANCE_M:g} m from the target"
    if truth.alt_m > MAX_ALT_M:
        return f"out of bounds: above {MAX_ALT_M:g} m"
    return None


@dataclass
class Hover:
    """Reach and hold one point: ``north_m`` and ``east_m`` within ``horizontal_m`` of the
    start, ``up_m`` between ``min_alt_m`` and ``max_alt_m``, drawn at each reset."""

    horizontal_m: float = 2.0
    min_alt_m: float = 1.5
    max_alt_m: float = 3.0
    targets: list[Vec3] = field(default_factory=list)
    index: int = 0

    name = "hover"

    def reset(self, rng: np.random.Generator) -> None:
        self.targets = [self._draw(rng)]
        self.index = 0

    def _draw(self, rng: np.random.Generator) -> Vec3:
        north, east = rng.uniform(-self.horizontal_m, self.horizontal_m, size=2)
        return (float(north), float(east), float(rng.uniform(self.min_alt_m, self.max_alt_m)))

    @property
    def target(self) -> Vec3:
        return self.targets[self.index]

    @property
    def next_target(self) -> Vec3 | None:
        """The point after the target (None: the target is the last), for the observation."""
        following = self.index + 1
        return self.targets[following] if following < len(self.targets) else None

    def reward(self, truth: TrueView, action: np.ndarray) -> float:
        """This step's reward, before :meth:`advance` (the module docstring)."""
        return step_reward(truth, self.target, action)

    def advance(self, truth: TrueView) -> tuple[float, bool]:
        """(bonus, finished) after this step: a hover never finishes early."""
        return 0.0, False

    def failure(self, truth: TrueView, *, armed: bool, has_flown: bool) -> str | None:
        """Why this task's episode must end now (None: it goes on)."""
        return failure(truth, self.target, armed=armed, has_flown=has_flown)

    def info(self) -> dict[str, object]:
        """What this task adds to the step's ``info`` (nothing for a hover)."""
        return {}


@dataclass
class Waypoints(Hover):
    """``count`` points in turn, each drawn like :class:`Hover`'s, or the fixed ``course``
    (north, east, up from the start) every episode; the next one is the target, and reaching
    the last ends the episode.  Paid for progress (the module docstring)."""

    count: int = 3
    course: tuple[Vec3, ...] | None = None
    #: The distance to the target at the last step (None: none yet this episode).
    last_distance_m: float | None = None

    name = "waypoints"

    def reset(self, rng: np.random.Generator) -> None:
        if self.course is None:
            self.targets = [self._draw(rng) for _ in range(self.count)]
        else:
            self.targets = list(self.course)
        self.index = 0
        self.last_distance_m = None

    def reward(self, truth: TrueView, action: np.ndarray) -> float:
        roll, pitch, _throttle, yaw = (float(v) for v in action)
        distance = distance_m(truth, self.target)
        last = distance if self.last_distance_m is None else self.last_distance_m
        self.last_distance_m = distance
        return PROGRESS_PER_M * (last - distance) - 0.01 * (roll * roll + pitch * pitch + yaw * yaw)

    def advance(self, truth: TrueView) -> tuple[float, bool]:
        if distance_m(truth, self.target) > REACHED_M:
            return 0.0, False
        if self.index == len(self.targets) - 1:
            return WAYPOINT_BONUS, True
        self.index += 1
        # Progress is counted on the new point from here.
        self.last_distance_m = distance_m(truth, self.target)
        return WAYPOINT_BONUS, False

    def info(self) -> dict[str, object]:
        """How many of the points were reached (the lap's, at its end)."""
        return {"waypoints": len(self.targets)}


@dataclass
class Recover(Hover):
    """Start from a throw drawn from ``throw`` and hold the point it was thrown from (module
    docstring); :attr:`thrown` is this episode's throw, for the environment's hand."""

    throw: Throw = field(default_factory=Throw)
    thrown: ThrownState | None = None
    #: Steps since the throw, and the first one that counted as a recovery (None: not yet).
    steps: int = 0
    recovered_step: int | None = None
    lowest_alt_m: float = math.inf

    name = "recover"

    def reset(self, rng: np.random.Generator) -> None:
        self.targets = [(0.0, 0.0, self.throw.height_m)]
        self.index = 0
        self.thrown = self.throw.draw(rng)
        self.steps = 0
        self.recovered_step = None
        self.lowest_alt_m = self.throw.height_m

    def advance(self, truth: TrueView) -> tuple[float, bool]:
        self.steps += 1
        self.lowest_alt_m = min(self.lowest_alt_m, truth.alt_m)
        if self.recovered_step is None and recovered(truth):
            self.recovered_step = self.steps
        return 0.0, False

    def failure(self, truth: TrueView, *, armed: bool, has_flown: bool) -> str | None:
        return failure(truth, self.target, armed=armed, has_flown=has_flown, tilt_ends=False)

    @property
    def height_lost_m(self) -> float:
        return max(0.0, self.throw.height_m - self.lowest_alt_m)

    def info(self) -> dict[str, object]:
        # The same type under each key at every step (no None): a vector environment makes
        # one array per key from the first episode's value (Gymnasium's own merging).
        assert self.thrown is not None
        return {
            "throw": self.thrown.as_dict(),
            "recovered": self.recovered_step is not None,
            "recovered_step": -1 if self.recovered_step is None else self.recovered_step,
            "height_lost_m": self.height_lost_m,
        }


def recovered(truth: TrueView) -> bool:
    """Upright, slow and calm at once (:class:`Recover`)."""
    speed = math.hypot(truth.v_north_m_s, truth.v_east_m_s, truth.v_up_m_s)
    return (
        truth.tilt_deg < RECOVERED_TILT_DEG
        and speed < RECOVERED_SPEED_M_S
        and math.hypot(*truth.rates_flu_rad_s) < RECOVERED_RATE_RAD_S
    )
