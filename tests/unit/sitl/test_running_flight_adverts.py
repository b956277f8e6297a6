"""Running flights' adverts (bfsitl.sitl.running_flights): written whole, withdrawn however
the flight ends, stale ones ignored and removed, several listed with how to choose.

Which processes run is a fake here (pid -> start ticks), except where /proc itself is the
subject."""

from __future__ import annotations

import dataclasses
import itertools
import os
from pathlib import Path

import pytest

from bfsitl.errors import AttachError
from bfsitl.sitl import running_flights
from bfsitl.sitl.running_flights import (
    FlightAdvert,
    FlightRegistry,
    choose_flight,
    command_line,
    flights_dir,
    process_start_ticks,
)


class FakeProcesses:
    """pid -> start ticks of the processes that run; any other pid is gone."""

    def __init__(self, **running: int) -> None:
        self.ticks = {int(pid.removeprefix("p")): ticks for pid, ticks in running.items()}

    def __call__(self, pid: int) -> int | None:
        return self.ticks.get(pid)


def advert(
    pid: int, *, ticks: int = 100, key: str | None = None, at_s: float = 0.0
) -> FlightAdvert:
    return FlightAdvert(
        key=key or str(pid),
        pid=pid,
        started_ticks=ticks,
        command=f"bfsitl fly --hold {pid}",
        firmware="4.6.0 (4.6 conventions)",
        host="127.0.0.1",
        port=5762,
        netns_pid=pid + 1,
        started_at_s=at_s,
        workdir="run",
    )


def registry(tmp_path: Path, processes: FakeProcesses) -> FlightRegistry:
    return FlightRegistry(tmp_path / "flights", start_ticks=processes)


def test_an_advertised_flight_is_found_with_everything_it_said(tmp_path: Path) -> None:
    flights = registry(tmp_path, FakeProcesses(p10=100))
    path = flights.advertise(advert(10))
    assert path == tmp_path / "flights" / "10.json"
    assert flights.running() == [advert(10)]
    assert [p.name for p in (tmp_path / "flights").iterdir()] == ["10.json"]  # no temp file


def test_the_advert_is_withdrawn_however_the_block_ends(tmp_path: Path) -> None:
    flights = registry(tmp_path, FakeProcesses(p10=100))
    with flights.advertised(advert(10)) as path:
        assert path.exists() and flights.running() == [advert(10)]
    assert not path.exists()
    for stop in (RuntimeError("crash"), KeyboardInterrupt()):
        with pytest.raises(type(stop)), flights.advertised(advert(10)):
            raise stop
        assert flights.running() == [] and not path.exists()


def test_a_flight_whose_process_is_gone_is_ignored_and_its_advert_removed(
    tmp_path: Path,
) -> None:
    writer = registry(tmp_path, FakeProcesses(p10=100, p20=200))
    writer.advertise(advert(10))
    writer.advertise(advert(20, ticks=200))
    # pid 10 was killed (SIGKILL: nothing withdrew its advert); pid 20 runs on.
    reader = registry(tmp_path, FakeProcesses(p20=200))
    assert [a.key for a in reader.running()] == ["20"]
    assert not (tmp_path / "flights" / "10.json").exists()


def test_a_reused_pid_is_not_the_flight(tmp_path: Path) -> None:
    registry(tmp_path, FakeProcesses(p10=100)).advertise(advert(10))
    # Another process got pid 10 later: it started at another time.
    reader = registry(tmp_path, FakeProcesses(p10=555))
    assert reader.running() == []
    assert not (tmp_path / "flights" / "10.json").exists()


def test_several_flights_are_listed_oldest_first(tmp_path: Path) -> None:
    flights = registry(tmp_path, FakeProcesses(p10=100, p20=100, p30=100))
    flights.advertise(advert(30, at_s=300.0))
    flights.advertise(advert(10, at_s=100.0))
    flights.advertise(advert(20, at_s=200.0))
    assert [a.key for a in flights.running()] == ["10", "20", "30"]


def test_a_file_that_is_no_advert_is_kept_while_its_pid_runs(tmp_path: Path) -> None:
    folder = tmp_path / "flights"
    folder.mkdir()
    (folder / "10.json").write_text('{"version": 99, "what": "a newer bfsitl"}')
    (folder / "20.json").write_text("not json")
    (folder / "notes.json").write_text("{}")
    flights = registry(tmp_path, FakeProcesses(p10=100))
    assert flights.running() == []
    assert sorted(p.name for p in folder.iterdir()) == ["10.json"]


def test_no_folder_yet_means_no_flights(tmp_path: Path) -> None:
    assert registry(tmp_path, FakeProcesses()).running() == []


def test_the_folder_is_in_the_cache_bfsitl_uses(tmp_path: Path) -> None:
    assert flights_dir({"BFSITL_CACHE_DIR": str(tmp_path)}) == tmp_path / "flights"
    assert FlightRegistry(start_ticks=FakeProcesses()).directory == flights_dir()


def test_choose_the_only_flight_or_the_one_asked_for() -> None:
    one, two = advert(10), advert(20)
    assert choose_flight([one], None) is one
    assert choose_flight([one, two], "20") is two
    assert choose_flight([one], "10") is one


