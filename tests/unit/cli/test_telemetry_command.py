"""`bfsitl telemetry` must not report success when no update arrived (a script relies on it)."""

from __future__ import annotations

import argparse
from contextlib import contextmanager
from types import SimpleNamespace

from bfsitl.cli import main as cli_main


class SilentPoller:
    """A poller that never gets a reply (the FC is gone or the port is in CLI mode)."""

    fatal_error = None
    sequence = 0

    def __init__(self, _client, rate_hz=None) -> None:  # type: ignore[no-untyped-def]
        pass

    def __enter__(self) -> SilentPoller:
        return self

    def __exit__(self, *_exc: object) -> None:
        pass

    def wait_next(self, _sequence: int, timeout_s: float = 2.0) -> None:
        return None

    def stats(self) -> SimpleNamespace:
        return SimpleNamespace(updates=0, elapsed_s=0.1, rate_hz=0.0, errors=3)


def test_no_update_at_all_exits_with_an_error(monkeypatch, capsys):
    @contextmanager
    def target(_args):  # type: ignore[no-untyped-def]
        yield SimpleNamespace(client=object())

    monkeypatch.setattr(cli_main, "open_target", target)
    monkeypatch.setattr(cli_main, "TelemetryPoller", SilentPoller)
    args = argparse.Namespace(json=True, rate=20.0, duration=0.05)
    assert cli_main.cmd_telemetry(args) == cli_main.EXIT_ERROR
    assert "no telemetry update arrived" in capsys.readouterr().err
