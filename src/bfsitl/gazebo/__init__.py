"""Gazebo Harmonic as the physics of a Betaflight SITL, instead of the embedded simulator.

:mod:`.world` ships the IRIS + BetaflightPlugin world (package data); :mod:`.launcher` finds
``gz`` and the plugin and plans the server command; :mod:`.supervise` waits for the plugin
and stops the server.  The usage is in the :mod:`.launcher` docstring and docs/gazebo.md.
"""

from bfsitl.gazebo.launcher import (
    GazeboInstall,
    GazeboLaunch,
    check_gazebo,
    plan_gazebo_launch,
)
from bfsitl.gazebo.supervise import (
    check_plugin_port_free,
    plugin_listening,
    stop_gazebo,
    wait_for_plugin,
)
from bfsitl.gazebo.world import DEFAULT_WORLD, PLUGIN_LIBRARY, WORLD_NAME, world_path

__all__ = [
    "DEFAULT_WORLD",
    "PLUGIN_LIBRARY",
    "WORLD_NAME",
    "GazeboInstall",
    "GazeboLaunch",
    "check_gazebo",
    "check_plugin_port_free",
    "plan_gazebo_launch",
    "plugin_listening",
    "stop_gazebo",
    "wait_for_plugin",
    "world_path",
]
