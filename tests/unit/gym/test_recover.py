"""Recover-v0's parts without a SITL: the throws drawn (attitude, speed, spin as said, the
same for a seed), the hand that lets go in the physics, and the task's scoring (tilt ends
nothing, the ground does; a recovery only when upright, slow and calm at once)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from support.fake_builds import fake_lockstep_build  # noqa: E402
from support.true_views import true_view  # noqa: E402

from bfsitl.backend.disturbances import Disturbances  # noqa: E402
from bfsitl.errors import DisturbanceUnavailableError, EnvironmentConfigError  # noqa: E402
from bfsitl.gym.env import RecoverEnv  # noqa: E402
from bfsitl.gym.snapshot import TrueView  # noqa: E402
from bfsitl.gym.tasks import Recover, recovered  # noqa: E402
from bfsitl.gym.throws import Throw  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402
from bfsitl.physics.frames import rotation_matrix  # noqa: E402
from bfsitl.physics.multirotor import Simulator  # noqa: E402


def body_down_tilt_deg(quaternion: tuple[float, float, float, float]) -> float:
    """The angle between the body's z (down through the belly) and the world's down."""
    r = rotation_matrix(quaternion)  # row-major, body FRD to NED
    return math.degrees(math.acos(max(-1.0, min(1.0, r[8]))))


def test_a_throw_is_tilted_moving_and_spinning_by_what_it_says_and_repeats_for_a_seed() -> None:
    throw = Throw(height_m=8.0, max_tilt_deg=180.0, max_speed_m_s=3.0, max_rate_deg_s=360.0)
    draws = [throw.draw(np.random.default_rng(seed)) for seed in range(300)]
    for thrown in draws:
        assert body_down_tilt_deg(thrown.quaternion_wxyz) == pytest.approx(
            thrown.tilt_deg, abs=1e-6
        )
        assert math.hypot(*thrown.velocity_ned_m_s) == pytest.approx(thrown.speed_m_s)
        spin = math.degrees(math.hypot(*thrown.angular_velocity_frd_rad_s))
        assert spin == pytest.approx(thrown.rate_deg_s)
    tilts = np.array([d.tilt_deg for d in draws])
    # Uniform over the range: the whole of it is drawn, upside down included.
    assert tilts.min() < 10.0 and tilts.max() > 170.0 and 75.0 < tilts.mean() < 105.0
    assert max(d.speed_m_s for d in draws) <= 3.0 and max(d.rate_deg_s for d in draws) <= 360.0
    # Directions over the whole sphere: down and up, each way.
    downs = [d.velocity_ned_m_s[2] for d in draws]
    assert min(downs) < -1.0 and max(downs) > 1.0
    assert throw.draw(np.random.default_rng(7)) == throw.draw(np.random.default_rng(7))
    assert throw.draw(np.random.default_rng(7)) != throw.draw(np.random.default_rng(8))
    level = Throw(max_tilt_deg=0.0, max_speed_m_s=0.0, max_rate_deg_s=0.0)
    still = level.draw(np.random.default_rng(1))
    assert body_down_tilt_deg(still.quaternion_wxyz) == pytest.approx(0.0, abs=1e-6)
    assert still.velocity_ned_m_s == (0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    ("field", "value"),
    [("height_m", 1.0), ("height_m", 16.0), ("max_tilt_deg", 181.0), ("max_speed_m_s", -1.0)],
)
def test_a_throw_outside_its_range_is_refused_naming_the_field(field: str, value: float) -> None:
    with pytest.raises(EnvironmentConfigError, match=rf"Throw\.{field} {value} is outside"):
        Throw(**{field: value})  # type: ignore[arg-type]


def test_the_hand_lets_go_tumbling_with_the_rotors_stopped() -> None:
    simulator = Simulator()
    hands = Disturbances("embedded", simulator=simulator)
    simulator.hold(True)
    thrown = Throw(height_m=10.0).draw(np.random.default_rng(3))
    hands.let_go(
        (1.0, 2.0, -10.0),
        quaternion_wxyz=thrown.quaternion_wxyz,
        velocity_ned_m_s=thrown.velocity_ned_m_s,
        angular_velocity_frd_rad_s=thrown.angular_velocity_frd_rad_s,
    )
    state = simulator.state
    assert state.position_ned_m == pytest.approx((1.0, 2.0, -10.0))
    assert state.quaternion_wxyz == pytest.approx(thrown.quaternion_wxyz)
    assert state.velocity_ned_m_s == pytest.approx(thrown.velocity_ned_m_s)
    assert state.angular_velocity_frd_rad_s == pytest.approx(thrown.angular_velocity_frd_rad_s)
    assert state.motor_speeds_rad_s == (0.0, 0.0, 0.0, 0.0)
    for _ in range(100):  # 0.1 s, no thrust: released, it falls and flies on
        simulator.step((0.0, 0.0, 0.0, 0.0), 0.001)
    moved = simulator.state
    vn, ve, vd = thrown.velocity_ned_m_s
    assert moved.velocity_ned_m_s[2] == pytest.approx(vd + 0.981, abs=0.05)
    assert moved.position_ned_m[0] == pytest.approx(1.0 + 0.1 * vn, abs=0.02)
    with pytest.raises(DisturbanceUnavailableError, match="embedded physics"):
        Disturbances("gazebo").let_go(
            (0.0, 0.0, -5.0),
            quaternion_wxyz=(1.0, 0.0, 0.0, 0.0),
            velocity_ned_m_s=(0.0, 0.0, 0.0),
            angular_velocity_frd_rad_s=(0.0, 0.0, 0.0),
        )


def truth(**changes: object) -> TrueView:
    """A quad 9 m up, tilted 5 deg, still: recovered unless ``changes`` say otherwise."""
    return true_view(**{"alt_m": 9.0, "tilt_deg": 5.0, **changes})


def test_upright_slow_and_calm_at_once_is_a_recovery_and_each_alone_is_not() -> None:
    assert recovered(truth())
    assert not recovered(truth(tilt_deg=25.0))  # swinging through level...
    assert not recovered(truth(v_up_m_s=-1.2))  # ...still falling...
    assert not recovered(truth(v_north_m_s=0.8, v_east_m_s=0.8))  # ...or drifting fast
    assert not recovered(truth(rates_flu_rad_s=(0.0, 1.1, 0.0)))  # ...or turning


def test_the_recover_task_scores_from_the_throw_and_only_the_ground_or_bounds_end_it() -> None:
    task = Recover(throw=Throw(height_m=10.0))
    task.reset(np.random.default_rng(2))
    assert task.target == (0.0, 0.0, 10.0) and task.thrown is not None
    upside_down = truth(alt_m=9.5, tilt_deg=170.0, v_up_m_s=-3.0)
    assert task.failure(upside_down, armed=True, has_flown=True) is None
    assert task.advance(upside_down) == (0.0, False)
    assert task.recovered_step is None
    before = task.info()
    assert before["recovered"] is False and before["recovered_step"] == -1
    task.advance(truth(alt_m=7.2, tilt_deg=30.0, v_up_m_s=-0.5))
    task.advance(truth(alt_m=7.4))  # the third step: upright, slow, calm
    task.advance(truth(alt_m=7.9))
    assert task.recovered_step == 3
    assert task.height_lost_m == pytest.approx(2.8)
    info = task.info()
    assert info["recovered"] is True and info["recovered_step"] == 3
    assert info["height_lost_m"] == pytest.approx(2.8)
    # Each key keeps its type whether recovered or not (a vector environment's info arrays
    # take the type of the first value they meet).
    assert {k: type(v) for k, v in info.items()} == {k: type(v) for k, v in before.items()}
    assert set(info["throw"]) == {"tilt_deg", "speed_m_s", "rate_deg_s"}  # type: ignore[arg-type]
    ground = truth(alt_m=0.0, on_ground=True, tilt_deg=90.0)
    assert task.failure(ground, armed=True, has_flown=True) == "crashed: back on the ground"
    assert task.failure(truth(), armed=False, has_flown=True) == "the FC disarmed"
    task.reset(np.random.default_rng(2))  # a new episode forgets the last
    assert task.recovered_step is None and task.height_lost_m == 0.0


def test_recover_starts_at_the_throws_height_and_refuses_another_start(tmp_path: Path) -> None:
    sitl = SitlLaunch(firmware=fake_lockstep_build(tmp_path))
    env = RecoverEnv(sitl=sitl, throw=Throw(height_m=6.0), mode="acro")
    assert env.start_alt_m == 6.0 and env.mode == "acro" and env.max_episode_steps == 400
    env.close()
    for options in ({"start_alt_m": 3.0}, {"start": "ground"}):
        with pytest.raises(EnvironmentConfigError, match=r"throw=Throw\(height_m=\.\.\.\)"):
            RecoverEnv(sitl=sitl, **options)
    with pytest.raises(EnvironmentConfigError, match="throw must be a Throw"):
        RecoverEnv(sitl=sitl, throw={"height_m": 5})
