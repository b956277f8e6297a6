"""Scenarios and firmware without files of their own: a scenario from a table, the profiles of
the two generations, and a file that passes for a stock 4.6.0 SITL."""

from __future__ import annotations

from pathlib import Path

from bfsitl.fc.firmware_detect import MASTER_API_VERSION
from bfsitl.protocol.firmware_profile import profile_for
from bfsitl.scenario.spec import scenario_from_dict

V46 = profile_for("1.47", "4.6.0")
MASTER = profile_for(MASTER_API_VERSION, "2026.12.0-alpha")


def scenario(**extra):  # type: ignore[no-untyped-def]
    data = {
        "duration_s": 20.0,
        "flight": {"takeoff_alt_m": 2.0},
        "expect": {"disarmed": True},
        **extra,
    }
    return scenario_from_dict(data, name="t")


def fake_binary(tmp_path: Path) -> Path:
    """A file that passes for a stock 4.6.0 SITL (no build record: 4.6.0, no GPS)."""
    binary = tmp_path / "betaflight_4.6.0_SITL"
    binary.write_bytes(b"\x00" * 64)
    binary.chmod(0o755)
    return binary
