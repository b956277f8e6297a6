"""The checks of an environment's options, which say what an option takes when it is given
something else (a dict from a config file, a string ``gymnasium.make`` passed on)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from bfsitl.backend.options import LOCKSTEP_EXCHANGES, Timing, World
from bfsitl.errors import EnvironmentConfigError, SimInputError
from bfsitl.gym.latency import Latency
from bfsitl.gym.random_vehicle import RandomVehicle
from bfsitl.gym.random_wind import RandomWind
from bfsitl.gym.snapshot import Vec3
from bfsitl.gym.tasks import MAX_ALT_M, MAX_DISTANCE_M
from bfsitl.mission.session import SitlLaunch
from bfsitl.sim.rc_frames import check_rc_rate

#: Random waypoints at most this far north and east of the start: two in a row are then
#: always inside the bounds (MAX_DISTANCE_M) of each other.
MAX_HORIZONTAL_M = 3.0
#: A course's points fly at least this high (the take-off's lowest start).
MIN_COURSE_UP_M = 0.5


def check_group(name: str, value: object, group: type) -> None:
    """Raise EnvironmentConfigError, saying what it takes, unless ``value`` is a ``group``."""
    # A group given as something else (a dict from a config file, a number for the old
    # ``wind``) is said with what it takes, not as an AttributeError deep in the start.
    if not isinstance(value, group):
        names = ", ".join(f.name for f in dataclasses.fields(group))
        raise EnvironmentConfigError(
            f"{name} must be a {group.__name__} (bfsitl.{group.__name__}({names}), all "
            f"optional), not {type(value).__name__}"
        )


def check_groups(
    sitl: SitlLaunch,
    timing: Timing,
    world: World,
    latency: Latency,
    random_wind: RandomWind | None,
    random_vehicle: RandomVehicle | None,
) -> None:
    """An environment's groups of options, each what it must be and together what the
    lockstep environment can fly; or EnvironmentConfigError saying what to give."""
    check_group("sitl", sitl, SitlLaunch)
    check_group("timing", timing, Timing)
    check_group("world", world, World)
    check_group("latency", latency, Latency)
    if random_wind is not None:
        check_group("random_wind", random_wind, RandomWind)
        if world.wind is not None:
            raise EnvironmentConfigError(
                "random_wind with world.wind: give one wind, drawn per episode "
                "(random_wind) or the same for all (world.wind)"
            )
    if random_vehicle is not None:
        check_group("random_vehicle", random_vehicle, RandomVehicle)
    check_choice("timing.lockstep_exchange", timing.lockstep_exchange, LOCKSTEP_EXCHANGES)
    if timing.lockstep is False:
        raise EnvironmentConfigError(
            "timing.lockstep=False: the environment steps the firmware with the physics; "
            "leave it None or True"
        )
    if world.physics != "embedded":
        raise EnvironmentConfigError(
            f"world.physics={world.physics!r}: the environment flies bfsitl's own "
            f"(embedded) physics, whose steps the lockstep follows"
        )


def check_choice(name: str, value: str, choices: tuple[str, ...]) -> None:
    # The types say it to a type checker; this says it to everyone else (a string from a
    # config file, gymnasium.make's keywords).
    if value not in choices:
        raise EnvironmentConfigError(f"{name} must be one of {', '.join(choices)}, not {value!r}")


def check_horizontal_m(horizontal_m: float) -> None:
    """Random waypoints' spread (``horizontal_m``), or EnvironmentConfigError."""
    if not 0.5 <= horizontal_m <= MAX_HORIZONTAL_M:
        raise EnvironmentConfigError(
            f"horizontal_m {horizontal_m} is outside 0.5..{MAX_HORIZONTAL_M:g} m"
        )


def check_course(course: Sequence[Vec3], *, start_up_m: float) -> tuple[Vec3, ...]:
    """``course`` as a tuple of (north, east, up) points, or EnvironmentConfigError saying
    which point is wrong: not three numbers, too low or high, or out of the bounds of the
    one before (the first: of the start, ``start_up_m`` above where it armed)."""
    points: list[Vec3] = []
    before: Vec3 = (0.0, 0.0, start_up_m)
    for number, point in enumerate(course, start=1):
        try:
            north, east, up = (float(v) for v in point)
        except (TypeError, ValueError):
            raise EnvironmentConfigError(
                f"course point {number} is not three numbers (north, east, up metres): {point!r}"
            ) from None
        if not all(math.isfinite(v) for v in (north, east, up)):
            raise EnvironmentConfigError(f"course point {number} is not finite: {point!r}")
        if not MIN_COURSE_UP_M <= up <= MAX_ALT_M:
            raise EnvironmentConfigError(
                f"course point {number} is {up:g} m up: outside "
                f"{MIN_COURSE_UP_M:g}..{MAX_ALT_M:g} m"
            )
        gap_m = math.dist(before, (north, east, up))
        if gap_m >= MAX_DISTANCE_M:
            raise EnvironmentConfigError(
                f"course point {number} is {gap_m:.1f} m from the one before (the start, "
                f"for the first): the episode ends {MAX_DISTANCE_M:g} m from its target; "
                f"add a point between"
            )
        before = (north, east, up)
        points.append(before)
    if not points:
        raise EnvironmentConfigError("course has no points: give one or more (north, east, up)")
    return tuple(points)


def check_rc_link(rc_rate_hz: float | None, rc_frame_per_step: bool) -> None:
    """The RC link's rate (16 to 1000 Hz, or None: one frame in every fdm packet); a frame
    per step needs a rate, which is what has a 4.6.0 build count the frames."""
    try:
        check_rc_rate(rc_rate_hz)
    except SimInputError as exc:
        raise EnvironmentConfigError(f"rc_rate_hz: {exc}") from None
    if rc_rate_hz is None and rc_frame_per_step:
        raise EnvironmentConfigError(
            "rc_frame_per_step=True with rc_rate_hz=None: a frame in every fdm packet leaves "
            "4.6.0 its stock receiver, which counts no frames; keep a rate (the default)"
        )
