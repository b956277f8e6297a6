"""TelemetryPoller on a thread, against the in-memory FC of tests/support/fake_fc.py.

Rates are checked with loose bounds: this is about the poller's logic (pacing, sequence numbers,
error accounting, shutdown), not a benchmark.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Iterator

import pytest
from support.fake_fc import FakeFcLink, multiple_msp, telemetry_link  # noqa: E402

from bfsitl.errors import LinkClosedError  # noqa: E402
from bfsitl.fc.msp_client import MspClient, Telemetry  # noqa: E402
from bfsitl.fc.telemetry_poller import TelemetryPoller  # noqa: E402
from bfsitl.protocol import messages as msg  # noqa: E402
from bfsitl.protocol.arming import ArmingFlag  # noqa: E402
from bfsitl.protocol.boxes import SITL_DEFAULT_BOX_IDS  # noqa: E402
from bfsitl.protocol.msp_codes import MspCommand  # noqa: E402
from bfsitl.protocol.msp_frame import MspFrame  # noqa: E402

THREAD_NAME = "bfsitl-telemetry"

#: A disarmed SITL before RC and fdm: RXLOSS and ANGLE block arming, ANGLE mode is on.
IDLE_STATUS = msg.StatusEx(
    cycle_time_us=125,
    i2c_errors=0,
    sensors_mask=0x23,
    flight_mode_flags=0b10,
    pid_profile=0,
    cpu_load_percent=5,
    pid_profile_count=4,
    rate_profile_index=0,
    arming_disable_flag_count=29,
    arming_disable_flags=ArmingFlag.RX_FAILSAFE.mask | ArmingFlag.ANGLE.mask,
    config_state=0,
    cpu_temp_c=0,
    rate_profile_count=4,
)


def make_link() -> FakeFcLink:
    link = telemetry_link(
        attitude=msg.Attitude(0, 0, 0),
        altitude=msg.Altitude(100, 0),
        status=IDLE_STATUS,
        analog=msg.Analog(126, 0, 0, 0, 1260),
        rc=msg.Rc((1500, 1500, 1500, 1000)),
        motor=msg.Motor((1000, 1000, 1000, 1000)),
        imu=msg.RawImu((0, 0, 256), (0, 0, 0), (0, 0, 0)),
        box_ids=SITL_DEFAULT_BOX_IDS,
    )
    # Yaw counts the attitude reads, so every snapshot is distinguishable.
    counter = itertools.count(1)
    link.handlers[MspCommand.ATTITUDE] = lambda _request: msg.Attitude(
        0, 0, next(counter) % 360
    ).encode()
    return link


def make_poller(rate_hz: float | None, link: FakeFcLink | None = None) -> TelemetryPoller:
    link = link or make_link()
    return TelemetryPoller(MspClient(link, timeout_s=0.1), rate_hz=rate_hz)


def poller_threads() -> set[threading.Thread]:
    return {t for t in threading.enumerate() if t.name == THREAD_NAME}


@pytest.fixture
def running() -> Iterator[list[TelemetryPoller]]:
    """Collects pollers a test starts and stops them even when the test fails."""
    pollers: list[TelemetryPoller] = []
    yield pollers
    for poller in pollers:
        poller.stop()


def wait_until(predicate: object, timeout_s: float = 2.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():  # type: ignore[operator]
            return True
        time.sleep(0.005)
    return False


def test_free_running_poller_publishes_increasing_sequence(
    running: list[TelemetryPoller],
) -> None:
    """At rate None snapshots keep arriving, each with a higher sequence number."""
    poller = make_poller(None).start()
    running.append(poller)
    first = poller.wait_next(0, timeout_s=2.0)
    assert isinstance(first, Telemetry)
    seen = [poller.sequence]
    for _ in range(3):
        assert poller.wait_next(seen[-1], timeout_s=2.0) is not None
        seen.append(poller.sequence)
    assert seen == sorted(seen) and len(set(seen)) == len(seen)
    latest = poller.latest()
    assert latest is not None
    assert latest.status == IDLE_STATUS
    assert latest.flight_modes == ("ANGLE",)
    assert latest.arming_blockers == ("RXLOSS", "ANGLE")


def test_wait_next_returns_a_newer_snapshot(running: list[TelemetryPoller]) -> None:
    """wait_next(n) blocks until a snapshot after sequence n, and returns that newer one."""
    poller = make_poller(50.0).start()
    running.append(poller)
    first = poller.wait_next(0, timeout_s=2.0)
    assert first is not None
    second = poller.wait_next(poller.sequence, timeout_s=2.0)
    assert second is not None
    assert second.attitude.yaw_deg > first.attitude.yaw_deg
    assert second.received_at_s > first.received_at_s


def test_wait_next_times_out_with_none_when_nothing_new() -> None:
    """Without a running poller no snapshot comes: wait_next returns None after its timeout."""
    poller = make_poller(50.0)
    start = time.monotonic()
    assert poller.wait_next(0, timeout_s=0.05) is None
    assert time.monotonic() - start >= 0.04


def test_fixed_rate_gives_about_the_requested_count(running: list[TelemetryPoller]) -> None:
    """20 Hz for 0.5 s gives about 10 snapshots (loose bounds), not as many as the FC allows."""
    poller = make_poller(20.0).start()
    running.append(poller)
    time.sleep(0.5)
    poller.stop()
    updates = poller.stats().updates
    assert 5 <= updates <= 15, updates


def test_link_closed_by_peer_sets_fatal_error_and_stops(running: list[TelemetryPoller]) -> None:
    """When the FC closes the connection the poller records LinkClosedError and ends."""
    link = make_link()
    before = poller_threads()
    poller = make_poller(None, link).start()
    running.append(poller)
    (thread,) = poller_threads() - before
    assert poller.wait_next(0, timeout_s=2.0) is not None
    link.closed_by_peer = True
    assert wait_until(lambda: poller.fatal_error is not None)
    assert isinstance(poller.fatal_error, LinkClosedError)
    thread.join(timeout=1.0)
    assert not thread.is_alive()
    assert poller.stats().last_error is not None
    count = poller.sequence
    time.sleep(0.05)
    assert poller.sequence == count


def test_wait_next_returns_promptly_when_the_poller_dies(
    running: list[TelemetryPoller],
) -> None:
    """A controller blocked in wait_next learns at once that the poller is gone, and so does
    a later call.

    Regression: the wait predicate ignored the end of the thread, so wait_next slept out its
    whole timeout although no snapshot could come.
    """
    link = make_link()
    poller = make_poller(None, link).start()
    running.append(poller)
    assert poller.wait_next(0, timeout_s=2.0) is not None
    link.handlers[MspCommand.MULTIPLE_MSP] = lambda _request: None  # no more snapshots
    time.sleep(0.05)
    after = poller.sequence
    outcome: dict[str, object] = {}

    def wait() -> None:
        outcome["value"] = poller.wait_next(after, timeout_s=2.0)
        outcome["at_s"] = time.monotonic()

    waiter = threading.Thread(target=wait)
    waiter.start()
    time.sleep(0.05)
    closed_at_s = time.monotonic()
    link.closed_by_peer = True
    waiter.join(timeout=3.0)
    assert outcome["value"] is None
    assert float(outcome["at_s"]) - closed_at_s < 0.5  # type: ignore[arg-type]
    assert isinstance(poller.fatal_error, LinkClosedError)
    start = time.monotonic()
    assert poller.wait_next(poller.sequence, timeout_s=1.0) is None
    assert time.monotonic() - start < 0.5


def test_stop_joins_the_thread_and_polling_ends() -> None:
    """stop() returns only after the thread has ended; no request is sent after it."""
    link = make_link()
    before = poller_threads()
    poller = make_poller(None, link).start()
    (thread,) = poller_threads() - before
    assert poller.wait_next(0, timeout_s=2.0) is not None
    poller.stop()
    assert not thread.is_alive()
    sent = len(link.sent_commands)
    count = poller.sequence
    time.sleep(0.05)
    assert len(link.sent_commands) == sent
    assert poller.sequence == count
    assert poller.fatal_error is None


def test_context_manager_starts_and_stops() -> None:
    """``with poller:`` runs the thread inside the block only."""
    before = poller_threads()
    with make_poller(None) as poller:
        assert poller.wait_next(0, timeout_s=2.0) is not None
        (thread,) = poller_threads() - before
    assert not thread.is_alive()


def test_decode_errors_are_counted_not_raised(running: list[TelemetryPoller]) -> None:
    """A reply that does not decode counts in stats().errors; the poller keeps going."""
    link = make_link()
    # The FC truncates MULTIPLE_MSP: 3 sub-replies for 7 commands cannot make a snapshot.
    link.handlers[MspCommand.MULTIPLE_MSP] = multiple_msp(link.handlers, limit=3)
    poller = make_poller(None, link).start()
    running.append(poller)
    assert wait_until(lambda: poller.stats().errors >= 3)
    stats = poller.stats()
    assert stats.updates == 0 and poller.latest() is None
    assert poller.fatal_error is None
    assert stats.last_error is not None


def test_poller_recovers_after_the_fc_stops_answering(running: list[TelemetryPoller]) -> None:
    """Timeouts do not end the poller: once the FC answers again, snapshots resume."""
    link = make_link()
    answer = link.handlers[MspCommand.MULTIPLE_MSP]
    mute = threading.Event()

    def sometimes(request: MspFrame) -> bytes | None:
        return None if mute.is_set() else answer(request)

    link.handlers[MspCommand.MULTIPLE_MSP] = sometimes
    poller = make_poller(None, link).start()
    running.append(poller)
    assert poller.wait_next(0, timeout_s=2.0) is not None
    mute.set()
    time.sleep(0.25)  # a couple of 0.1 s timeouts
    mute.clear()
    assert poller.wait_next(poller.sequence, timeout_s=2.0) is not None
    assert poller.fatal_error is None
    # The unanswered polls are counted, not raised.  Replies go to the oldest outstanding
    # identical polls, so the unanswered ones surface when they time out at the end of a
    # batch rather than at once.
    deadline = time.monotonic() + 2.0
    while poller.stats().missed < 1 and time.monotonic() < deadline:
        time.sleep(0.02)
    assert poller.stats().missed >= 1


def test_poller_lets_other_users_of_the_client_in(running: list[TelemetryPoller]) -> None:
    """While polling flat out, another thread's request on the same client still completes."""
    link = make_link()
    client = MspClient(link, timeout_s=0.1)
    poller = TelemetryPoller(client, rate_hz=None).start()
    running.append(poller)
    assert poller.wait_next(0, timeout_s=2.0) is not None
    start = time.monotonic()
    assert msg.Altitude.decode(client.request(MspCommand.ALTITUDE)) == msg.Altitude(100, 0)
    # A liveness bound, not a speed one: a starved request would wait for ever (the fake
    # answers at once); a loaded 2-core machine once took 1.03 s here.
    assert time.monotonic() - start < 5.0
    assert poller.wait_next(poller.sequence, timeout_s=2.0) is not None


def test_box_ids_are_read_before_the_thread_starts() -> None:
    """start() fetches BOXIDS once, so every snapshot can name its flight modes."""
    link = make_link()
    poller = make_poller(50.0, link)
    with poller:
        assert poller.wait_next(0, timeout_s=2.0) is not None
    assert link.sent_commands[0] == MspCommand.BOXIDS
    assert link.sent_commands.count(MspCommand.BOXIDS) == 1


@pytest.mark.parametrize("rate_hz", [0.0, -5.0])
def test_rate_must_be_positive(rate_hz: float) -> None:
    """A zero or negative rate is refused up front."""
    with pytest.raises(ValueError):
        make_poller(rate_hz)


def test_start_twice_is_refused() -> None:
    """A poller runs one thread at most."""
    poller = make_poller(50.0).start()
    try:
        with pytest.raises(RuntimeError):
            poller.start()
    finally:
        poller.stop()
