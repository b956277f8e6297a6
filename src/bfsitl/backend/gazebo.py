"""Gazebo Harmonic's physics under a stock SITL: ``gz sim`` with the BetaflightPlugin.

Gazebo starts first and must have bound its motor port before the SITL boots, as in the
tutorial; both live in the SITL's network namespace because both ends use fixed loopback
ports.  bfsitl's relay (:mod:`bfsitl.gazebo.packet_tap`) sits between them, so Gazebo's own
pose, velocity and motors are the flight's truth.  Time is the wall clock; bfsitl can disturb
RC (over UDP) and, in a flight started with a wind, Gazebo's wind (:mod:`bfsitl.gazebo.wind`).
"""

from __future__ import annotations

import functools
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

from bfsitl.backend.base import SitlBackend, Truth
from bfsitl.backend.disturbances import Disturbances
from bfsitl.errors import BfsitlError
from bfsitl.fc.firmware_detect import profile_of_binary
from bfsitl.gazebo.wind import GazeboWind, wind_enu_m_s
from bfsitl.physics.frames import GeoPoint, betaflight_attitude_deg, tilt_deg

if TYPE_CHECKING:
    from collections.abc import Callable

    from bfsitl.gazebo.launcher import GazeboInstall
    from bfsitl.gazebo.packet_tap import PacketRecorder, PluginTap
    from bfsitl.physics.wind import Wind
    from bfsitl.sitl.process import SitlProcess

#: Gazebo says nothing about contact: the vehicle counts as on the ground while it is within
#: this of the lowest height it was seen at (where it rested before take-off; the skids'
#: compression and the solver's settling are a few millimetres).
ON_GROUND_MARGIN_M = 0.05
#: Where the world's origin is on the earth for a GPS build: the embedded physics' home too.
HOME = GeoPoint(0.0, 0.0, 0.0)


