"""Sensor readings, noise and bias (packing them is tests/unit/protocol/test_fdm_encoding.py)."""

from __future__ import annotations

import math
import statistics

import pytest

from bfsitl.errors import SimInputError
from bfsitl.physics import (
    IRIS,
    GeoPoint,
    SensorConfig,
    SensorReading,
    Simulator,
    betaflight_altitude_m,
    isa_pressure_pa,
)
from bfsitl.physics.atmosphere import firmware_pressure_pa
from bfsitl.physics.frames import EARTH_RADIUS_M

G = 9.80665
HOME = GeoPoint(47.3977, 8.5456, 488.0)


def flying(sensors: SensorConfig | None = None, seed: int = 0) -> Simulator:
    sim = Simulator(sensors=sensors, home=HOME, seed=seed)
    sim.reset(
        (30.0, -40.0, -12.0),
        yaw_deg=45.0,
        velocity_ned_m_s=(3.0, 4.0, -1.5),
        angular_velocity_frd_rad_s=(0.1, -0.2, 0.3),
        motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4,
    )
    sim.step((IRIS.hover_command,) * 4, 0.001)
    return sim


def test_ideal_sensors_report_the_true_state():
    sim = flying()
    reading, state = sim.read_sensors(), sim.state
    assert isinstance(reading, SensorReading)
    assert reading.time_s == sim.time_s == state.time_s
    assert reading.gyro_frd_rad_s == state.angular_velocity_frd_rad_s
    assert reading.quaternion_wxyz == state.quaternion_wxyz
    assert reading.position_ned_m == state.position_ned_m
    assert reading.velocity_ned_m_s == state.velocity_ned_m_s
    assert reading.pressure_pa == isa_pressure_pa(HOME.alt_m - state.position_ned_m[2])


def test_reading_is_cached_until_the_next_step():
    sim = flying(SensorConfig(gyro_noise_std_rad_s=0.1))
    first = sim.read_sensors()
    assert sim.read_sensors() is first  # same noise sample within a step
    sim.step((0.5,) * 4, 0.001)
    assert sim.read_sensors() is not first


def test_geodetic_reading_is_lon_lat_alt_and_enu_velocity():
    sim = flying()
    reading = sim.read_sensors()
    north, east, down = sim.state.position_ned_m
    vn, ve, vd = sim.state.velocity_ned_m_s
    lon, lat, alt = reading.geodetic
    assert lat == pytest.approx(HOME.lat_deg + math.degrees(north / EARTH_RADIUS_M), abs=1e-12)
    assert lon == pytest.approx(
        HOME.lon_deg + math.degrees(east / (EARTH_RADIUS_M * math.cos(math.radians(HOME.lat_deg)))),
        abs=1e-12,
    )
    assert lat > HOME.lat_deg and lon < HOME.lon_deg  # 30 m north, 40 m west of home
    assert alt == pytest.approx(HOME.alt_m - down)
    assert reading.velocity_enu_m_s == (ve, vn, -vd)
    assert reading.velocity_enu_m_s == pytest.approx((4.0, 3.0, 1.5), abs=0.05)  # E, N, up
    # What a -DUSE_GPS firmware derives (sitl.c): course atan2(vE, vN), 53.1 deg here.
    ve_, vn_, _ = reading.velocity_enu_m_s
    assert math.degrees(math.atan2(ve_, vn_)) == pytest.approx(53.13, abs=0.5)


def test_noise_is_repeatable_with_the_seed_and_has_the_configured_spread():
    config = SensorConfig(
        gyro_noise_std_rad_s=0.01, accel_noise_std_m_s2=0.2, baro_noise_std_pa=3.0
    )

    def samples(seed: int) -> list[SensorReading]:
        sim = Simulator(sensors=config, seed=seed)  # parked: the true values are constant
        out = []
        for _ in range(3000):
            sim.step((0.0,) * 4, 0.001)
            out.append(sim.read_sensors())
        return out

    a, b, c = samples(7), samples(7), samples(8)
    assert a == b
    assert a != c
    gyro_x = [r.gyro_frd_rad_s[0] for r in a]
    accel_z = [r.specific_force_frd_m_s2[2] for r in a]
    pressure = [r.pressure_pa for r in a]
    assert statistics.fmean(gyro_x) == pytest.approx(0.0, abs=0.001)
    assert statistics.pstdev(gyro_x) == pytest.approx(0.01, rel=0.1)
    assert statistics.fmean(accel_z) == pytest.approx(-G, abs=0.02)
    assert statistics.pstdev(accel_z) == pytest.approx(0.2, rel=0.1)
    assert statistics.pstdev(pressure) == pytest.approx(3.0, rel=0.1)
    # Noise never touches the true state.
    assert {r.quaternion_wxyz for r in a} == {(1.0, 0.0, 0.0, 0.0)}


