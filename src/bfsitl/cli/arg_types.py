"""Argument types that check a value when the command line is read, before anything starts.

A value out of range is an argparse error (``bfsitl fly: error: argument --rate: 0 is out of
range: 1..200 Hz``, exit code 2) within milliseconds, instead of a failure after a SITL has
been started and provisioned.
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bfsitl.physics.params import QuadParams


def number_in(
    low: float | None, high: float | None, unit: str, *, above_low: bool = False
) -> Callable[[str], float]:
    """A finite number within ``low``..``high`` (either may be None: unbounded); with
    ``above_low`` the low end itself is refused (``> 0`` rather than ``>= 0``)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{text!r} must be a finite number")
        too_low = low is not None and (value <= low if above_low else value < low)
        too_high = high is not None and value > high
        if too_low or too_high:
            allowed = _range(low, high, unit, above_low)
            raise argparse.ArgumentTypeError(f"{text} is out of range: {allowed}")
        return value

    parse.__name__ = "number"  # argparse names the type in some messages
    return parse


def rc_rate(text: str) -> float | None:
    """``--rc-rate``: a receiver's frame rate in Hz, or ``packet`` (None: a frame in every
    fdm packet)."""
    from bfsitl.sim.rc_frames import MAX_RC_RATE_HZ, MIN_RC_RATE_HZ

    if text == "packet":
        return None
    return number_in(MIN_RC_RATE_HZ, MAX_RC_RATE_HZ, "Hz")(text)


def _range(low: float | None, high: float | None, unit: str, above_low: bool) -> str:
    if low is not None and high is not None and not above_low:
        return f"{low:g}..{high:g} {unit}"
    parts = []
    if low is not None:
        parts.append(f"{'>' if above_low else '>='} {low:g} {unit}")
    if high is not None:
        parts.append(f"<= {high:g} {unit}")
    return " and ".join(parts)


def port_number(text: str) -> int:
    """A TCP/UDP port, 0 (any free port) to 65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"{text} is out of range: 0..65535 (0: any free port)")
    return value


def whole_number_at_least(low: int) -> Callable[[str], int]:
    """A whole number >= ``low``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"{text} is out of range: at least {low}")
        return value

    parse.__name__ = "whole number"
    return parse


def parse_speed(text: str) -> float:
    """``--speed``: a positive number, or ``max`` (as fast as a lockstep build goes)."""
    if text.strip().lower() == "max":
        return math.inf
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number or 'max'") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number or 'max'")
    return value


def north_east_up(text: str) -> tuple[float, float, float]:
    """``N,E,UP``: three finite numbers, metres north, east and up; up above 0."""
    parts = [part.strip() for part in text.split(",")]
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected N,E,UP (three numbers, metres), e.g. 1,-1,2"
        )
    try:
        north, east, up = (float(part) for part in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: N,E,UP must be numbers") from None
    if not all(math.isfinite(v) for v in (north, east, up)):
        raise argparse.ArgumentTypeError(f"{text!r}: N,E,UP must be finite")
    if up <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: UP must be above the ground (> 0 m)")
    return (north, east, up)


def vehicle(text: str) -> QuadParams:
    """``--vehicle``: a shipped vehicle's name or a profile file, read now."""
    from bfsitl.errors import VehicleProfileError
    from bfsitl.vehicles import load_vehicle

    try:
        return load_vehicle(text)
    except VehicleProfileError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


VEHICLE_HELP = (
    "the simulated quad: iris (the default, Gazebo's), a shipped profile (`bfsitl vehicle "
    "list`: 5inch-freestyle, 3inch-cinewhoop, 7inch-longrange) or a profile file NAME.toml"
)


def add_vehicle_argument(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup, *, per_scenario: bool = False
) -> None:
    """``--vehicle NAME|FILE``, read when the command line is: IRIS by default, or (for the
    scenario commands) each scenario's own."""
    parser.add_argument(
        "--vehicle",
        type=vehicle,
        default=None if per_scenario else "iris",
        metavar="NAME|FILE",
        help=VEHICLE_HELP
        + (
            " (default: each scenario's own; those whose [vehicle] names a model or a mass "
            "keep theirs)"
            if per_scenario
            else ""
        ),
    )


def out_dir_problem(path: Path) -> str | None:
    """Why ``--out path`` could not be made, or None: checked before a slow command starts,
    without making the folder, so a command that then fails leaves nothing behind."""
    try:
        if path.exists():
            return None if path.is_dir() else f"{path} exists and is not a folder"
        parent = path.absolute().parent
        while not parent.exists():
            parent = parent.parent
        if not parent.is_dir():
            return f"{parent} is not a folder"
        if not os.access(parent, os.W_OK | os.X_OK):
            return f"{parent} is not writable"
    except OSError as exc:  # a folder on the way that cannot even be looked into
        return str(exc)
    return None
