"""The real Betaflight as a Gymnasium environment, stepped in lockstep.

Each environment owns one SITL of a ``--lockstep`` build, in its own network namespace: the
firmware's clock moves only when the physics steps, so a step of the policy is exactly
``1 / control_hz`` of simulated time however long the policy thinks, and the same seed and
actions give the same trajectory, bit for bit (``tests/integration/test_gym_sitl.py``).

**A step**: the action's sticks go out as RC (riding in the next fdm packets), the simulation
runs to the next control tick, and the FC is read (one MSP round trip, the GPS in it) beside
the truth.

**A reset with a seed** (and the first reset) ends the SITL and boots a fresh one from the same
provisioned EEPROM, arms it and, with ``start="air"``, has bfsitl's own autopilot take off to
``start_alt_m`` before the policy gets the sticks: nothing of the firmware's state carries
over, so the same seed and actions repeat bit for bit.  It costs about 0.6 s of wall time (the
FC's 5 s boot grace, the ground wait and the take-off, all on simulated time).  The first
reset provisions the EEPROM once (ARM, ANGLE and the serial rate), in a boot of its own, so
the first episode starts like all the others.

**A reset without a seed** (what training does between episodes) is warm when the firmware is
alive, armed and out of failsafe: a hand (the disturbance surface's ``place`` and
``hold_still``) puts the vehicle back at the start, level, rotors at hover speed, and holds it
for ``WARM_SETTLE_S`` of simulated time while the FC settles, throttle low first so that the
FC resets its I-terms, then lets go: about 10 ms of wall time.  What carries over is what a
quad caught by hand and released would keep: the filters, the attitude estimate (held level,
it settles), the clock, the GPS origin and the altitude zero of the first arming.  It is as
deterministic as the episodes before it: from a seeded reset on, the same actions give the
same flights.  ``warm_resets=False`` boots afresh every time.

The observation (:mod:`~bfsitl.gym.observation`), the reward and the endings
(:mod:`~bfsitl.gym.tasks`) are documented where they are computed; what ``render()`` draws
with ``render_mode="rgb_array"``, in :mod:`~bfsitl.gym.render`.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Literal, get_args

import gymnasium
import numpy as np
from gymnasium import spaces

from bfsitl.backend.disturbances import Disturbances
from bfsitl.backend.options import Timing, World
from bfsitl.control import make_controller
from bfsitl.errors import EnvironmentConfigError, LinkError, MspError, SitlError
from bfsitl.fc.rc_link import RcCommand
from bfsitl.gym.baseline import hover_stick
from bfsitl.gym.latency import NO_LATENCY, DelayLine, Latency
from bfsitl.gym.observation import (
    OBSERVATIONS,
    ObservationSource,
    observation_space,
    observe,
)
from bfsitl.gym.option_checks import (
    check_choice,
    check_course,
    check_group,
    check_groups,
    check_horizontal_m,
    check_rc_link,
)
from bfsitl.gym.random_vehicle import RandomVehicle
from bfsitl.gym.random_wind import RandomWind
from bfsitl.gym.render import RENDER_MODES, check_render_mode, render_frame
from bfsitl.gym.snapshot import Snapshot, Vec3, read_snapshot
from bfsitl.gym.sticks import sticks_to_rc
from bfsitl.gym.tasks import (
    AIRBORNE_M,
    FAILURE_REWARD,
    Hover,
    Recover,
    Waypoints,
    distance_m,
)
from bfsitl.gym.throws import Throw
from bfsitl.mission.loop import FlightLoop
from bfsitl.mission.session import FcSetup, FlightSession, SessionConfig, SitlLaunch
from bfsitl.owned_temp import owned_temp_dir
from bfsitl.physics.wind import Wind
from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ
from bfsitl.sitl.core_claim import CoreClaim, claim_core
from bfsitl.sitl.firmware import find_firmware

#: The FC's mode the policy's sticks fly in: ANGLE (roll and pitch set an angle) or ACRO
#: (every stick sets a rate).
FlightMode = Literal["angle", "acro"]
MODES: tuple[FlightMode, ...] = get_args(FlightMode)
#: Where an episode starts: in the air, after bfsitl's own take-off, or armed on the ground.
EpisodeStart = Literal["air", "ground"]
STARTS: tuple[EpisodeStart, ...] = get_args(EpisodeStart)
#: The control rates a lockstep SITL's MSP budget sustains (the serial task runs at 1 kHz).
CONTROL_HZ_RANGE = (1.0, 200.0)
DEFAULT_CONTROL_HZ = 100.0
#: The episodes' lengths in steps (Gymnasium's ``max_episode_steps``, registered with the
#: ids): 10 s of Hover and 20 s of Waypoints at the default control rate.
HOVER_MAX_EPISODE_STEPS = round(10.0 * DEFAULT_CONTROL_HZ)
WAYPOINTS_MAX_EPISODE_STEPS = round(20.0 * DEFAULT_CONTROL_HZ)
#: A throw's episode: 4 s, to recover and then hold.
RECOVER_MAX_EPISODE_STEPS = round(4.0 * DEFAULT_CONTROL_HZ)
DEFAULT_FIRMWARE = "4.6.0-gps-lockstep"
#: How high an "air" start hands over, metres above where the quad armed.
DEFAULT_START_ALT_M = 1.5
#: Armed on the ground before an "air" start's take-off (the FC's altitude settles).
_GROUND_S = 1.0
#: A warm reset holds the vehicle this long (simulated) while the FC settles.
WARM_SETTLE_S = 0.5

#: Called before every step with the flight's disturbance surface and the episode's time:
#: faults, wind changes, a weak motor, sensor errors (see bfsitl.backend.disturbances).
DisturbanceHook = Callable[[Disturbances, float], object]


#: The SITL an environment starts by default: the GPS lockstep build of 4.6.0, in a
#: temporary run directory the environment removes when it closes.
DEFAULT_SITL = SitlLaunch(firmware=DEFAULT_FIRMWARE)
#: As fast as the lockstep goes, spinning where the environment has the cores (see spin).
DEFAULT_TIMING = Timing()
#: Still air, IRIS, the default sensor errors; each episode brings its own seed.
DEFAULT_WORLD = World()


class FlightEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    """See the module docstring; :class:`HoverEnv` and :class:`WaypointsEnv` choose the task.

    The options that configure the flight are the session's groups
    (:class:`~bfsitl.mission.session.SessionConfig`), as keywords: ``sitl`` (the firmware,
    a lockstep build, and the SITL's run directory: None is a temporary one, removed on
    close), ``timing`` (the lockstep: always on here; ``lockstep_spin`` None spins unless the
    environment is pinned to a core or in a vector environment's worker) and ``world`` (the
    quad, wind, sensors and heading of the embedded physics; its seed is replaced by each
    episode's).  Another quad: ``world=World(quad=load_vehicle("5inch-freestyle"))``
    (:func:`bfsitl.vehicles.load_vehicle`; a profile file too).  The rest are the
    environment's own: the policy's rate, mode and observation, the episode's start and
    length, the disturbances, the observation's ``latency`` (:mod:`~bfsitl.gym.latency`:
    late by some control steps, drawn per episode, for a policy that is to fly outside the
    lockstep), ``rc_rate_hz`` (the RC link's frames a second, 250 by default, 16 to 1000;
    None: one in every fdm packet), ``rc_frame_per_step`` (one receiver frame per step
    instead: the FC smooths at a rate of the policy's), ``random_wind``
    (:mod:`~bfsitl.gym.random_wind`: a wind drawn per episode, instead of ``world.wind``),
    ``random_vehicle``
    (:mod:`~bfsitl.gym.random_vehicle`: a quad drawn per episode, instead of ``world.quad``),
    the core pinning and the warm resets, and ``render_mode``:
    ``"rgb_array"`` makes :meth:`render` draw the truth (:mod:`~bfsitl.gym.render`).
    """

    #: Each environment's own copy says its ``control_hz`` as the frame rate: one frame a
    #: step, so a recorded video runs in simulated real time.
    metadata: dict[str, Any] = {
        "render_modes": list(RENDER_MODES),
        "render_fps": DEFAULT_CONTROL_HZ,
    }

    def __init__(
        self,
        task: Hover,
        *,
        sitl: SitlLaunch = DEFAULT_SITL,
        timing: Timing = DEFAULT_TIMING,
        world: World = DEFAULT_WORLD,
        control_hz: float = DEFAULT_CONTROL_HZ,
        mode: FlightMode = "angle",
        observation: ObservationSource = "fc",
        disturbances: DisturbanceHook | None = None,
        max_episode_steps: int | None = HOVER_MAX_EPISODE_STEPS,
        start: EpisodeStart = "air",
        start_alt_m: float = DEFAULT_START_ALT_M,
        latency: Latency = NO_LATENCY,
        rc_frame_per_step: bool = False,
        rc_rate_hz: float | None = DEFAULT_RC_RATE_HZ,
        random_wind: RandomWind | None = None,
        random_vehicle: RandomVehicle | None = None,
        pin_core: bool | None = None,
        warm_resets: bool = True,
        render_mode: str | None = None,
    ) -> None:
        check_groups(sitl, timing, world, latency, random_wind, random_vehicle)
        check_choice("mode", mode, MODES)
        check_choice("observation", observation, OBSERVATIONS)
        check_choice("start", start, STARTS)
        check_render_mode(render_mode)
        spin = timing.lockstep_spin
        low, high = CONTROL_HZ_RANGE
        if not low <= control_hz <= high:
            raise EnvironmentConfigError(f"control_hz {control_hz} is outside {low:g}..{high:g} Hz")
        if max_episode_steps is not None and max_episode_steps < 1:
            raise EnvironmentConfigError(
                f"max_episode_steps {max_episode_steps} is not a number of steps (1 or more; "
                f"None: no limit)"
            )
        if not 0.5 <= start_alt_m <= 15.0:
            raise EnvironmentConfigError(f"start_alt_m {start_alt_m} is outside 0.5..15 m")
        check_rc_link(rc_rate_hz, rc_frame_per_step)
        in_worker = multiprocessing.parent_process() is not None
        #: Pin this process and its SITL to one core of their own (bfsitl.sitl.core_claim):
        #: the lockstep hand-over stays on that core, and environments side by side do not
        #: take each other's time.  None: in the workers of a vector environment only.
        self.pin_core = in_worker if pin_core is None else pin_core
        if self.pin_core and spin:
            raise EnvironmentConfigError(
                "timing.lockstep_spin=True with pin_core=True: the SITL and the environment "
                "share the pinned core, so a busy-wait would starve the firmware it waits for; "
                "choose one"
            )
        #: Busy-wait for the firmware's replies (Timing.lockstep_spin): the SITL and bfsitl
        #: each keep a core busy, which makes one environment faster and several sharing the
        #: cores slower (benchmarks/gym.py).  None: spin when not pinned and not in the
        #: worker of a vector environment.
        self.spin = (not in_worker and not self.pin_core) if spin is None else spin
        # Every option is checked before the firmware is looked up: a wrong option is said
        # as such, whatever builds this machine holds.
        self.binary = find_firmware(sitl.firmware)
        if not self.binary.lockstep:
            raise EnvironmentConfigError(
                f"{sitl.firmware}: not a lockstep build; the environment steps the firmware "
                f"with the physics. Build one: `bfsitl firmware build --gps --lockstep` (makes "
                f"{DEFAULT_FIRMWARE})"
            )
        self.task = task
        self.control_hz = control_hz
        self.render_mode = render_mode
        self.metadata = {"render_modes": list(RENDER_MODES), "render_fps": control_hz}
        self.mode = mode
        self.observation = observation
        # What every episode's session is made from: the lockstep always on, the spin as
        # decided above; the session's SITL takes the firmware found and the run directory.
        self.sitl = sitl
        self.timing = dataclasses.replace(timing, lockstep=True, lockstep_spin=self.spin)
        self.world = world
        self.disturbances = disturbances
        #: Truncate the episode after this many steps (None: never), when the environment is
        #: made directly (``HoverEnv(...)``, a vector environment's workers, a Ray actor).
        #: Made by ``gymnasium.make``, Gymnasium's TimeLimit counts its own
        #: ``max_episode_steps`` (registered, or given to ``make``) and this one is not
        #: counted: one limit, never two that disagree (see :meth:`_step_limit`).
        self.max_episode_steps = max_episode_steps
        self.start = start
        self.start_alt_m = start_alt_m
        #: How late the policy's observation is (bfsitl.gym.latency), drawn per episode.
        self.latency = latency
        self._delay = DelayLine(latency)
        #: A wind drawn per episode (bfsitl.gym.random_wind), None: the world's always.
        self.random_wind = random_wind
        self._episode_wind: Wind | None = world.wind
        #: A quad drawn per episode (bfsitl.gym.random_vehicle), None: the world's always.
        self.random_vehicle = random_vehicle
        self._episode_quad = world.quad
        #: The FC's receiver takes one RC frame per control step, as from a companion computer
        #: or a receiver at that rate, instead of one per fdm packet (in which 4.6.0 finds no
        #: receiver rate and smooths nothing): the policy then flies the RC smoothing it
        #: meets outside the lockstep.  Needs a build that counts receiver frames
        #: (`bfsitl firmware build --lockstep` of this bfsitl).
        self.rc_frame_per_step = rc_frame_per_step
        self.rc_rate_hz = rc_rate_hz
        self._core: CoreClaim | None = None
        #: A reset without a seed keeps the firmware running when it can (see the module
        #: docstring); False boots a fresh one every time.
        self.warm_resets = warm_resets
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self.observation_space = observation_space()
        self._own_workdir = sitl.workdir is None
        #: The SITL's run directory (its EEPROM, provisioned once, boots every episode).
        self.workdir = Path(owned_temp_dir("bfsitl-gym-") if sitl.workdir is None else sitl.workdir)
        self._vehicle: FlightSession | None = None
        self._prepared = False
        self._arm_ned: Vec3 = (0.0, 0.0, 0.0)
        self._started_s = 0.0
        self._next_s = 0.0
        self._has_flown = False
        self._steps = 0  # in this episode
        self._snapshot: Snapshot | None = None

    # -- the episode -------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is None and self.warm_resets and self.start == "air" and self._can_go_on():
            return self._warm_reset()
        self._close_vehicle()
        if not self._prepared:
            self._prepare()
        episode_seed = int(self.np_random.integers(0, 2**31 - 1))
        self.task.reset(self.np_random)
        self._draw_episode()
        vehicle = self._new_session(episode_seed).start()
        self._vehicle = vehicle
        throws = isinstance(self.task, Recover)
        if throws:
            # The take-off only lifts the quad to the hand, which throws it into the
            # episode's wind: in still air, so that a gusty wind cannot tip a small quad on
            # the way (the autopilot's take-off of the 5-inch did, in 3 m/s gusting 1.5).
            vehicle.disturbances.set_wind(None)
        if self.start == "air":
            loop = FlightLoop(
                vehicle, make_controller("fused", quad=self._episode_quad), rate_hz=self.control_hz
            )
            loop.arm()
            self._mark_arming(vehicle)
            loop.wait_on_ground(_GROUND_S)
            loop.takeoff(self.start_alt_m, hold_position=vehicle.has_gps)
            if throws:
                return self._hand_start(vehicle)  # the throw
        else:
            vehicle.arm()
            self._mark_arming(vehicle)
        self._set_wind(vehicle.disturbances)
        self._started_s = self._next_s = vehicle.time_s
        self._steps = 0
        self._has_flown = self.start == "air"
        self._frames_per_step(vehicle, True)
        self._snapshot = read_snapshot(vehicle, arm_ned_m=self._arm_ned)
        return self._delay.restart(self._observe(), self.np_random), self._info(None)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        vehicle = self._vehicle
        if vehicle is None:
            raise EnvironmentConfigError("step() before reset(): call env.reset() first")
        action = np.asarray(action, dtype=np.float32)
        if action.shape != (4,):
            raise EnvironmentConfigError(
                f"an action is 4 sticks (roll, pitch, throttle, yaw), got shape {action.shape}"
            )
        try:
            if self.disturbances is not None:
                self.disturbances(vehicle.disturbances, vehicle.time_s - self._started_s)
            vehicle.set_rc(sticks_to_rc(action.tolist(), vehicle.rc_command))
            self._next_s += 1.0 / self.control_hz
            wait_s = self._next_s - vehicle.time_s
            if wait_s > 0:
                vehicle.clock.sleep_s(wait_s)
            else:
                self._next_s = vehicle.time_s  # late: the schedule restarts here
            self._snapshot = snapshot = read_snapshot(vehicle, arm_ned_m=self._arm_ned)
        except (SitlError, LinkError, MspError) as exc:
            # The firmware died or stopped answering: the episode ends, the next reset boots
            # a fresh one; training goes on.
            self._close_vehicle()
            assert self._snapshot is not None
            return (
                self._delay.push(self._observe()),
                FAILURE_REWARD,
                True,
                False,
                self._info(f"the SITL failed: {exc}".splitlines()[0]),
            )
        truth = snapshot.truth
        if truth.alt_m > AIRBORNE_M:
            self._has_flown = True
        reward = self.task.reward(truth, action)
        bonus, finished = self.task.advance(truth)
        why = self.task.failure(truth, armed=snapshot.fc.armed, has_flown=self._has_flown)
        reward += bonus + (FAILURE_REWARD if why is not None else 0.0)
        terminated = finished or why is not None
        self._steps += 1
        limit = self._step_limit()
        truncated = not terminated and limit is not None and self._steps >= limit
        observation = self._delay.push(self._observe())
        return observation, float(reward), terminated, truncated, self._info(why)

    def _step_limit(self) -> int | None:
        """Where this environment truncates an episode itself: :attr:`max_episode_steps`,
        unless ``gymnasium.make`` made it (it sets ``spec``), whose TimeLimit wrapper then
        counts the steps; counting here as well would end the episode at two limits when
        ``make`` was given another ``max_episode_steps`` than the default."""
        return None if self.spec is not None else self.max_episode_steps

    def _can_go_on(self) -> bool:
        """The firmware is alive, armed and out of failsafe: a warm reset can use it."""
        vehicle, snapshot = self._vehicle, self._snapshot
        return (
            vehicle is not None
            and snapshot is not None
            and not vehicle.has_exited()
            and snapshot.fc.armed
            and "FAILSAFE" not in snapshot.fc.flight_modes
        )

    def _warm_reset(self) -> tuple[np.ndarray, dict[str, Any]]:
        assert self._vehicle is not None
        self.task.reset(self.np_random)
        self._draw_episode()
        simulator = self._vehicle.simulator
        assert simulator is not None
        if simulator.params != self._episode_quad:
            # Swapped while the hand holds it, which places it next (random_vehicle).
            simulator.set_vehicle(self._episode_quad)
            self._vehicle.quad = self._episode_quad
        return self._hand_start(self._vehicle)

    def _hand_start(self, vehicle: FlightSession) -> tuple[np.ndarray, dict[str, Any]]:
        """A hand puts the vehicle at the start, level, rotors at hover speed, and holds it
        there while the FC settles: sticks centred, throttle low first (the FC resets its
        I-terms at low throttle), then about the hover point; then lets go, level and at
        rest, or (:class:`~bfsitl.gym.tasks.Recover`) throws it as the task drew."""
        assert vehicle.simulator is not None
        hands = vehicle.disturbances
        north, east, down = self._arm_ned
        start = (north, east, down - self.start_alt_m)
        hover_rad_s = vehicle.simulator.params.hover_rotor_speed_rad_s
        hands.place(start, motor_speeds_rad_s=(hover_rad_s,) * 4)
        hands.hold_still(True)
        # The held sticks go out as frames all along: no gap the FC would take for a lost link.
        self._frames_per_step(vehicle, False)
        for throttle in (-1.0, hover_stick(self._episode_quad)):
            vehicle.set_rc(sticks_to_rc([0.0, 0.0, throttle, 0.0], vehicle.rc_command))
            vehicle.clock.sleep_s(WARM_SETTLE_S / 2)
        thrown = self.task.thrown if isinstance(self.task, Recover) else None
        self._set_wind(hands)
        if thrown is None:
            hands.place(start, motor_speeds_rad_s=(hover_rad_s,) * 4)
            hands.hold_still(False)
        else:
            hands.let_go(
                start,
                quaternion_wxyz=thrown.quaternion_wxyz,
                velocity_ned_m_s=thrown.velocity_ned_m_s,
                angular_velocity_frd_rad_s=thrown.angular_velocity_frd_rad_s,
            )
        self._frames_per_step(vehicle, True)
        self._started_s = self._next_s = vehicle.time_s
        self._steps = 0
        self._has_flown = True
        self._snapshot = read_snapshot(vehicle, arm_ned_m=self._arm_ned)
        return self._delay.restart(self._observe(), self.np_random), self._info(None)

    def close(self) -> None:
        self._close_vehicle()
        if self._core is not None:
            self._core.release()
            self._core = None
        if self._own_workdir:
            shutil.rmtree(self.workdir, ignore_errors=True)
        super().close()

    def render(self) -> np.ndarray | None:
        """The frame of the last step's truth and the task's targets (uint8, height x width
        x 3; :mod:`~bfsitl.gym.render`), or None without a ``render_mode``, as Gymnasium
        has it."""
        if self.render_mode is None:
            return None
        snapshot = self._snapshot
        if snapshot is None:
            raise EnvironmentConfigError("render() before reset(): call env.reset() first")
        return render_frame(snapshot.truth, self.task.targets, current=self.task.index)

    @property
    def snapshot(self) -> Snapshot | None:
        """The last look at the flight (the FC's view and the truth), None before a reset."""
        return self._snapshot

    @property
    def rc_command(self) -> RcCommand | None:
        """What the RC link sends now (the last action's sticks and the switches)."""
        return self._vehicle.rc_command if self._vehicle is not None else None

    # -- parts ---------------------------------------------------------------------------------
    def _new_session(self, seed: int) -> FlightSession:
        # The RC link's rate (the default) has a 4.6.0 build count a frame per trailer, which
        # rc_frame_per_step's frames on set need too.
        sitl = dataclasses.replace(self.sitl, firmware=self.binary.path, workdir=self.workdir)
        config = SessionConfig.for_autopilot(
            control_rate_hz=self.control_hz,
            sitl=sitl,
            timing=self.timing,
            fc=FcSetup(angle_mode=self.mode == "angle", rc_rate_hz=self.rc_rate_hz),
            world=dataclasses.replace(self.world, seed=seed, quad=self._episode_quad),
        )
        return FlightSession(config)

    def _prepare(self) -> None:
        """One boot that provisions the EEPROM, so every episode boots the same FC (on the
        claimed core, which every SITL started from now on inherits)."""
        if self.pin_core and self._core is None:
            self._core = claim_core()
        with self._new_session(0) as session:
            session.start()
        self._prepared = True

    def _draw_episode(self) -> None:
        """This episode's wind and quad, where they are drawn per episode."""
        if self.random_wind is not None:
            self._episode_wind = self.random_wind.draw(self.np_random)
        if self.random_vehicle is not None:
            self._episode_quad = self.random_vehicle.draw(self.np_random)

    def _set_wind(self, hands: Disturbances) -> None:
        """This episode's wind from now on (it is off during a throw's take-off, and a
        random one changes with every episode); left alone when it is already blowing, so
        that its gusts go on."""
        if hands.wind != self._episode_wind:
            hands.set_wind(self._episode_wind)

    def _mark_arming(self, vehicle: FlightSession) -> None:
        simulator = vehicle.simulator
        assert simulator is not None
        north, east, down = simulator.state.position_ned_m
        self._arm_ned = (north, east, down)

    def _frames_per_step(self, vehicle: FlightSession, on: bool) -> None:
        """One receiver frame per step from now on (``on``, with ``rc_frame_per_step``), or
        the RC link's frames at its rate (arming, the take-off, a warm reset's hold)."""
        bridge = vehicle.bridge
        if self.rc_frame_per_step and bridge is not None:
            # The environment flies lockstep builds only (checked when it is made), as log
            # replay does: the bridge is a LockstepBridge.
            bridge.rc_frames_on_set = on  # type: ignore[union-attr]

    def _close_vehicle(self) -> None:
        vehicle, self._vehicle = self._vehicle, None
        if vehicle is not None:
            vehicle.close()

    def _observe(self) -> np.ndarray:
        assert self._snapshot is not None
        return observe(self._snapshot, self.task.target, self.observation, self.task.next_target)

    def _info(self, ended_because: str | None) -> dict[str, Any]:
        snapshot = self._snapshot
        assert snapshot is not None
        truth = snapshot.truth
        return {
            "time_s": snapshot.time_s - self._started_s,
            "target": self.task.target,
            "waypoint": self.task.index,
            "distance_m": distance_m(truth, self.task.target),
            "truth": truth.as_dict(),
            "armed": snapshot.fc.armed,
            "arming_blockers": snapshot.fc.arming_blockers,
            "flight_modes": snapshot.fc.flight_modes,
            "failsafe": "FAILSAFE" in snapshot.fc.flight_modes,
            "ended_because": ended_because,
            "vehicle": self._episode_quad.name,
            **self.task.info(),
        }


class HoverEnv(FlightEnv):
    """``bfsitl/Hover-v0``: reach and hold one point (see :class:`~bfsitl.gym.tasks.Hover`)."""

    def __init__(self, **options: Any) -> None:
        super().__init__(Hover(), **options)


class WaypointsEnv(FlightEnv):
    """``bfsitl/Waypoints-v0``: ``count`` points in turn (three), each drawn within
    ``horizontal_m`` of the start, or the fixed ``course`` (north, east, up from the start),
    the current point and the one after it in the observation (see
    :class:`~bfsitl.gym.tasks.Waypoints`); 20 s by default."""

    def __init__(
        self,
        *,
        count: int = 3,
        horizontal_m: float = 2.0,
        course: Sequence[Vec3] | None = None,
        max_episode_steps: int | None = WAYPOINTS_MAX_EPISODE_STEPS,
        **options: Any,
    ) -> None:
        if not 1 <= count <= 50:
            raise EnvironmentConfigError(f"count {count} is outside 1..50 waypoints")
        check_horizontal_m(horizontal_m)
        if course is not None:
            start_up_m = options.get("start_alt_m", DEFAULT_START_ALT_M)
            course = check_course(course, start_up_m=start_up_m)
        task = Waypoints(count=count, horizontal_m=horizontal_m, course=course)
        super().__init__(task, max_episode_steps=max_episode_steps, **options)
        self._waypoints = task

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """As every environment's; ``options={"course": [(north, east, up), ...]}`` flies
        that course from this episode on, as if it had been given to the constructor."""
        if options and "course" in options:
            self._waypoints.course = check_course(options["course"], start_up_m=self.start_alt_m)
        return super().reset(seed=seed, options=options)


class RecoverEnv(FlightEnv):
    """``bfsitl/Recover-v0``: thrown (:mod:`~bfsitl.gym.throws`), recover and hold the point
    of the throw (see :class:`~bfsitl.gym.tasks.Recover`); 4 s by default.  ``throw`` is the
    range each episode's throw is drawn from; ``mode`` ``"angle"`` (the FC levels the quad
    itself when the roll and pitch sticks are centred) or ``"acro"`` (every stick a rate: the
    policy rights the quad).  ``start_alt_m`` is the throw's height."""

    def __init__(
        self,
        *,
        throw: Throw | None = None,
        max_episode_steps: int | None = RECOVER_MAX_EPISODE_STEPS,
        **options: Any,
    ) -> None:
        throw = Throw() if throw is None else throw
        check_group("throw", throw, Throw)
        if "start_alt_m" in options or options.get("start", "air") != "air":
            raise EnvironmentConfigError(
                "Recover-v0 starts in the air at the throw's height: give "
                "throw=Throw(height_m=...), not start or start_alt_m"
            )
        super().__init__(
            Recover(throw=throw),
            max_episode_steps=max_episode_steps,
            start_alt_m=throw.height_m,
            **options,
        )
