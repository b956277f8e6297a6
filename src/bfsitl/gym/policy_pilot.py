"""A trained policy flying a vehicle: in a SITL on any physics, or on a board.

:class:`PolicyPilot` is a :class:`~bfsitl.mission.stick_pilot.StickPilot`: each control step
it builds the observation from what the FC reported in the step's sample
(:func:`~bfsitl.gym.snapshot.fc_view`, the same function that fills the observation in
training, so the policy sees in flight exactly what it saw there), asks the policy for the
sticks, and sends them.  It never reads the truth, so what flies a SITL flies a board::

    from bfsitl import Autopilot, connect
    from bfsitl.gym.policy_pilot import PolicyPilot

    with connect("serial:///dev/ttyACM0") as board:        # propellers off
        pilot = PolicyPilot(board, "hover.onnx", target=(0.0, 0.0, 2.0))
        autopilot = Autopilot(board, rate_hz=pilot.rate_hz)
        autopilot.takeoff(2.0)
        autopilot.fly_sticks(pilot, 10.0)
        autopilot.land()
        print(pilot.report(autopilot.rows))

``bfsitl fly --policy FILE.onnx`` does the same on a SITL.  The policy must be asked at the
rate it was trained at (the file says it); the loop refuses another.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from bfsitl.errors import MissionError
from bfsitl.fc.rc_link import RcCommand
from bfsitl.gym.observation import observe_view
from bfsitl.gym.onnx_policy import OnnxPolicy
from bfsitl.gym.snapshot import Vec3, fc_view, watch_fc
from bfsitl.gym.sticks import sticks_to_rc
from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.phase import Phase
from bfsitl.mission.vehicle import SWITCH_OFF_US, SWITCH_ON_US, FlightSample, Vehicle

#: The FC reports a mode a few RC frames after the switch moves: a policy that has flown this
#: many steps without the mode it was trained in is flying something else.
MODE_GRACE_STEPS = 10
#: The hold is judged over this much of the end of the policy's time (or all of it if less).
JUDGED_S = 5.0

Policy = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class PolicyReport:
    """How a policy's flight went: its rate, its inference time, how well it held."""

    steps: int
    #: Control steps per second of the vehicle's clock that the loop kept (the policy's
    #: rate when it keeps up).
    rate_hz_kept: float
    rate_hz_asked: float | None
    inference_us_median: float
    inference_us_p99: float
    inference_us_max: float
    #: Over the last JUDGED_S of the policy's time: the distance from the target by the FC's
    #: own readings (its GPS and altitude: what the policy saw), and by the truth (NaN where
    #: none is known: a board, Gazebo).
    fc_distance_rms_m: float
    fc_distance_max_m: float
    true_distance_rms_m: float
    true_distance_max_m: float
    target: Vec3
    #: The seconds at the end of the policy's time that the distances cover.
    judged_s: float = JUDGED_S


