"""The Gazebo launcher without Gazebo: a fake ``gz`` on a temporary PATH, a fake plugin file.

Checks the clear errors for a missing ``gz`` or plugin, the exact command and environment of
the plan, and that the plan runs through the same spawner as the SITL (host network and a
private namespace), where a stand-in ``gz`` binds the plugin's UDP 9002 and is stopped again.
"""

from __future__ import annotations

import json
import os
import signal
import stat
import sys
import textwrap
import time
from pathlib import Path

import pytest
from support.fake_processes import FakeGazebo

from bfsitl.errors import (
    BfsitlError,
    GazeboNotFoundError,
    GazeboPluginNotFoundError,
    GazeboStartError,
    PortInUseError,
)
from bfsitl.gazebo import (
    GazeboLaunch,
    check_gazebo,
    check_plugin_port_free,
    plan_gazebo_launch,
    plugin_listening,
    stop_gazebo,
    wait_for_plugin,
)
from bfsitl.gazebo.launcher import prepend_search_path, split_search_path
from bfsitl.gazebo.world import PLUGIN_LIBRARY, WORLDS_DIR, world_path
from bfsitl.sitl.network import HostNetwork, IsolatedNetwork, unshare_available

#: A stand-in for `gz`: records its argv and the Gazebo variables, binds UDP 9002 like the
#: plugin when BIND=1, and exits 0 on SIGINT as gz does.
FAKE_GZ = textwrap.dedent("""\
    #!{python}
    import json, os, signal, socket, sys, time
    names = ("GZ_SIM_SYSTEM_PLUGIN_PATH", "GZ_SIM_RESOURCE_PATH", "GZ_IP", "GZ_PARTITION",
             "MARKER")
    record = {{"argv": sys.argv[1:], "env": {{n: os.environ.get(n) for n in names}}}}
    with open(os.environ["RECORD"], "w") as out:
        json.dump(record, out)
    signal.signal(signal.SIGINT, lambda *_: sys.exit(0))
    if os.environ.get("BIND") == "1":
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 9002))
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            time.sleep(0.05)
""")


