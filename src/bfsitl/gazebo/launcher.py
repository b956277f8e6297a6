"""Find Gazebo Harmonic and the BetaflightPlugin, and plan the ``gz sim`` server command.

Nothing here starts a process: :func:`plan_gazebo_launch` returns a :class:`GazeboLaunch`
(argv, complete environment, world file) that the caller hands to the same spawner that runs
the SITL, so Gazebo lands in the SITL's network namespace.  That matters because both ends
of the physics link use fixed loopback ports (the SITL sends motors to 127.0.0.1:9002, the
plugin sends state to 127.0.0.1:9003): they must share one network, and an isolated SITL's
network is only reachable from inside its namespace.

Wiring ``bfsitl fly --physics gazebo`` (the intended use)::

    from bfsitl.gazebo import (check_plugin_port_free, plan_gazebo_launch, stop_gazebo,
                               wait_for_plugin)

    launch = plan_gazebo_launch(plugin_dir=args.gz_plugin_dir)  # fails early, with the fix
    sitl = SitlProcess(args.firmware, workdir=args.workdir, isolate=True)
    network = sitl.prepare_network()            # the namespace exists before the SITL does
    check_plugin_port_free(network)             # nothing else holds UDP 9002 in it
    gz = network.spawn(launch.argv, sitl.workdir, sitl.workdir / "gazebo.log",
                       env=launch.env_dict())
    try:
        wait_for_plugin(network, gz)            # UDP 9002 bound: the plugin has loaded
        sitl.start()                            # its boot servo_packet reaches the plugin
        ...                                     # RC on UDP 9004, provisioning, the mission;
                                                # no embedded SitlBridge (Gazebo is the physics)
    finally:
        stop_gazebo(gz)                         # SIGINT first: gz shuts down cleanly
        sitl.stop()                             # closes the namespace; ends anything left

``env`` is the *complete* environment for the child (the caller's environment plus the
Gazebo variables), because a namespace spawner replaces the environment rather than adding to
it.  The plan sets ``GZ_IP=127.0.0.1`` unless the caller set it: a fresh namespace has only a
loopback interface, which gz-transport does not pick by itself.

Timing caveat (docs/firmware-facts.md#sim-clock): the plugin stamps fdm packets with sim
time, and stock 4.6.0 SITL then runs its clock faster than sim time (2.9x-8.8x measured on a
2-core VM).  The embedded physics avoids that; Gazebo is for parity with the tutorial and
for worlds the embedded physics cannot model.
"""

from __future__ import annotations

import os
import shlex
import shutil
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

from bfsitl.errors import GazeboNotFoundError, GazeboPluginNotFoundError
from bfsitl.gazebo.install_hints import BUILD_HINT, INSTALL_HINT
from bfsitl.gazebo.world import DEFAULT_WORLD, PLUGIN_LIBRARY, world_path

#: Where ``gz sim`` (gz-sim 8) looks for system plugins and for models/worlds.
PLUGIN_PATH_VAR = "GZ_SIM_SYSTEM_PLUGIN_PATH"
RESOURCE_PATH_VAR = "GZ_SIM_RESOURCE_PATH"
#: gz-transport's interface choice; loopback inside a private namespace.
TRANSPORT_IP_VAR = "GZ_IP"
TRANSPORT_IP = "127.0.0.1"
#: Keeps the topics of one Gazebo apart from another's on a shared network.
PARTITION_VAR = "GZ_PARTITION"


@dataclass(frozen=True, slots=True)
class GazeboInstall:
    """The two things found on this machine: the ``gz`` command and the plugin library."""

    gz: Path
    plugin_library: Path

    @property
    def plugin_dir(self) -> Path:
        return self.plugin_library.parent


@dataclass(frozen=True, slots=True)
class GazeboLaunch:
    """How to start the Gazebo server: pass ``argv`` and ``env_dict()`` to a spawner."""

    argv: tuple[str, ...]
    #: The complete environment of the child (read-only view).
    env: Mapping[str, str]
    world_path: Path
    plugin_library: Path

    def env_dict(self) -> dict[str, str]:
        """A plain copy of :attr:`env`, as ``Network.spawn(env=...)`` and Popen take it."""
        return dict(self.env)

    def command_line(self) -> str:
        """The command as a shell would run it, with the Gazebo variables, for logs and docs."""
        variables = [
            f"{name}={shlex.quote(self.env[name])}"
            for name in (PLUGIN_PATH_VAR, RESOURCE_PATH_VAR, TRANSPORT_IP_VAR, PARTITION_VAR)
            if name in self.env
        ]
        return " ".join([*variables, *map(shlex.quote, self.argv)])