class GazeboBackend(SitlBackend):
    """See the module docstring."""

    name: ClassVar[str] = "Gazebo's physics"

    def __init__(
        self,
        plugin_dir: str | Path | None,
        *,
        progress: Callable[[str], None],
        recorder: PacketRecorder | None = None,
        frozen_rate: bool = True,
        wind: Wind | None = None,
        world_file: str | Path | None = None,
    ) -> None:
        from bfsitl.gazebo import check_gazebo

        super().__init__()
        self.progress = progress
        self.recorder = recorder
        #: Restamp the plugin's fdm packets so that the FC's clock keeps to the wall clock
        #: (:mod:`bfsitl.gazebo.packet_tap`); False keeps Gazebo's stamps, as the tutorial does.
        self.frozen_rate = frozen_rate
        # Fails early, with the fix, before any SITL starts.
        self.install: GazeboInstall = check_gazebo(plugin_dir)
        self.tap: PluginTap | None = None
        #: The user's own world (checked now: a file with the plugin); None: bfsitl's.
        self.world_file: Path | None = None
        if world_file is not None:
            from bfsitl.gazebo.plugin_frame import PluginFrame
            from bfsitl.gazebo.world import world_path

            self.world_file = world_path(world_file)
            PluginFrame.of_world(self.world_file)
        #: The wind the world starts with (None: none, and Gazebo's IRIS feels none).
        self.start_wind = wind
        if wind is not None:
            wind_enu_m_s(wind)  # gusts are refused before anything starts
        self.gazebo_wind: GazeboWind | None = None
        self.disturbances = Disturbances(
            self.name, rc=lambda: self.rc, wind=lambda: self.gazebo_wind
        )
        self._rest_altitude_m: float | None = None

    def start(self, sitl: SitlProcess, stack: ExitStack) -> None:
        from bfsitl.gazebo import (
            check_plugin_port_free,
            plan_gazebo_launch,
            stop_gazebo,
            wait_for_plugin,
        )
        from bfsitl.gazebo.packet_tap import PluginTap, TapPorts
        from bfsitl.gazebo.plugin_frame import PluginFrame, gps_fields
        from bfsitl.gazebo.world import (
            WorldChanges,
            world_for_profile,
            world_name,
            write_session_world,
        )
        from bfsitl.sim.clock_lock import FrozenRateStamps

        stack.callback(sitl.stop)  # runs last: after Gazebo has stopped
        # Gazebo starts before the SITL can say who it is: the binary's profile (its build
        # record, else its bytes) picks the world's frame transform and motor channels.
        profile = profile_of_binary(sitl.firmware.path)
        gps = None
        if profile.has_gps:
            if profile.fdm.gps_mirrored_about_first_fix:
                raise BfsitlError(
                    f"{sitl.firmware.path} is a GPS build of {profile.name}, whose GPS fields "
                    f"bfsitl's Gazebo relay does not write yet: fly a build without GPS, or "
                    f"4.6.0's GPS build, on Gazebo"
                )
            gps = functools.partial(gps_fields, home=HOME)
        ports = TapPorts()
        changes = WorldChanges(
            servo_in_port=ports.plugin_servo,
            fdm_out_port=ports.tap_fdm,
            wind_enu_m_s=wind_enu_m_s(self.start_wind) if self.start_wind is not None else None,
        )
        base = self.world_file or world_for_profile(profile, sitl.workdir)
        world = write_session_world(base, sitl.workdir, changes)
        # The copy lives in the run directory: the original's folder keeps its models found.
        launch = plan_gazebo_launch(world, install=self.install, resource_dirs=[base.parent])
        network = sitl.prepare_network()
        for port in (ports.plugin_servo, ports.tap_fdm, ports.sitl_servo):
            check_plugin_port_free(network, port)
        self.tap = PluginTap(
            network,
            PluginFrame.of_world(world),
            profile.motor_slot_of_betaflight_motor,
            ports=ports,
            recorder=self.recorder,
            clock=self.clock.now_s,
            next_timestamp=FrozenRateStamps().next if self.frozen_rate else None,
            gps_fields=gps,
        ).start()
        stack.callback(self.tap.stop)  # after Gazebo and the SITL stopped sending
        stack.callback(self._say_pace)
        self.progress(f"starting Gazebo: {launch.command_line()}")
        gazebo = network.spawn(
            launch.argv, sitl.workdir, sitl.workdir / "gazebo.log", env=launch.env_dict()
        )
        stack.callback(stop_gazebo, gazebo)
        self.gazebo_wind = GazeboWind.in_network(
            network,
            launch.env_dict(),
            self.install.gz,
            world_name(world),
            sitl.workdir,
            self.start_wind,
        )
        wait_for_plugin(network, gazebo, port=ports.plugin_servo)
        sitl.start()

    def _say_pace(self) -> None:
        if self.tap is None:
            return
        counts = self.tap.counts()
        if counts.wall_time_s > 0:
            self.progress(
                f"Gazebo ran {counts.sim_time_s:.1f} s of sim time in {counts.wall_time_s:.1f} s "
                f"({counts.real_time_factor:.2f}x real time; {counts.fdm} state and "
                f"{counts.servo} motor packets relayed)"
            )

    def truth(self) -> Truth | None:
        reading = self.tap.reading() if self.tap is not None else None
        if reading is None:
            return None
        state = reading.state
        altitude_m = state.altitude_m
        if self._rest_altitude_m is None or altitude_m < self._rest_altitude_m:
            self._rest_altitude_m = altitude_m
        north, east, _down = state.position_ned_m
        return Truth(
            reading.state_at_s,
            altitude_m,
            -state.velocity_ned_m_s[2],
            tilt_deg(state.quaternion_wxyz),
            betaflight_attitude_deg(state.quaternion_wxyz),
            altitude_m <= self._rest_altitude_m + ON_GROUND_MARGIN_M,
            reading.motors,
            north,
            east,
        )

    def failure(self) -> str | None:
        error = self.tap.error if self.tap is not None else None
        return None if error is None else f"the Gazebo relay failed: {error!r}"
