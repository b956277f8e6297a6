"""The boot-time scheduler lock-out check of SitlProcess (the real case is in the integration
tests' starts; the stall that causes it cannot be provoked reliably without stopping the SITL
at the right 100 us, so the decision itself is tested here)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

import bfsitl.sitl.process as process
from bfsitl.errors import SitlLockedOutError, SitlNotReadyError
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE
from bfsitl.sitl.process import SitlHooks, SitlProcess


class StubClient:
    """MSP_STATUS answers with these cycle times, the last one repeated."""

    def __init__(self, *cycle_times_us: int) -> None:
        self.cycle_times_us = list(cycle_times_us)
        self.asked = 0

    def status(self) -> SimpleNamespace:
        self.asked += 1
        value = (
            self.cycle_times_us.pop(0) if len(self.cycle_times_us) > 1 else self.cycle_times_us[0]
        )
        return SimpleNamespace(cycle_time_us=value)


def bare_process() -> SitlProcess:
    sitl = SitlProcess.__new__(SitlProcess)  # no binary needed to judge the answers
    sitl._process = None  # type: ignore[attr-defined]
    sitl.hooks = SitlHooks()
    return sitl


def test_a_running_pid_loop_passes_at_once():
    client = StubClient(125)
    bare_process()._check_pid_loop(client)  # type: ignore[arg-type]
    assert client.asked == 1


def test_a_pid_loop_that_starts_a_little_late_passes():
    client = StubClient(0, 0, 125)
    bare_process()._check_pid_loop(client)  # type: ignore[arg-type]
    assert client.asked == 3


def test_a_locked_out_pid_loop_is_named(monkeypatch):
    monkeypatch.setattr(process, "PID_LOOP_TIMEOUT_S", 0.12)
    with pytest.raises(SitlLockedOutError, match="locked them out") as caught:
        bare_process()._check_pid_loop(StubClient(0))  # type: ignore[arg-type]
    # A kind of "not ready": callers that handle that handle this too.
    assert isinstance(caught.value, SitlNotReadyError)


class StubNetwork:
    """Spawns nothing; counts the launches a start asked for."""

    netns_pid = None
    isolated = True

    def __init__(self) -> None:
        self.spawned = 0

    def spawn(self, *_args: object, **_kwargs: object) -> None:
        self.spawned += 1


def startable(clients: list[StubClient], monkeypatch, tmp_path) -> SitlProcess:
    """A SitlProcess whose launches answer MSP with ``clients`` in turn."""
    sitl = bare_process()
    sitl.network = StubNetwork()  # type: ignore[assignment]
    sitl.firmware = SimpleNamespace(command=lambda: ["sitl"], path=SimpleNamespace(name="sitl"))
    sitl.workdir, sitl.log_path, sitl.timer_slack_ns = tmp_path, tmp_path / "sitl.log", None
    sitl.env = None
    sitl.ready_timeout_s, sitl.starts, sitl.launches = 1.0, 0, 0
    sitl.said = []  # type: ignore[attr-defined]
    sitl._progress = sitl.said.append  # type: ignore[attr-defined]
    sitl._terminate = lambda: None  # type: ignore[attr-defined]
    sitl.build_options = lambda: None  # type: ignore[method-assign]
    sitl._wait_ready = lambda _timeout_s, _check: clients.pop(0)  # type: ignore[attr-defined]
    monkeypatch.setattr(process, "check_ports_free", lambda *_args, **_kwargs: None)
    monkeypatch.setattr(process, "PID_LOOP_TIMEOUT_S", 0.05)
    monkeypatch.setattr(process, "_RETRY_WAIT_S", 0.001)
    monkeypatch.setattr(process, "detect_profile", lambda _client, _build, **_kw: DEFAULT_PROFILE)
    return sitl


def test_a_locked_out_launch_is_retried_and_counts_as_a_launch_not_a_start(monkeypatch, tmp_path):
    sitl = startable([StubClient(0), StubClient(125)], monkeypatch, tmp_path)
    sitl.start()
    # Tests and callers count starts to see reboots; a retried launch must not look like one.
    assert (sitl.starts, sitl.launches, sitl.network.spawned) == (1, 2, 2)
    assert any("lock-out" in line and "starting again" in line for line in sitl.said)


def test_a_launch_locked_out_every_time_is_reported(monkeypatch, tmp_path):
    locked_out = [StubClient(0) for _ in range(process._START_ATTEMPTS)]
    sitl = startable(locked_out, monkeypatch, tmp_path)
    with pytest.raises(
        SitlLockedOutError, match="launches in a row failed at boot.*load average.*--lockstep"
    ):
        sitl.start()
    assert (sitl.starts, sitl.launches) == (0, process._START_ATTEMPTS)
    # Each retry said why, how busy the machine was, and how long it waits.
    retries = [line for line in sitl.said if "starting again in" in line]
    assert len(retries) == process._START_ATTEMPTS - 1
    assert all("load average" in line for line in retries)


def test_retries_wait_longer_each_time_up_to_a_cap():
    waits = [process._retry_wait_s(attempt) for attempt in range(1, process._START_ATTEMPTS)]
    assert waits[0] == process._RETRY_WAIT_S
    assert all(b >= a for a, b in zip(waits, waits[1:], strict=False))
    assert waits[1] == 2 * waits[0]
    assert max(waits) == process._RETRY_WAIT_MAX_S
    # Long enough to outlast a busy spell of a few seconds, short enough to be a start.
    assert 5.0 <= sum(waits) <= 15.0
