"""The Gazebo backend's truth: the relay's latest reading as the flight's simulated truth."""

from __future__ import annotations

from pathlib import Path

import pytest

import bfsitl.gazebo
from bfsitl.backend.gazebo import ON_GROUND_MARGIN_M, GazeboBackend
from bfsitl.errors import BfsitlError, GazeboError
from bfsitl.gazebo.packet_tap import TapCounts, TapReading
from bfsitl.gazebo.plugin_frame import GazeboState
from bfsitl.gazebo.world import world_path
from bfsitl.physics.frames import quat_from_euler_deg


class FakeTap:
    def __init__(self) -> None:
        self.latest: TapReading | None = None
        self.error: BaseException | None = None

    def reading(self) -> TapReading | None:
        return self.latest

    def counts(self) -> TapCounts:
        return TapCounts(fdm=9800, servo=9700, unreadable=0, sim_time_s=9.8, wall_time_s=10.0)


def _reading(altitude_m: float, roll_deg: float = 0.0) -> TapReading:
    state = GazeboState(
        sim_time_s=7.0,
        position_ned_m=(3.0, -4.0, -altitude_m),
        velocity_ned_m_s=(0.0, 0.0, -1.5),
        quaternion_wxyz=quat_from_euler_deg(roll_deg, 0.0, 90.0),
        gyro_rad_s=(0.0, 0.0, 0.0),
        specific_force_m_s2=(0.0, 0.0, -9.8),
        pressure_pa=101000.0,
    )
    return TapReading(state, 42.0, (0.1, 0.2, 0.3, 0.4))


@pytest.fixture
def backend(monkeypatch: pytest.MonkeyPatch) -> GazeboBackend:
    monkeypatch.setattr(bfsitl.gazebo, "check_gazebo", lambda plugin_dir: object())
    backend = GazeboBackend(None, progress=lambda line: None)
    backend.tap = FakeTap()  # type: ignore[assignment]
    return backend


def test_no_truth_before_the_plugins_first_packet(backend: GazeboBackend) -> None:
    assert backend.truth() is None


def test_the_latest_reading_is_the_truth(backend: GazeboBackend) -> None:
    tap: FakeTap = backend.tap  # type: ignore[assignment]
    tap.latest = _reading(0.19)
    resting = backend.truth()
    assert resting is not None and resting.on_ground
    tap.latest = _reading(2.0, roll_deg=10.0)
    truth = backend.truth()
    assert truth is not None
    assert truth.time_s == 42.0
    assert truth.altitude_m == pytest.approx(2.0)
    assert truth.climb_m_s == pytest.approx(1.5)
    assert (truth.north_m, truth.east_m) == pytest.approx((3.0, -4.0))
    assert truth.attitude_deg == pytest.approx((10.0, 0.0, 90.0))
    assert truth.tilt_deg == pytest.approx(10.0)
    assert truth.motors == (0.1, 0.2, 0.3, 0.4)
    assert not truth.on_ground
    # Back down to within the margin of where it rested: on the ground again.
    tap.latest = _reading(0.19 + ON_GROUND_MARGIN_M * 0.9)
    again = backend.truth()
    assert again is not None and again.on_ground


def test_a_failed_relay_is_the_flights_failure(backend: GazeboBackend) -> None:
    assert backend.failure() is None
    tap: FakeTap = backend.tap  # type: ignore[assignment]
    tap.error = OSError("socket closed")
    failure = backend.failure()
    assert failure is not None and "Gazebo relay" in failure


def test_a_world_of_ones_own_is_checked_before_anything_starts(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr(bfsitl.gazebo, "check_gazebo", lambda plugin_dir: object())
    with pytest.raises(BfsitlError, match="no Gazebo world"):
        GazeboBackend(None, progress=lambda line: None, world_file=tmp_path / "missing.sdf")
    bare = tmp_path / "bare.sdf"
    bare.write_text("<sdf version='1.9'><world name='w'/></sdf>")
    with pytest.raises(GazeboError, match="BetaflightPlugin"):
        GazeboBackend(None, progress=lambda line: None, world_file=bare)
    own = tmp_path / "mine.sdf"
    own.write_text(world_path().read_text())
    backend = GazeboBackend(None, progress=lambda line: None, world_file=own)
    assert backend.world_file == own.resolve()


def test_gazebos_pace_is_said_when_the_flight_ends(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bfsitl.gazebo, "check_gazebo", lambda plugin_dir: object())
    lines: list[str] = []
    backend = GazeboBackend(None, progress=lines.append)
    backend.tap = FakeTap()  # type: ignore[assignment]
    backend._say_pace()
    assert lines == [
        "Gazebo ran 9.8 s of sim time in 10.0 s (0.98x real time; 9800 state and 9700 motor "
        "packets relayed)"
    ]
