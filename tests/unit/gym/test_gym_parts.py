"""The environment's pure parts without a SITL: sticks, the observation's layout, the reward,
the endings and the tasks, and the options refused before anything starts."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from support.fake_builds import fake_lockstep_build  # noqa: E402

from bfsitl.backend.options import Timing, World  # noqa: E402
from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.fc.rc_link import RcCommand  # noqa: E402
from bfsitl.gym.env import FlightEnv, HoverEnv, WaypointsEnv  # noqa: E402
from bfsitl.gym.observation import observation_space, observe  # noqa: E402
from bfsitl.gym.snapshot import FcView, Snapshot, TrueView  # noqa: E402
from bfsitl.gym.sticks import rc_to_sticks, stick_us, sticks_to_rc  # noqa: E402
from bfsitl.gym.tasks import (  # noqa: E402
    CRASH_TILT_DEG,
    MAX_DISTANCE_M,
    WAYPOINT_BONUS,
    Hover,
    Waypoints,
    failure,
    step_reward,
)
from bfsitl.mission.session import SitlLaunch  # noqa: E402


# -- sticks -------------------------------------------------------------------------------------
def test_sticks_map_onto_pulses_in_the_receivers_order_and_keep_the_switches() -> None:
    base = RcCommand(aux_us=(1800, 1800))
    rc = sticks_to_rc([0.5, -0.5, -1.0, 1.0], base)
    assert (rc.roll_us, rc.pitch_us, rc.throttle_us, rc.yaw_us) == (1750, 1250, 1000, 2000)
    assert rc.aux_us == (1800, 1800)  # ARM and ANGLE are not the policy's
    assert rc_to_sticks(rc) == (0.5, -0.5, -1.0, 1.0)
    assert stick_us(7.0) == 2000 and stick_us(-7.0) == 1000  # clipped to the stick's travel
    with pytest.raises(ValueError, match="NaN"):
        stick_us(float("nan"))


# -- the observation ---------------------------------------------------------------------------
def snapshot(**truth_changes: object) -> Snapshot:
    fc = FcView(
        roll_rad=0.1,
        pitch_rad=-0.2,
        yaw_rad=math.pi / 2,
        rates_flu_rad_s=(1, 2, 3),
        accel_flu_m_s2=(0.1, 0.2, 9.8),
        accel_up_m_s2=0.05,
        alt_m=1.9,
        climb_m_s=0.3,
        north_m=0.5,
        east_m=-0.5,
        v_north_m_s=0.4,
        v_east_m_s=-0.4,
        has_gps=True,
        motors=(0.4, 0.5, 0.6, 0.7),
        armed=True,
        arming_blockers=(),
        flight_modes=("ANGLE",),
    )
    truth = dict(
        north_m=0.6,
        east_m=-0.6,
        alt_m=2.0,
        v_north_m_s=0.5,
        v_east_m_s=-0.5,
        v_up_m_s=0.2,
        roll_rad=0.11,
        pitch_rad=-0.21,
        yaw_rad=math.pi,
        rates_flu_rad_s=(1.1, 2.1, 3.1),
        accel_flu_m_s2=(0.0, 0.0, 9.81),
        motors=(0.41, 0.51, 0.61, 0.71),
        tilt_deg=10.0,
        on_ground=False,
    )
    truth.update(truth_changes)
    return Snapshot(12.0, fc, TrueView(**truth))  # type: ignore[arg-type]


def test_the_observation_puts_each_quantity_in_its_slot_for_the_fc_and_the_truth() -> None:
    target = (1.0, 1.0, 3.0)
    fc = observe(snapshot(), target, "fc")
    assert fc.dtype == np.float32 and fc.shape == (23,)
    np.testing.assert_allclose(
        fc,
        [
            0.5,
            1.5,
            1.1,
            0.4,
            -0.4,
            0.3,
            0.1,
            -0.2,
            1.0,
            0.0,
            1,
            2,
            3,
            0.1,
            0.2,
            9.8,
            0.4,
            0.5,
            0.6,
            0.7,
            0.0,
            0.0,
            0.0,
        ],
        atol=1e-6,
    )
    # The next leg: from the target to the point after it.
    truth = observe(snapshot(), target, "truth", next_target=(4.0, -2.0, 2.5))
    np.testing.assert_allclose(
        truth,
        [
            0.4,
            1.6,
            1.0,
            0.5,
            -0.5,
            0.2,
            0.11,
            -0.21,
            0.0,
            -1.0,
            1.1,
            2.1,
            3.1,
            0.0,
            0.0,
            9.81,
            0.41,
            0.51,
            0.61,
            0.71,
            3.0,
            -3.0,
            -0.5,
        ],
        atol=1e-6,
    )
    assert observation_space().contains(fc) and observation_space().contains(truth)


def test_a_value_beyond_the_space_is_clipped_into_it() -> None:
    wild = observe(snapshot(north_m=-5000.0, rates_flu_rad_s=(500.0, 0.0, 0.0)), (0, 0, 0), "truth")
    assert wild[0] == 1000.0 and wild[10] == 100.0 and observation_space().contains(wild)


# -- reward and endings ------------------------------------------------------------------------
def test_the_reward_is_one_at_the_target_and_falls_with_distance_tilt_and_effort() -> None:
    level = snapshot(tilt_deg=0.0).truth
    at = (level.north_m, level.east_m, level.alt_m)
    still = np.zeros(4, dtype=np.float32)
    assert step_reward(level, at, still) == pytest.approx(1.0)
    a_metre_off = (at[0] + 1.0, at[1], at[2])
    assert step_reward(level, a_metre_off, still) == pytest.approx(math.exp(-1.0))
    tilted = snapshot(tilt_deg=30.0).truth
    assert step_reward(tilted, at, still) == pytest.approx(1.0 - 0.1 * math.radians(30.0))
    # Throttle is free (holding height needs it); roll, pitch and yaw sticks cost.
    assert step_reward(level, at, np.array([0, 0, 1, 0], dtype=np.float32)) == 1.0
    assert step_reward(level, at, np.array([1, -1, 0, 1], dtype=np.float32)) == pytest.approx(
        1.0 - 0.03
    )


def test_each_ending_is_named_and_a_calm_flight_goes_on() -> None:
    truth = snapshot(tilt_deg=5.0).truth
    here = (truth.north_m, truth.east_m, truth.alt_m)
    assert failure(truth, here, armed=True, has_flown=True) is None
    assert "tilted" in failure(
        snapshot(tilt_deg=CRASH_TILT_DEG + 1).truth,
        here,  # type: ignore[operator]
        armed=True,
        has_flown=True,
    )
    on_ground = snapshot(on_ground=True, alt_m=0.0).truth
    assert failure(on_ground, here, armed=True, has_flown=False) is None  # before take-off
    assert "back on the ground" in failure(on_ground, here, armed=True, has_flown=True)  # type: ignore[operator]
    assert failure(truth, here, armed=False, has_flown=True) == "the FC disarmed"
    far = (here[0] + MAX_DISTANCE_M + 0.1, here[1], here[2])
    assert "out of bounds" in failure(truth, far, armed=True, has_flown=True)  # type: ignore[operator]
    assert "above" in failure(
        snapshot(alt_m=25.0).truth,
        (0.6, -0.6, 24.0),  # type: ignore[operator]
        armed=True,
        has_flown=True,
    )


def test_targets_are_drawn_from_the_episodes_generator_inside_their_box() -> None:
    task = Hover()
    task.reset(np.random.default_rng(7))
    first = task.target
    task.reset(np.random.default_rng(7))
    assert task.target == first  # the same seed, the same target
    targets = []
    for seed in range(200):
        task.reset(np.random.default_rng(seed))
        targets.append(task.target)
    north, east, up = np.array(targets).T
    assert abs(north).max() <= 2.0 and abs(east).max() <= 2.0
    assert 1.5 <= up.min() and up.max() <= 3.0
    assert north.std() > 0.5 and east.std() > 0.5  # both axes are drawn


def test_waypoints_advance_when_reached_pay_a_bonus_and_finish_at_the_last() -> None:
    task = Waypoints(count=2)
    task.reset(np.random.default_rng(1))
    first, last = task.targets
    far = snapshot(north_m=first[0] + 3.0, east_m=first[1], alt_m=first[2]).truth
    assert task.advance(far) == (0.0, False) and task.index == 0
    near = snapshot(north_m=first[0] + 0.3, east_m=first[1], alt_m=first[2]).truth
    assert task.advance(near) == (WAYPOINT_BONUS, False) and task.target == last
    at_last = snapshot(north_m=last[0], east_m=last[1], alt_m=last[2]).truth
    assert task.advance(at_last) == (WAYPOINT_BONUS, True)


# -- options refused before anything starts ---------------------------------------------------
@pytest.mark.parametrize(
    ("options", "fix"),
    [
        ({"mode": "horizon"}, "mode must be one of angle, acro"),
        ({"observation": "camera"}, "observation must be one of fc, truth"),
        ({"start": "orbit"}, "start must be one of air, ground"),
        ({"control_hz": 500.0}, r"control_hz 500.0 is outside 1..200 Hz"),
        ({"max_episode_steps": 0}, "max_episode_steps 0 is not a number of steps"),
        ({"start_alt_m": 40.0}, "start_alt_m 40.0 is outside 0.5..15 m"),
        (
            {"timing": Timing(lockstep_exchange="pigeon")},  # type: ignore[arg-type]
            "timing.lockstep_exchange must be one of auto, shm, udp",
        ),
        (
            {"timing": Timing(lockstep_spin=True), "pin_core": True},
            "lockstep_spin=True with pin_core=True",
        ),
        ({"timing": Timing(lockstep=False)}, "timing.lockstep=False: the environment steps"),
        ({"world": World(physics="gazebo")}, "world.physics='gazebo': the environment flies"),
        # A group given as something else: what it takes, before anything is looked up.
        (
            {"timing": {"lockstep_exchange": "udp"}},
            r"timing must be a Timing \(bfsitl.Timing\(speed, lockstep, lockstep_spin, "
            r"lockstep_exchange\), all optional\), not dict",
        ),
        ({"world": 3.0}, r"world must be a World \(bfsitl.World\(physics, .*\), not float"),
        ({"rc_rate_hz": 5.0}, r"rc_rate_hz: an RC link rate of 5.0 Hz: give 16 to 1000 Hz"),
        (
            {"rc_rate_hz": None, "rc_frame_per_step": True},
            "rc_frame_per_step=True with rc_rate_hz=None",
        ),
        (
            {"sitl": "4.6.0-gps-lockstep"},
            r"sitl must be a SitlLaunch \(bfsitl.SitlLaunch\("
            r"firmware, workdir, isolate, env\), all optional\), not str",
        ),
    ],
)
def test_an_option_the_environment_cannot_take_is_refused_with_what_it_takes(
    options: dict, fix: str
) -> None:
    with pytest.raises(EnvironmentConfigError, match=fix):
        HoverEnv(**options)
    with pytest.raises(EnvironmentConfigError, match="count 0 is outside"):
        WaypointsEnv(count=0)


def test_the_rc_link_flies_the_environments_rate(tmp_path: Path) -> None:
    sitl = SitlLaunch(firmware=fake_lockstep_build(tmp_path))
    rates = []
    for options in ({}, {"rc_rate_hz": 50.0}, {"rc_rate_hz": None}):
        env = HoverEnv(sitl=sitl, **options)
        rates.append(env._new_session(1).config.fc.rc_rate_hz)
        env.close()
    assert rates == [250.0, 50.0, None]


def test_pinning_and_spin_default_by_where_the_environment_runs(tmp_path: Path) -> None:
    sitl = SitlLaunch(firmware=fake_lockstep_build(tmp_path))
    here = HoverEnv(sitl=sitl)  # a main process: spin on two cores, no pinning
    assert here.spin and not here.pin_core
    pinned = HoverEnv(sitl=sitl, pin_core=True)  # it shares the core with its SITL
    assert pinned.pin_core and not pinned.spin
    for env in (here, pinned):
        env.close()


def test_the_episode_limit_is_gymnasiums_max_episode_steps_counted_once(tmp_path: Path) -> None:
    import gymnasium

    import bfsitl.gym
    from bfsitl.gym.env import DEFAULT_CONTROL_HZ

    # Registered with the ids: the default episodes (10 s, 20 s, 4 s) at the default rate.
    assert bfsitl.gym.MAX_EPISODE_STEPS == {
        "bfsitl/Hover-v0": 10 * DEFAULT_CONTROL_HZ,
        "bfsitl/Waypoints-v0": 20 * DEFAULT_CONTROL_HZ,
        "bfsitl/Recover-v0": 4 * DEFAULT_CONTROL_HZ,
    }
    for env_id, steps in bfsitl.gym.MAX_EPISODE_STEPS.items():
        assert gymnasium.spec(env_id).max_episode_steps == steps
    build = fake_lockstep_build(tmp_path)
    alone = HoverEnv(sitl=SitlLaunch(firmware=build), max_episode_steps=50)  # made directly
    assert alone._step_limit() == 50
    waypoints = WaypointsEnv(sitl=SitlLaunch(firmware=build))
    assert waypoints._step_limit() == 2000
    made = gymnasium.make("bfsitl/Hover-v0", sitl=SitlLaunch(firmware=build), max_episode_steps=70)
    # Made by Gymnasium: its TimeLimit counts make's max_episode_steps, the environment not.
    assert made.spec is not None and made.spec.max_episode_steps == 70
    assert made.unwrapped._step_limit() is None  # type: ignore[attr-defined]
    for env in (alone, waypoints, made):
        env.close()


def test_a_stock_build_is_refused_with_the_command_that_makes_a_lockstep_one(tmp_path) -> None:  # type: ignore[no-untyped-def]
    stock = tmp_path / "betaflight_4.6.0_SITL"
    stock.write_bytes(b"\x00" * 64)
    stock.chmod(0o755)
    with pytest.raises(
        EnvironmentConfigError,
        match=r"not a lockstep build.*bfsitl firmware build --gps --lockstep",
    ):
        FlightEnv(Hover(), sitl=SitlLaunch(firmware=stock))


# -- the hand-written policy ------------------------------------------------------------------
def offsets(north: float, east: float, up: float, heading_deg: float) -> np.ndarray:
    observation = np.zeros(20, dtype=np.float32)
    observation[:3] = (north, east, up)
    observation[8:10] = (math.sin(math.radians(heading_deg)), math.cos(math.radians(heading_deg)))
    return observation


def test_the_hand_policy_steers_towards_the_target_whatever_the_heading() -> None:
    from bfsitl.gym.baseline import HOVER_THROTTLE, hand_policy

    roll, pitch, throttle, yaw = hand_policy(offsets(1.0, 0.0, 0.0, 0.0))
    assert pitch > 0 and roll == 0 and throttle == pytest.approx(HOVER_THROTTLE) and yaw == 0
    roll, pitch, *_ = hand_policy(offsets(0.0, 1.0, 0.0, 0.0))  # east of a north-facing quad
    assert roll > 0 and pitch == pytest.approx(0.0, abs=1e-6)
    roll, pitch, *_ = hand_policy(offsets(1.0, 0.0, 0.0, 90.0))  # north of an east-facing one
    assert roll < 0 and pitch == pytest.approx(0.0, abs=1e-6)  # it is on its left
    _, _, throttle, _ = hand_policy(offsets(0.0, 0.0, 1.0, 0.0))
    assert throttle > HOVER_THROTTLE  # below the target: climb


# -- recording an episode ----------------------------------------------------------------------
def test_a_step_becomes_a_flight_row_with_the_fc_the_truth_and_the_target() -> None:
    from types import SimpleNamespace

    from bfsitl.gym.recording import snapshot_row

    env = SimpleNamespace(rc_command=RcCommand(1600, 1450, 1550, 1500, (1800, 1800)))
    row = snapshot_row(snapshot(), (1.0, 2.0, 3.0), env, wall_s=0.5, waypoint=0)  # type: ignore[arg-type]
    assert (row.time_s, row.phase, row.waypoint) == (12.0, "policy", 1)
    assert (row.target_north_m, row.target_east_m, row.target_alt_m) == (1.0, 2.0, 3.0)
    assert (row.fc_alt_m, row.fc_north_m, row.fc_east_m) == (1.9, 0.5, -0.5)
    assert (row.sim_alt_m, row.sim_north_m, row.sim_east_m) == (2.0, 0.6, -0.6)
    assert row.roll_deg == pytest.approx(math.degrees(0.1))
    assert row.pitch_deg == pytest.approx(math.degrees(-0.2))
    assert row.yaw_deg == pytest.approx(90.0) and row.sim_yaw_deg == pytest.approx(180.0)
    assert (row.rc_roll_us, row.rc_pitch_us, row.rc_throttle_us, row.rc_aux1_us) == (
        1600,
        1450,
        1550,
        1800,
    )
    assert row.motor4 == 0.71 and row.armed and row.fc_accel_up_m_s2 == 0.05


def test_the_warm_reset_holds_each_quad_about_its_own_hover_stick() -> None:
    from bfsitl.gym.baseline import HOVER_THROTTLE, hover_stick
    from bfsitl.physics import IRIS
    from bfsitl.vehicles import hover_throttle_us, load_vehicle

    assert hover_stick(IRIS) == HOVER_THROTTLE  # unchanged to the bit
    five = load_vehicle("5inch-freestyle")
    # A quarter of the stick for a 5-inch: well below the middle, a little above its hover.
    stick_us = 1500 + 500 * hover_stick(five)
    assert hover_throttle_us(five) < stick_us < hover_throttle_us(five) + 10