def test_bias_shifts_readings_exactly():
    config = SensorConfig(
        gyro_bias_rad_s=(0.01, -0.02, 0.03), accel_bias_m_s2=(0.1, 0.0, -0.2), baro_bias_pa=-12.5
    )
    ideal, biased = Simulator().read_sensors(), Simulator(sensors=config).read_sensors()
    assert biased.gyro_frd_rad_s == (0.01, -0.02, 0.03)
    assert biased.specific_force_frd_m_s2 == pytest.approx((0.1, 0.0, -G - 0.2))
    assert biased.pressure_pa == pytest.approx(ideal.pressure_pa - 12.5)


def test_default_sensors_are_ideal_and_do_not_jitter_at_rest():
    assert SensorConfig().is_ideal
    sim = Simulator()
    first = sim.read_sensors()
    for _ in range(500):
        sim.step((0.055,) * 4, 0.001)
        reading = sim.read_sensors()
        assert reading.gyro_frd_rad_s == first.gyro_frd_rad_s
        assert reading.specific_force_frd_m_s2 == first.specific_force_frd_m_s2
        assert reading.pressure_pa == first.pressure_pa


def test_typical_mems_noise_from_densities():
    config = SensorConfig.typical_mems(1000.0)
    assert config.gyro_noise_std_rad_s == pytest.approx(1.8665e-4 * math.sqrt(1000))
    assert config.accel_noise_std_m_s2 == pytest.approx(1.86e-3 * math.sqrt(1000))
    assert not config.is_ideal


@pytest.mark.parametrize(
    "kwargs",
    [
        {"gyro_noise_std_rad_s": -0.1},
        {"baro_noise_std_pa": float("nan")},
        {"accel_bias_m_s2": (0.0, 0.0)},
        {"gyro_bias_rad_s": (0.0, float("inf"), 0.0)},
    ],
)
def test_bad_sensor_config_raises(kwargs):
    with pytest.raises(SimInputError):
        SensorConfig(**kwargs)


# ---- barometer --------------------------------------------------------------------------------


def test_ten_metre_climb_reads_ten_metres_of_betaflight_altitude():
    sim = Simulator(home=HOME)
    ground = sim.read_sensors().pressure_pa
    sim.hold(True)
    sim.reset((0.0, 0.0, sim.state.position_ned_m[2] - 10.0))
    sim.step((0.0,) * 4, 0.001)
    climbed = sim.read_sensors().pressure_pa
    # Hydrostatics: dP = rho g dh, ISA density at ~490 m being 1.168 kg/m^3.
    assert ground - climbed == pytest.approx(1.168 * G * 10.0, rel=2e-3)
    # What the firmware computes from the truncated pascals (measured: MSP ~1008 cm,
    # docs/firmware-facts.md#sign-table).
    metres = betaflight_altitude_m(firmware_pressure_pa(climbed)) - betaflight_altitude_m(
        firmware_pressure_pa(ground)
    )
    assert metres == pytest.approx(10.0, abs=0.1)


def test_isa_pressure_values_and_limits():
    assert isa_pressure_pa(0.0) == 101325.0
    assert isa_pressure_pa(1000.0) == pytest.approx(89874.6, abs=0.5)  # ISA table
    assert isa_pressure_pa(-100.0) > 101325.0
    assert betaflight_altitude_m(isa_pressure_pa(1000.0)) == pytest.approx(1000.0, abs=0.5)
    with pytest.raises(SimInputError, match="outside"):
        isa_pressure_pa(50_000.0)
    with pytest.raises(SimInputError):
        betaflight_altitude_m(0.0)
