"""Gazebo Harmonic's physics under a stock SITL: ``gz sim`` with the BetaflightPlugin.

Gazebo starts first and must have bound UDP 9002 before the SITL boots, as in the tutorial;
both live in the SITL's network namespace because both ends use fixed loopback ports.  Time
is the wall clock, the truth is Gazebo's and unknown here, and RC (over UDP) is the only
thing bfsitl can disturb.
"""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

from bfsitl.backend.base import SitlBackend
from bfsitl.fc.firmware_detect import profile_of_binary

if TYPE_CHECKING:
    from collections.abc import Callable

    from bfsitl.gazebo.launcher import GazeboInstall
    from bfsitl.sitl.process import SitlProcess


class GazeboBackend(SitlBackend):
    """See the module docstring."""

    name: ClassVar[str] = "Gazebo's physics"

    def __init__(self, plugin_dir: str | Path | None, *, progress: Callable[[str], None]) -> None:
        from bfsitl.gazebo import check_gazebo

        super().__init__()
        self.progress = progress
        # Fails early, with the fix, before any SITL starts.
        self.install: GazeboInstall = check_gazebo(plugin_dir)

    def start(self, sitl: SitlProcess, stack: ExitStack) -> None:
        from bfsitl.gazebo import (
            check_plugin_port_free,
            plan_gazebo_launch,
            stop_gazebo,
            wait_for_plugin,
        )
        from bfsitl.gazebo.world import world_for_profile

        stack.callback(sitl.stop)  # runs last: after Gazebo has stopped
        # Gazebo starts before the SITL can say who it is: the binary's profile (its build
        # record, else its bytes) picks the world's frame transform and motor channels.
        world = world_for_profile(profile_of_binary(sitl.firmware.path), sitl.workdir)
        launch = plan_gazebo_launch(world, install=self.install)
        network = sitl.prepare_network()
        check_plugin_port_free(network)
        self.progress(f"starting Gazebo: {launch.command_line()}")
        gazebo = network.spawn(
            launch.argv, sitl.workdir, sitl.workdir / "gazebo.log", env=launch.env_dict()
        )
        stack.callback(stop_gazebo, gazebo)
        wait_for_plugin(network, gazebo)
        sitl.start()
