"""Text shown on the terminal: status reports and telemetry rows."""

from __future__ import annotations

from bfsitl.errors import UnsupportedFirmwareError
from bfsitl.fc.identity import FcIdentity
from bfsitl.fc.msp_client import Telemetry
from bfsitl.protocol.firmware_profile import TESTED_VERSIONS, profile_for


def conventions_text(identity: FcIdentity) -> str | None:
    """Which SITL conventions bfsitl uses for this firmware, and whether it was tested."""
    if not identity.is_sitl:
        return None
    try:
        profile = profile_for(identity.api_version, identity.firmware_version)
    except UnsupportedFirmwareError as exc:
        return f"unsupported: {exc}"
    if profile.tested:
        return f"{profile.generation.value} (tested with bfsitl)"
    like = ", ".join(TESTED_VERSIONS[profile.generation])
    return f"{profile.generation.value} (not tested with bfsitl; assumed to behave like {like})"


def status_report(identity: FcIdentity, telemetry: Telemetry) -> str:
    status, a = telemetry.status, telemetry.attitude
    lines = [
        f"firmware   {identity.describe()}",
        *([f"sitl       {text}"] if (text := conventions_text(identity)) else []),
        f"sensors    {', '.join(status.sensors) or 'none'}",
        f"pid loop   {status.cycle_time_us} us cycle, CPU load {status.cpu_load_percent} %",
        f"armed      {'YES' if status.armed else 'no'}",
        f"modes      {', '.join(telemetry.flight_modes) or 'none active'}",
        f"attitude   roll {a.roll_deg:+.1f} deg, pitch {a.pitch_deg:+.1f} deg "
        f"(+ = nose down), heading {a.yaw_deg} deg",
        f"altitude   {telemetry.altitude.altitude_m:+.2f} m (baro, up positive)",
        f"battery    {telemetry.analog.battery_v:.2f} V",
    ]
    blockers = status.arming_blockers
    if not blockers:
        lines.append("arming     nothing blocks arming")
    else:
        lines.append(f"arming     blocked by {len(blockers)} flag(s):")
        width = max(len(b.cli_name) for b in blockers)
        for blocker in blockers:
            lines.append(f"  {blocker.cli_name:<{width}}  {blocker.meaning}")
            lines.append(f"  {'':<{width}}  fix: {blocker.fix}")
    return "\n".join(lines)


TELEMETRY_HEADER = (
    f"{'time_s':>7} {'roll':>6} {'pitch':>6} {'yaw':>4} {'alt_m':>7} {'thr':>5} "
    f"{'motors_us':<20} {'armed':<5} blockers"
)


def telemetry_row(t_s: float, snapshot: Telemetry) -> str:
    a = snapshot.attitude
    motors = ",".join(str(m) for m in snapshot.motors.motors_us[:4])
    return (
        f"{t_s:7.2f} {a.roll_deg:+6.1f} {a.pitch_deg:+6.1f} {a.yaw_deg:4d} "
        f"{snapshot.altitude.altitude_m:+7.2f} {snapshot.rc.throttle_us:5d} {motors:<20} "
        f"{'yes' if snapshot.armed else 'no':<5} {' '.join(snapshot.arming_blockers) or '-'}"
    )


def telemetry_record(t_s: float, snapshot: Telemetry) -> dict[str, object]:
    """One JSON-lines record; field names carry their units."""
    a = snapshot.attitude
    return {
        "time_s": round(t_s, 4),
        "roll_deg": a.roll_deg,
        "pitch_deg": a.pitch_deg,
        "yaw_deg": a.yaw_deg,
        "altitude_m": snapshot.altitude.altitude_m,
        "vario_m_s": snapshot.altitude.vario_m_s,
        "battery_v": snapshot.analog.battery_v,
        "rc_us": list(snapshot.rc.channels_us),
        "motors_us": list(snapshot.motors.motors_us),
        "armed": snapshot.armed,
        "arming_blockers": list(snapshot.arming_blockers),
        "flight_modes": list(snapshot.flight_modes),
        "cycle_time_us": snapshot.status.cycle_time_us,
        "cpu_load_percent": snapshot.status.cpu_load_percent,
    }
