"""``bfsitl log fit`` as a function: a blackbox log and a mass in, a vehicle profile and its
scores out.

The steps: the log's flight on a uniform clock (:mod:`bfsitl.fit.log_data`); its usable
half-second windows, the first 70 % to fit and the rest to score (:mod:`bfsitl.fit.windows`);
the rotation and the motor lag (:mod:`bfsitl.fit.rotation`), then the thrust
(:mod:`bfsitl.fit.thrust`), both with the base profile's thrust curve shape; the profile over
a base (:mod:`bfsitl.fit.fitted_profile`); and the open-loop replay of the
windows the fit did not see, with the fitted profile, with every shipped profile unfitted and
with "hold" (:mod:`bfsitl.fit.replay`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from bfsitl.blackbox import BlackboxLog, decode_blackbox
from bfsitl.errors import FitError
from bfsitl.fit.fitted_profile import closest_base, fitted_spec, spec_beta
from bfsitl.fit.log_data import FlightData, flight_data
from bfsitl.fit.noise_floor import NoiseFloor, noise_floor
from bfsitl.fit.replay import Replay, ReplayScore, hold_score, replay, score
from bfsitl.fit.rotation import RotationFit, fit_rotation
from bfsitl.fit.thrust import ThrustFit, calm_frames, fit_thrust, hover_command
from bfsitl.fit.windows import TRAIN_SHARE, Windows, train_and_test
from bfsitl.vehicles import VehicleSpec, quad_params, shipped_profiles


@dataclass(frozen=True)
class LogFit:
    """What a fit found, and how well it replays what it did not see.

    Attributes:
        data: The flight as the fit read it.
        base: The profile whose frame, props and drag the fitted one keeps.
        spec: The fitted profile.
        rotation: Each axis' effectiveness, the motor lag and the terms the physics lacks.
        thrust: The thrust-to-weight ratio and the curve's shape.
        hover_logged: The log's median motor command where it hangs at 1 g (0..1).
        hover_model: The command the fitted physics hovers at (0..1).
        train_windows: The windows fitted; ``test_windows``: the windows scored.
        fitted: The fitted profile's replay score; ``replayed`` its traces.
        shipped: Each shipped profile's score, unfitted, by name.
        hold: The score of predicting no change.
        noise: The gyro's and the accelerometer's noise floor as logged.
        notes: What the reader of the report must know (props out, a yaw the log does not
            show, a figure at the edge of its search, gaps).
    """

    data: FlightData
    base: VehicleSpec
    spec: VehicleSpec
    rotation: RotationFit
    thrust: ThrustFit
    hover_logged: float
    hover_model: float
    train_windows: Windows
    test_windows: Windows
    fitted: ReplayScore
    replayed: Replay
    shipped: dict[str, ReplayScore]
    hold: ReplayScore
    noise: NoiseFloor
    notes: list[str] = field(default_factory=list)

    @property
    def closest_shipped(self) -> tuple[str, ReplayScore]:
        """The shipped profile that replays this log best, unfitted."""
        name = min(self.shipped, key=lambda n: sum(self.shipped[n].rates))
        return name, self.shipped[name]


def pick_log(path: Path, index: int | None) -> BlackboxLog:
    """The log numbered ``index`` in the file, or, without one, the one with the most frames.

    Raises:
        BlackboxError: The file cannot be read.
        FitError: No such log in the file.
    """
    logs = decode_blackbox(path)
    if not logs:
        raise FitError(f"{path}: no log in the file")
    if index is None:
        return max(logs, key=lambda log: len(log.frames))
    for log in logs:
        if log.index == index:
            return log
    numbers = ", ".join(str(log.index) for log in logs)
    raise FitError(f"{path}: no log {index} in the file (it holds logs {numbers})")


def fit_log(
    log: BlackboxLog, *, mass_g: float, base: VehicleSpec | None = None, name: str | None = None
) -> LogFit:
    """Fit ``log`` (see the module doc).

    Raises:
        FitError: The log cannot identify a quad (the message says what it lacks).
    """
    if not (math.isfinite(mass_g) and mass_g > 0):
        raise FitError(f"the mass must be a positive number of grams, got {mass_g!r}")
    data = flight_data(log)
    base = base or closest_base(mass_g)
    train, test = train_and_test(data)
    if len(test) < 3:
        raise FitError(
            f"{data.label}: {len(test)} half-second windows to score after the first "
            f"{TRAIN_SHARE:.0%}; a fit needs a longer flight (give another log with --index)"
        )
    base_beta = spec_beta(base)
    until = data.split_index(TRAIN_SHARE)
    # The hover is checked first: the lag search takes a while, a log without a hover fails.
    calm_frames(data, until)
    rotation = fit_rotation(data, train, base_beta)
    thrust = fit_thrust(data, rotation.time_constant_s, base_beta, until=until)
    notes = _notes(data, rotation, thrust)
    label = data.label if not data.craft else f"{data.label} ({data.craft})"
    spec = fitted_spec(
        base,
        name=name or f"{Path(log.path).stem.lower()}-fit",
        mass_g=mass_g,
        label=label,
        rotation=rotation,
        thrust=thrust,
    )
    quad = quad_params(spec)
    delay = rotation.delay_frames
    replayed = replay(data, test, quad, delay_frames=delay)
    shipped = {
        key: score(replay(data, test, quad_params(other), delay_frames=delay), data.dt_s)
        for key, other in sorted(shipped_profiles().items())
    }
    return LogFit(
        data=data,
        base=base,
        spec=spec,
        rotation=rotation,
        thrust=thrust,
        hover_logged=hover_command(data),
        hover_model=float(quad.hover_command),
        train_windows=train,
        test_windows=test,
        fitted=score(replayed, data.dt_s),
        replayed=replayed,
        shipped=shipped,
        hold=hold_score(data, test),
        noise=noise_floor(data),
        notes=notes,
    )


def _notes(data: FlightData, rotation: RotationFit, thrust: ThrustFit) -> list[str]:
    notes = []
    notes.extend(rotation.at_bounds)
    if not rotation.yaw_identified:
        yaw = rotation.yaw.effectiveness
        notes.append(
            f"the yaw hardly follows the motors ({yaw.value:.3g} +- {yaw.std:.2g}): the "
            "profile keeps the base's yaw inertia"
        )
    if rotation.props_out:
        notes.append(
            "the yaw follows the motors the other way round: the props spin outwards "
            "(yaw_motors_reversed); the physics flies props in, so the profile's yaw is "
            "the magnitude only"
        )
    if data.gaps_s > 0:
        notes.append(f"{data.gaps_s:.1f} s of gaps in the log were left out")
    return notes