def split_search_path(value: str | None) -> list[str]:
    """Entries of a PATH-like variable, empty entries dropped."""
    return [entry for entry in (value or "").split(os.pathsep) if entry]


def prepend_search_path(value: str | None, first: Iterable[Path | str]) -> str:
    """``first`` ahead of the existing entries, each entry once (the first occurrence wins)."""
    entries: list[str] = []
    for entry in [*map(str, first), *split_search_path(value)]:
        if entry not in entries:
            entries.append(entry)
    return os.pathsep.join(entries)


def find_gz(env: Mapping[str, str] | None = None) -> Path:
    """The ``gz`` command on ``env``'s PATH (default: this process's)."""
    env = os.environ if env is None else env
    found = shutil.which("gz", path=env.get("PATH", os.defpath))
    if found is None:
        raise GazeboNotFoundError(f"Gazebo's `gz` command is not on PATH. {INSTALL_HINT}")
    return Path(found)


def find_plugin(plugin_dir: str | Path | None = None, env: Mapping[str, str] | None = None) -> Path:
    """The BetaflightPlugin library: in ``plugin_dir`` if given, else on the plugin path.

    ``plugin_dir`` may also name the library file itself.  An explicit directory that does not
    hold it is an error even when the search path would: the user asked for that build.
    """
    env = os.environ if env is None else env
    if plugin_dir is not None:
        given = Path(plugin_dir).expanduser()
        candidate = given if given.is_file() else given / PLUGIN_LIBRARY
        if candidate.is_file():
            return candidate.resolve()
        raise GazeboPluginNotFoundError(
            f"{PLUGIN_LIBRARY} is not in --gz-plugin-dir {given}. {BUILD_HINT}"
        )
    searched = split_search_path(env.get(PLUGIN_PATH_VAR))
    for entry in searched:
        candidate = Path(entry) / PLUGIN_LIBRARY
        if candidate.is_file():
            return candidate.resolve()
    where = (
        f"{PLUGIN_PATH_VAR} ({os.pathsep.join(searched)})"
        if searched
        else f"{PLUGIN_PATH_VAR} (not set)"
    )
    raise GazeboPluginNotFoundError(f"{PLUGIN_LIBRARY} was not found on {where}. {BUILD_HINT}")


def check_gazebo(
    plugin_dir: str | Path | None = None, *, env: Mapping[str, str] | None = None
) -> GazeboInstall:
    """Both parts Gazebo needs here, or a :class:`GazeboNotFoundError` that says how to get
    them.  ``gz`` is checked first: without it the plugin is of no use."""
    return GazeboInstall(find_gz(env), find_plugin(plugin_dir, env))


def plan_gazebo_launch(
    world: str | Path = DEFAULT_WORLD,
    *,
    plugin_dir: str | Path | None = None,
    resource_dirs: Iterable[str | Path] = (),
    headless: bool = True,
    run: bool = True,
    verbosity: int | None = None,
    partition: str | None = None,
    env: Mapping[str, str] | None = None,
    install: GazeboInstall | None = None,
) -> GazeboLaunch:
    """The ``gz sim`` command and environment for ``world`` (a shipped name or an SDF path).

    ``headless`` adds ``-s`` (server only, no GUI), ``run`` adds ``-r`` (start unpaused: the
    plugin only talks to the SITL while the simulation runs).  ``resource_dirs`` are extra
    model folders; ``env`` is the environment to start from (default: this process's).
    """
    base = dict(os.environ if env is None else env)
    install = install or check_gazebo(plugin_dir, env=base)
    world_file = world_path(world)
    child_env = dict(base)
    child_env[PLUGIN_PATH_VAR] = prepend_search_path(
        base.get(PLUGIN_PATH_VAR), [install.plugin_dir]
    )
    child_env[RESOURCE_PATH_VAR] = prepend_search_path(
        base.get(RESOURCE_PATH_VAR), [world_file.parent, *(Path(d) for d in resource_dirs)]
    )
    child_env.setdefault(TRANSPORT_IP_VAR, TRANSPORT_IP)
    if partition is not None:
        child_env[PARTITION_VAR] = partition
    argv = [str(install.gz), "sim"]
    if headless:
        argv.append("-s")
    if run:
        argv.append("-r")
    if verbosity is not None:
        if not 0 <= verbosity <= 4:
            raise ValueError(f"gz verbosity is 0..4, got {verbosity}")
        argv += ["-v", str(verbosity)]
    argv.append(str(world_file))
    return GazeboLaunch(
        tuple(argv), MappingProxyType(child_env), world_file, install.plugin_library
    )