def test_choosing_among_several_says_which_run_and_how_to_choose() -> None:
    with pytest.raises(AttachError) as caught:
        choose_flight([advert(10), advert(20)], None)
    message = str(caught.value)
    assert "2 flights are running" in message
    assert "10 (`bfsitl fly --hold 10`" in message and "20 (`bfsitl fly --hold 20`" in message
    assert "`bfsitl top --attach 10`" in message
    assert "\n" not in message


def test_choosing_a_flight_that_does_not_run_says_what_does() -> None:
    with pytest.raises(AttachError, match="no running flight 30; running now: 10 "):
        choose_flight([advert(10)], "30")
    with pytest.raises(AttachError, match="no running flight to attach to: start one"):
        choose_flight([], None)
    with pytest.raises(AttachError, match="no running flight 30 to attach to"):
        choose_flight([], "30")


def test_a_flight_describes_itself_on_one_line() -> None:
    text = advert(10).describe()
    assert text.startswith("flight 10: `bfsitl fly --hold 10`, 4.6.0 (4.6 conventions), since ")
    assert text.endswith("MSP on UART2 at tcp://127.0.0.1:5762 in its private network namespace")
    host = dataclasses.replace(advert(10), netns_pid=None)
    assert host.describe().endswith("at tcp://127.0.0.1:5762")


def test_adverts_of_another_version_or_shape_are_not_read() -> None:
    assert FlightAdvert.from_json(advert(10).to_json()) == advert(10)
    assert (
        FlightAdvert.from_json(advert(10).to_json().replace('"version": 1', '"version": 2')) is None
    )
    assert FlightAdvert.from_json('{"version": 1, "key": "10"}') is None
    assert FlightAdvert.from_json("[]") is None


@pytest.mark.parametrize(
    "change",
    [
        {"started_at_s": "bad"},  # describe() would crash on it
        {"started_at_s": float("nan")},
        {"host": "203.0.113.7"},  # top would connect to another machine
        {"port": 0},
        {"port": 70000},
        {"pid": "10"},
        {"netns_pid": -1},
        {"command": 5},
    ],
)
def test_an_advert_with_a_field_out_of_shape_is_not_read(change: dict[str, object]) -> None:
    import json

    data = json.loads(advert(10).to_json())
    data.update(change)
    assert FlightAdvert.from_json(json.dumps(data)) is None


def test_a_file_that_is_not_text_or_cannot_be_removed_does_not_stop_the_listing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = tmp_path / "flights"
    folder.mkdir()
    (folder / "30.json").write_bytes(b"\xff\xfe not utf-8")
    flights = registry(tmp_path, FakeProcesses(p10=100))
    flights.advertise(advert(10))
    assert [a.key for a in flights.running()] == ["10"]
    assert not (folder / "30.json").exists()  # no advert, its pid gone: removed

    def refuse(self: Path, missing_ok: bool = False) -> None:
        raise PermissionError("read-only cache")

    (folder / "40.json").write_text("{}")
    monkeypatch.setattr(Path, "unlink", refuse)
    assert [a.key for a in flights.running()] == ["10"]  # no PermissionError


def test_this_process_advertises_under_its_pid_then_pid_dot_n(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(running_flights, "_advertised_here", itertools.count(1))
    monkeypatch.setattr(running_flights.sys, "argv", ["/usr/bin/bfsitl", "fly", "--hold", "60"])
    pid = os.getpid()

    def made() -> FlightAdvert:
        return FlightAdvert.for_this_process(
            firmware="fw",
            host="127.0.0.1",
            port=5762,
            netns_pid=None,
            workdir="run",
            start_ticks=lambda _pid: 42,
            now_s=5.0,
        )

    first, second = made(), made()
    assert (first.key, second.key) == (str(pid), f"{pid}.2")
    assert first.pid == second.pid == pid and first.started_ticks == 42
    assert first.command == "bfsitl fly --hold 60" and first.started_at_s == 5.0


def test_a_long_command_line_is_cut() -> None:
    assert command_line(["/x/bfsitl", "fly", "--log", "a b.csv"]) == "bfsitl fly --log 'a b.csv'"
    long = command_line(["bfsitl", "fly", *(["--gain", "kp=1"] * 40)])
    assert len(long) == running_flights.MAX_COMMAND_CHARS and long.endswith("...")


def test_start_ticks_from_proc(tmp_path: Path) -> None:
    own = process_start_ticks(os.getpid())
    assert own is not None and own > 0
    fields = ["S", *["0"] * 18, "12345", "0"]
    (tmp_path / "7").mkdir()
    (tmp_path / "7" / "stat").write_text(f"7 (a (tricky) name) {' '.join(fields)}\n")
    assert process_start_ticks(7, proc_root=tmp_path) == 12345
    (tmp_path / "7" / "stat").write_text(f"7 (zombie) Z {' '.join(fields[1:])}\n")
    assert process_start_ticks(7, proc_root=tmp_path) is None  # ended, not yet collected
    assert process_start_ticks(8, proc_root=tmp_path) is None  # gone
