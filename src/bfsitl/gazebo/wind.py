"""Gazebo's own wind, set while it flies: its WindEffects system through ``gz topic``.

The world bfsitl writes for a flight with a wind (:func:`bfsitl.gazebo.world.write_session_world`)
loads WindEffects and lets every link of the quad feel it; the wind is then changed by
publishing a ``gz.msgs.Wind`` on ``/world/<name>/wind``.  That topic carries one velocity:
a constant wind.  Gusts, and a wind for a world started without one, are refused with
:class:`~bfsitl.errors.DisturbanceUnavailableError`, saying what to do instead.
"""

from __future__ import annotations

import signal
from collections.abc import Callable, Mapping
from pathlib import Path

from bfsitl.errors import DisturbanceUnavailableError, GazeboError
from bfsitl.physics.frames import ned_to_enu
from bfsitl.physics.wind import Wind
from bfsitl.sitl.network import Network, ProcessHandle

#: ``gz topic -p`` discovers the subscriber, publishes once and exits within a second or two.
PUBLISH_TIMEOUT_S = 10.0


def wind_message(wind: Wind | None) -> str:
    """The ``gz.msgs.Wind`` text for ``wind`` (ENU, the world's frame; None is still air)."""
    east, north, up = ned_to_enu(wind.velocity_ned_m_s if wind is not None else (0.0, 0.0, 0.0))
    return f"linear_velocity: {{x: {east:.6f}, y: {north:.6f}, z: {up:.6f}}}, enable_wind: true"


class GazeboWind:
    """The wind of one running Gazebo world (see the module docstring)."""

    def __init__(
        self,
        spawn: Callable[[list[str], Path], ProcessHandle],
        gz: Path,
        world_name: str,
        log_dir: Path,
        started_with: Wind | None,
    ) -> None:
        self._spawn = spawn
        self._gz = gz
        self._topic = f"/world/{world_name}/wind"
        self._log = log_dir / "gazebo-wind.log"
        self._felt = started_with is not None
        self._wind = started_with

    @classmethod
    def in_network(
        cls,
        network: Network,
        env: Mapping[str, str],
        gz: Path,
        world_name: str,
        log_dir: Path,
        started_with: Wind | None,
    ) -> GazeboWind:
        def spawn(argv: list[str], log: Path) -> ProcessHandle:
            return network.spawn(argv, log_dir, log, env=env)

        return cls(spawn, gz, world_name, log_dir, started_with)

    @property
    def wind(self) -> Wind | None:
        return self._wind

    def set_wind(self, wind: Wind | None) -> None:
        if not self._felt:
            raise DisturbanceUnavailableError(
                "the wind cannot be disturbed with Gazebo's physics in a flight started "
                "without one: start it with a wind (--wind, or World(wind=Wind()) for still "
                "air) so that bfsitl's world loads WindEffects and the quad's links feel it"
            )
        if wind is not None and wind.gust_std_m_s > 0:
            raise DisturbanceUnavailableError(
                "gusts cannot be disturbed with Gazebo's physics: its wind topic sets a constant "
                "wind (give gust_std_m_s = 0, or use the embedded physics)"
            )
        process = self._spawn(
            [
                str(self._gz),
                "topic",
                "-t",
                self._topic,
                "-m",
                "gz.msgs.Wind",
                "-p",
                wind_message(wind),
            ],
            self._log,
        )
        code = process.wait(PUBLISH_TIMEOUT_S)
        if code != 0:
            process.signal_group(signal.SIGKILL)
            raise GazeboError(
                f"gz topic could not publish the wind on {self._topic} (exit "
                f"{'timeout' if code is None else code}); see {self._log}"
            )
        self._wind = wind


def wind_enu_m_s(wind: Wind) -> tuple[float, float, float]:
    """The world file's ``<wind><linear_velocity>`` for a flight started in ``wind``."""
    if wind.gust_std_m_s > 0:
        raise DisturbanceUnavailableError(
            "gusts cannot be disturbed with Gazebo's physics: its WindEffects is given one "
            "constant wind here (give gust_std_m_s = 0, or use the embedded physics)"
        )
    return ned_to_enu(wind.velocity_ned_m_s)