class PolicyPilot:
    """A trained policy as the pilot of a :meth:`FlightLoop.fly_sticks
    <bfsitl.mission.loop.FlightLoop.fly_sticks>` (module docstring).

    Args:
        vehicle: The started vehicle it flies (a SITL's session or a board's): its samples
            are read for the FC's view, MSP_MOTOR and the GPS taken in their round trip.
        policy: An exported policy's file (run with onnxruntime, :class:`OnnxPolicy`), or
            any callable from one observation (:mod:`~bfsitl.gym.observation`) to the four
            sticks in -1..1.
        target: North, east, up, metres from the take-off point: where the policy is to fly.
        mode: The FC mode it was trained in, ``angle`` or ``acro`` (AUX2 is set to match);
            None: the file's (``angle`` for a callable without one).
        rate_hz: The rate it must be asked at; None: the file's (any, for a callable
            without one).

    Raises:
        EnvironmentConfigError: The file is missing or not a bfsitl policy.
        ExtraMissingError: onnxruntime is not installed (``pip install 'bfsitl[policy]'``).
    """

    def __init__(
        self,
        vehicle: Vehicle,
        policy: str | Path | Policy,
        target: Vec3,
        *,
        mode: str | None = None,
        rate_hz: float | None = None,
    ) -> None:
        if isinstance(policy, (str, Path)):
            policy = OnnxPolicy(policy)
        self.policy: Policy = policy
        self.vehicle = vehicle
        self.target: Vec3 = (float(target[0]), float(target[1]), float(target[2]))
        self.target_alt_m: float | None = self.target[2]
        self.mode = mode or getattr(policy, "mode", "angle")
        if self.mode not in ("angle", "acro"):
            raise MissionError(f"policy mode {self.mode!r}: expected 'angle' or 'acro'")
        self.rate_hz: float | None = (
            rate_hz if rate_hz is not None else getattr(policy, "control_hz", None)
        )
        path = getattr(policy, "path", None)
        self.name = f"policy {path.name}" if isinstance(path, Path) else "the policy"
        #: Seconds each call of the policy took (perf_counter), one per step.
        self.inference_s: list[float] = []
        #: The distance from the target by the FC's readings, one per step.
        self.fc_distance_m: list[float] = []
        #: The sample's time of each step (the loop's rows carry the same clock).
        self.step_times_s: list[float] = []
        watch_fc(vehicle)

    def sticks(self, sample: FlightSample, command: RcCommand) -> RcCommand:
        """One step: the FC's view in ``sample`` -> observation -> policy -> RC command."""
        observation = observe_view(fc_view(self.vehicle, sample), self.target)
        started = time.perf_counter()
        action = np.asarray(self.policy(observation), dtype=np.float64).reshape(-1)
        self.inference_s.append(time.perf_counter() - started)
        self.fc_distance_m.append(float(np.linalg.norm(observation[:3])))
        self.step_times_s.append(sample.time_s)
        if action.shape != (4,) or not np.all(np.isfinite(action)):
            raise MissionError(
                f"{self.name} gave {action.tolist()}; a policy gives 4 finite sticks (roll, "
                f"pitch, throttle, yaw)"
            )
        self._check_mode(sample)
        aux2_us = SWITCH_ON_US if self.mode == "angle" else SWITCH_OFF_US
        out = sticks_to_rc(action.tolist(), command)
        return replace(out, aux_us=(out.aux_us[0], aux2_us, *out.aux_us[2:]))

    def _check_mode(self, sample: FlightSample) -> None:
        if len(self.inference_s) != MODE_GRACE_STEPS:
            return
        in_angle = "ANGLE" in sample.flight_modes
        if self.mode == "angle" and not in_angle:
            raise MissionError(
                f"{self.name} was trained in ANGLE and the FC is not in ANGLE after "
                f"{MODE_GRACE_STEPS} steps with AUX2 on: provision ANGLE on AUX2 (bfsitl's "
                f"default profile; not --no-angle)"
            )
        if self.mode == "acro" and in_angle:
            raise MissionError(
                f"{self.name} was trained in ACRO and the FC stays in ANGLE with AUX2 off: "
                f"ANGLE is on another switch or forced; clear it"
            )

    def report(self, rows: Sequence[FlightRow]) -> PolicyReport:
        """How the policy flew, from the loop's rows of its phase and what it timed.  Rows
        and steps are paired by time: the rows may hold another pilot's flight too."""
        if not self.step_times_s:
            raise MissionError("the policy has not flown (no rows of its phase)")
        first_s, last_s = self.step_times_s[0], self.step_times_s[-1]
        flown = [
            row for row in rows if row.phase == Phase.POLICY and first_s <= row.time_s <= last_s
        ]
        if len(flown) < 2:
            raise MissionError("the policy has not flown (no rows of its phase)")
        span_s = flown[-1].time_s - flown[0].time_s
        judged_from_s = flown[-1].time_s - JUDGED_S
        fc_recent = [
            distance
            for time_s, distance in zip(self.step_times_s, self.fc_distance_m, strict=True)
            if time_s >= judged_from_s
        ]
        true_recent = [
            math.dist((row.sim_north_m, row.sim_east_m, row.sim_alt_m), self.target)
            for row in flown
            if row.time_s >= judged_from_s
        ]
        inference_us = sorted(s * 1e6 for s in self.inference_s)
        return PolicyReport(
            steps=len(flown),
            rate_hz_kept=(len(flown) - 1) / span_s if span_s > 0 else math.nan,
            rate_hz_asked=self.rate_hz,
            inference_us_median=statistics.median(inference_us),
            inference_us_p99=inference_us[int(0.99 * (len(inference_us) - 1))],
            inference_us_max=inference_us[-1],
            fc_distance_rms_m=_rms(fc_recent),
            fc_distance_max_m=_largest(fc_recent),
            true_distance_rms_m=_rms(true_recent),
            true_distance_max_m=_largest(true_recent),
            target=self.target,
            judged_s=min(JUDGED_S, span_s),
        )


def _rms(values: Sequence[float]) -> float:
    if not values:
        return math.nan
    return math.sqrt(sum(v * v for v in values) / len(values))


def _largest(values: Sequence[float]) -> float:
    """The largest value; NaN when there is none or any is unknown (a board's truth)."""
    if not values or any(math.isnan(v) for v in values):
        return math.nan
    return max(values)
