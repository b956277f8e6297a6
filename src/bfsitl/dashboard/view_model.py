"""Snapshot -> view model: everything the dashboard shows, as plain typed values.

This is the pure half of ``bfsitl top``: no terminal, no socket, no clock.  It decides what is
worth showing (which RC channels the FC actually processes, which motor outputs exist, when
data counts as stale) so the renderer only lays things out, and so both are unit-tested from a
hand-built :class:`~bfsitl.fc.msp_client.Telemetry`.
"""

from __future__ import annotations

from dataclasses import dataclass

from bfsitl.dashboard.link_stats import LinkStats
from bfsitl.fc.msp_client import Telemetry

#: RC channels shown: roll, pitch, yaw, throttle and AUX1-6.  4.6.0 SITL only processes
#: ``max_aux_channels + 4`` = 10 channels; the rest always read 1500
#: (docs/firmware-facts.md#aux-channels).
RC_CHANNELS_SHOWN = 10
#: MSP_RC is in the FC's internal order: roll, pitch, yaw, throttle, then AUX1...
RC_LABELS: tuple[str, ...] = ("roll", "pitch", "yaw", "thr")
#: MSP_MOTOR always carries 8 outputs; 0 means "no such motor".  A quad shows at least four.
MIN_MOTORS_SHOWN = 4
#: PWM range the bars span (mincommand .. maxthrottle).
PWM_MIN_US = 1000
PWM_MAX_US = 2000
#: A snapshot older than this is flagged stale (the FC stopped answering).
DEFAULT_STALE_AFTER_S = 1.0


@dataclass(frozen=True, slots=True)
class ChannelView:
    """One RC channel or motor output: its label, value and bar fill."""

    label: str
    value_us: int
    #: 0..1 across PWM_MIN_US..PWM_MAX_US, clamped.
    fill: float


@dataclass(frozen=True, slots=True)
class BlockerView:
    """One arming-disable flag, decoded: CLI name, what it means, what to do."""

    name: str
    bit: int
    meaning: str
    fix: str


@dataclass(frozen=True, slots=True)
class FlightView:
    """The FC's state from one telemetry snapshot."""

    armed: bool
    roll_deg: float
    #: Betaflight's convention: positive nose down.
    pitch_deg: float
    heading_deg: int
    altitude_m: float
    vario_m_s: float
    battery_v: float
    cycle_time_us: int
    cpu_load_percent: int
    motors: tuple[ChannelView, ...]
    rc: tuple[ChannelView, ...]
    flight_modes: tuple[str, ...]
    blockers: tuple[BlockerView, ...]


@dataclass(frozen=True, slots=True)
class DashboardView:
    """A whole frame: where we are connected, the link, and the flight state if any."""

    target: str
    link: LinkStats
    #: None until the first snapshot has arrived.
    flight: FlightView | None
    #: The newest snapshot is older than the stale limit (values shown are the last known).
    stale: bool
    rate_hz: float


def pwm_fill(value_us: int) -> float:
    """Bar fill for a PWM value: 1000 us empty, 2000 us full, clamped outside."""
    return min(1.0, max(0.0, (value_us - PWM_MIN_US) / (PWM_MAX_US - PWM_MIN_US)))


def rc_label(index: int) -> str:
    return RC_LABELS[index] if index < len(RC_LABELS) else f"AUX{index - len(RC_LABELS) + 1}"


def flight_view(snapshot: Telemetry, rc_channels: int = RC_CHANNELS_SHOWN) -> FlightView:
    """Decode one snapshot into what the dashboard shows."""
    motors_us = snapshot.motors.motors_us
    motors = tuple(
        ChannelView(f"M{i + 1}", value, pwm_fill(value))
        for i, value in enumerate(motors_us)
        if i < MIN_MOTORS_SHOWN or value > 0
    )
    rc = tuple(
        ChannelView(rc_label(i), value, pwm_fill(value))
        for i, value in enumerate(snapshot.rc.channels_us[:rc_channels])
    )
    blockers = tuple(
        BlockerView(info.cli_name, info.bit, info.meaning, info.fix)
        for info in snapshot.status.arming_blockers
    )
    attitude = snapshot.attitude
    return FlightView(
        armed=snapshot.armed,
        roll_deg=attitude.roll_deg,
        pitch_deg=attitude.pitch_deg,
        heading_deg=attitude.yaw_deg,
        altitude_m=snapshot.altitude.altitude_m,
        vario_m_s=snapshot.altitude.vario_m_s,
        battery_v=snapshot.analog.battery_v,
        cycle_time_us=snapshot.status.cycle_time_us,
        cpu_load_percent=snapshot.status.cpu_load_percent,
        motors=motors,
        rc=rc,
        flight_modes=snapshot.flight_modes,
        blockers=blockers,
    )


def build_view(
    snapshot: Telemetry | None,
    link: LinkStats,
    *,
    target: str,
    rate_hz: float,
    stale_after_s: float = DEFAULT_STALE_AFTER_S,
) -> DashboardView:
    """The frame for the newest snapshot (None before the first) and the link figures."""
    stale = snapshot is not None and (link.age_s is None or link.age_s > stale_after_s)
    return DashboardView(
        target=target,
        link=link,
        flight=None if snapshot is None else flight_view(snapshot),
        stale=stale,
        rate_hz=rate_hz,
    )
