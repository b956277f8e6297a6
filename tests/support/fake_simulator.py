"""A simulator that only counts: time moves by each step, the motor commands it was given
are kept, and its sensors read a level vehicle at rest (for the lockstep bridge's tests)."""

from __future__ import annotations

from bfsitl.physics.sensors import SensorReading


class FakeSimulator:
    def __init__(self) -> None:
        self.time_s = 0.0
        self.applied: list[tuple[float, ...]] = []

    def step(self, motors: tuple[float, ...], dt_s: float) -> None:
        self.applied.append(motors)
        self.time_s = round(self.time_s + dt_s, 9)

    def read_sensors(self) -> SensorReading:
        zero = (0.0, 0.0, 0.0)
        return SensorReading(
            time_s=self.time_s,
            gyro_frd_rad_s=zero,
            specific_force_frd_m_s2=(0.0, 0.0, -9.80665),
            quaternion_wxyz=(1.0, 0.0, 0.0, 0.0),
            pressure_pa=101325.0,
            position_ned_m=zero,
            velocity_ned_m_s=zero,
            geodetic=(0.0, 0.0, 0.0),
            velocity_enu_m_s=zero,
        )