@pytest.fixture
def gz_bin(tmp_path: Path) -> Path:
    """A folder holding an executable fake `gz`."""
    folder = tmp_path / "bin"
    folder.mkdir()
    gz = folder / "gz"
    gz.write_text(FAKE_GZ.format(python=sys.executable))
    gz.chmod(gz.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    return folder


@pytest.fixture
def plugin_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "plugin-build"
    folder.mkdir()
    (folder / PLUGIN_LIBRARY).write_bytes(b"\x7fELF fake")
    return folder


def test_check_finds_gz_on_path_and_the_plugin_on_the_plugin_path(
    gz_bin: Path, plugin_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PATH", str(gz_bin))
    monkeypatch.setenv(
        "GZ_SIM_SYSTEM_PLUGIN_PATH", os.pathsep.join([str(tmp_path / "elsewhere"), str(plugin_dir)])
    )
    found = check_gazebo()
    assert found.gz == gz_bin / "gz"
    assert found.plugin_library == (plugin_dir / PLUGIN_LIBRARY).resolve()
    assert found.plugin_dir == plugin_dir.resolve()


def test_missing_gz_says_how_to_install_harmonic(
    tmp_path: Path, plugin_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setenv("PATH", str(empty))
    with pytest.raises(GazeboNotFoundError) as caught:
        check_gazebo(plugin_dir)
    message = str(caught.value)
    assert not isinstance(caught.value, GazeboPluginNotFoundError)
    assert isinstance(caught.value, BfsitlError)
    assert "`gz`" in message and "gz-harmonic" in message and "docs/gazebo.md" in message


def test_a_non_executable_gz_does_not_count(
    gz_bin: Path, plugin_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (gz_bin / "gz").chmod(0o644)
    monkeypatch.setenv("PATH", str(gz_bin))
    with pytest.raises(GazeboNotFoundError):
        check_gazebo(plugin_dir)


def test_missing_plugin_says_where_it_looked_and_how_to_build_it(
    gz_bin: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PATH", str(gz_bin))
    monkeypatch.delenv("GZ_SIM_SYSTEM_PLUGIN_PATH", raising=False)
    with pytest.raises(GazeboPluginNotFoundError) as unset:
        check_gazebo()
    assert "GZ_SIM_SYSTEM_PLUGIN_PATH (not set)" in str(unset.value)
    for hint in (PLUGIN_LIBRARY, "gz-sim8", "gz-transport13", "--gz-plugin-dir", "docs/gazebo.md"):
        assert hint in str(unset.value), hint

    searched = tmp_path / "no-plugin-here"
    searched.mkdir()
    monkeypatch.setenv("GZ_SIM_SYSTEM_PLUGIN_PATH", str(searched))
    with pytest.raises(GazeboPluginNotFoundError, match=str(searched)):
        check_gazebo()


def test_an_explicit_plugin_dir_must_hold_the_plugin(
    gz_bin: Path, plugin_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--gz-plugin-dir names the build to use: no silent fallback to the search path."""
    monkeypatch.setenv("PATH", str(gz_bin))
    monkeypatch.setenv("GZ_SIM_SYSTEM_PLUGIN_PATH", str(plugin_dir))
    wrong = tmp_path / "wrong-build"
    wrong.mkdir()
    with pytest.raises(GazeboPluginNotFoundError, match="--gz-plugin-dir"):
        check_gazebo(wrong)
    # The library file itself is accepted as well as its folder.
    library = plugin_dir / PLUGIN_LIBRARY
    assert check_gazebo(library).plugin_library == library.resolve()


def test_plan_builds_the_headless_server_command(
    gz_bin: Path, plugin_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PATH", str(gz_bin))
    launch = plan_gazebo_launch(plugin_dir=plugin_dir)
    assert isinstance(launch, GazeboLaunch)
    assert launch.argv == (str(gz_bin / "gz"), "sim", "-s", "-r", str(world_path()))
    assert launch.world_path == world_path()
    assert launch.plugin_library == (plugin_dir / PLUGIN_LIBRARY).resolve()
    verbose_gui = plan_gazebo_launch(plugin_dir=plugin_dir, headless=False, run=False, verbosity=4)
    assert verbose_gui.argv[1:] == ("sim", "-v", "4", str(world_path()))
    with pytest.raises(ValueError):
        plan_gazebo_launch(plugin_dir=plugin_dir, verbosity=9)


def test_plan_environment_puts_our_folders_first_and_keeps_the_rest(
    gz_bin: Path, plugin_dir: Path, tmp_path: Path
) -> None:
    models = tmp_path / "models"
    base = {
        "PATH": str(gz_bin),
        "HOME": "/home/pilot",
        "GZ_SIM_SYSTEM_PLUGIN_PATH": os.pathsep.join(["/opt/other", str(plugin_dir.resolve())]),
        "GZ_SIM_RESOURCE_PATH": "/opt/models",
    }
    launch = plan_gazebo_launch(
        plugin_dir=plugin_dir, resource_dirs=[models], env=base, partition="bfsitl-1"
    )
    env = launch.env
    assert split_search_path(env["GZ_SIM_SYSTEM_PLUGIN_PATH"]) == [
        str(plugin_dir.resolve()),
        "/opt/other",
    ]  # first, and not twice
    assert split_search_path(env["GZ_SIM_RESOURCE_PATH"]) == [
        str(WORLDS_DIR),
        str(models),
        "/opt/models",
    ]
    assert env["GZ_IP"] == "127.0.0.1"
    assert env["GZ_PARTITION"] == "bfsitl-1"
    # The complete environment: a namespace spawner replaces the child's environment.
    assert env["HOME"] == "/home/pilot" and env["PATH"] == str(gz_bin)
    assert base["GZ_SIM_RESOURCE_PATH"] == "/opt/models"  # the input is not modified
    with pytest.raises(TypeError):
        launch.env["GZ_IP"] = "10.0.0.1"  # type: ignore[index]
    copy = launch.env_dict()
    copy["GZ_IP"] = "10.0.0.1"
    assert launch.env["GZ_IP"] == "127.0.0.1"
    shown = launch.command_line()
    assert shown.startswith("GZ_SIM_SYSTEM_PLUGIN_PATH=") and shown.endswith(
        f"sim -s -r {world_path()}"
    )


def test_plan_keeps_a_chosen_transport_interface_and_takes_a_world_file(
    gz_bin: Path, plugin_dir: Path, tmp_path: Path
) -> None:
    custom = tmp_path / "worlds" / "field.sdf"
    custom.parent.mkdir()
    custom.write_text("<sdf/>")
    launch = plan_gazebo_launch(
        custom, plugin_dir=plugin_dir, env={"PATH": str(gz_bin), "GZ_IP": "192.168.1.5"}
    )
    assert launch.env["GZ_IP"] == "192.168.1.5"
    assert launch.argv[-1] == str(custom.resolve())
    assert split_search_path(launch.env["GZ_SIM_RESOURCE_PATH"])[0] == str(custom.parent)
    with pytest.raises(BfsitlError):
        plan_gazebo_launch(
            tmp_path / "missing.sdf", plugin_dir=plugin_dir, env={"PATH": str(gz_bin)}
        )


def test_search_path_helpers() -> None:
    joined = prepend_search_path(os.pathsep.join(["", "/b", "/a", ""]), ["/a", "/c"])
    assert split_search_path(joined) == ["/a", "/c", "/b"]
    assert split_search_path(None) == [] and prepend_search_path(None, []) == ""


# --- through the SITL's spawner ----------------------------------------------------------------


def read_record(path: Path, timeout_s: float = 10.0) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if path.exists() and path.stat().st_size:
            return json.loads(path.read_text())
        time.sleep(0.02)
    raise AssertionError("the fake gz never ran")


def test_the_plan_runs_through_the_host_spawner(
    gz_bin: Path, plugin_dir: Path, tmp_path: Path
) -> None:
    record = tmp_path / "record.json"
    env = {**os.environ, "PATH": str(gz_bin), "RECORD": str(record), "MARKER": "host"}
    launch = plan_gazebo_launch(plugin_dir=plugin_dir, env=env)
    handle = HostNetwork().spawn(
        launch.argv, tmp_path, tmp_path / "gazebo.log", env=launch.env_dict()
    )
    try:
        seen = read_record(record)
        assert handle.wait(10.0) == 0
    finally:
        stop_gazebo(handle, grace_s=1.0)
    assert seen["argv"] == ["sim", "-s", "-r", str(world_path())]
    assert seen["env"]["MARKER"] == "host"
    assert seen["env"]["GZ_IP"] == "127.0.0.1"
    assert split_search_path(seen["env"]["GZ_SIM_SYSTEM_PLUGIN_PATH"])[0] == str(
        plugin_dir.resolve()
    )


@pytest.mark.skipif(not unshare_available(), reason="unshare (util-linux) is missing")
def test_the_plan_runs_in_a_private_namespace_and_is_seen_listening(
    gz_bin: Path, plugin_dir: Path, tmp_path: Path
) -> None:
    """In the SITL's kind of namespace: env arrives, UDP 9002 shows, SIGINT stops it."""
    record = tmp_path / "record.json"
    env = {**os.environ, "PATH": str(gz_bin), "RECORD": str(record), "MARKER": "netns", "BIND": "1"}
    launch = plan_gazebo_launch(plugin_dir=plugin_dir, env=env)
    with IsolatedNetwork() as network:
        assert not plugin_listening(network.netns_pid)
        check_plugin_port_free(network)
        handle = network.spawn(
            launch.argv, tmp_path, tmp_path / "gazebo.log", env=launch.env_dict()
        )
        try:
            wait_for_plugin(network, handle, timeout_s=20.0, poll_s=0.02)
            assert plugin_listening(network.netns_pid)
            with pytest.raises(PortInUseError, match="9002"):
                check_plugin_port_free(network)  # a second Gazebo would be refused
            assert read_record(record)["env"]["MARKER"] == "netns"
        finally:
            code = stop_gazebo(handle, grace_s=5.0)
        assert code == 0  # ended by SIGINT, the first and gentlest signal


# --- waiting and stopping, with fakes ----------------------------------------------------------

UDP_HEADER = (
    "  sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid"
    "  timeout inode ref pointer drops\n"
)


def udp_row(port: int) -> str:
    return (
        f"  12: 0100007F:{port:04X} 00000000:0000 07 00000000:00000000 00:00000000 "
        f"00000000  1000        0 4242 2 0000000000000000 0\n"
    )


class FakeNetwork:
    def __init__(self, proc_root: Path, pid: int = 4242) -> None:
        self.netns_pid = pid
        self.isolated = True
        self.udp = proc_root / str(pid) / "net" / "udp"
        self.udp.parent.mkdir(parents=True)
        self.udp.write_text(UDP_HEADER)


class StepClock:
    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s

    def sleep(self, seconds: float) -> None:
        self.now_s += seconds


def test_wait_for_plugin_returns_when_the_port_appears(tmp_path: Path) -> None:
    network = FakeNetwork(tmp_path)
    clock = StepClock()
    polls: list[float] = []

    def sleep(seconds: float) -> None:
        polls.append(clock.now_s)
        clock.sleep(seconds)
        if len(polls) == 3:  # the plugin binds 9002 during the third wait
            network.udp.write_text(UDP_HEADER + udp_row(9003) + udp_row(9002))

    wait_for_plugin(
        network,
        FakeGazebo(),
        timeout_s=10.0,
        poll_s=0.5,
        proc_root=tmp_path,
        clock=clock,
        sleep=sleep,
    )
    assert len(polls) == 3


def test_wait_for_plugin_fails_clearly_when_gz_exits_or_times_out(tmp_path: Path) -> None:
    network = FakeNetwork(tmp_path)
    network.udp.write_text(UDP_HEADER + udp_row(9003))  # someone else's port does not count
    with pytest.raises(GazeboStartError, match="exited with code 255"):
        wait_for_plugin(
            network,
            FakeGazebo(code=255),
            proc_root=tmp_path,
            clock=StepClock(),
            sleep=lambda s: None,
        )
    clock = StepClock()
    with pytest.raises(GazeboStartError, match="within 2 s"):
        wait_for_plugin(
            network,
            FakeGazebo(),
            timeout_s=2.0,
            poll_s=0.5,
            proc_root=tmp_path,
            clock=clock,
            sleep=clock.sleep,
        )
    assert clock.now_s == pytest.approx(2.0)


def test_stop_gazebo_escalates_only_as_far_as_needed() -> None:
    polite = FakeGazebo(exit_after=1)
    assert stop_gazebo(polite, grace_s=0.0) == -signal.SIGINT
    assert polite.signals == [signal.SIGINT]
    stubborn = FakeGazebo(exit_after=3)
    stop_gazebo(stubborn, grace_s=0.0)
    assert stubborn.signals == [signal.SIGINT, signal.SIGTERM, signal.SIGKILL]
    gone = FakeGazebo(code=0)
    assert stop_gazebo(gone) == 0 and gone.signals == []
