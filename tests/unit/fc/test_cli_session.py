"""CliSession against FakeCliLink, a port that mimics the 4.6 CLI byte for byte.

The fake echoes typed characters, prints the prompt after each line, answers ``###ERROR`` and
``ERR_CMD_NA`` like ``cli/cli.c``, reboots (end of stream) on ``save``/``exit``, and speaks MSP
outside the CLI, so a test can check that the port really is back in MSP afterwards.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from support.fake_fc import DIFF_ALL, FakeCliLink, fixed  # noqa: E402

from bfsitl.errors import CliCommandError, CliError, MspTimeoutError  # noqa: E402
from bfsitl.fc import cli_session  # noqa: E402
from bfsitl.fc.cli_session import CliSession  # noqa: E402
from bfsitl.fc.msp_client import MspClient  # noqa: E402
from bfsitl.protocol import messages as msg  # noqa: E402
from bfsitl.protocol.msp_codes import MspCommand  # noqa: E402

API_VERSION = msg.ApiVersion(0, 1, 47)


def make_link(state: str = "msp", enter_silence_s: float = 0.02) -> FakeCliLink:
    link = FakeCliLink(
        {MspCommand.API_VERSION: fixed(API_VERSION.encode())},
        state=state,
        enter_silence_s=enter_silence_s,
    )
    # Distinct values, so picking the wrong line of a substring match shows.
    link.settings["rc_smoothing_auto_factor_throttle"] = (45, 0, 250)
    return link


@pytest.fixture
def fast_enter(monkeypatch: pytest.MonkeyPatch) -> None:
    """Shrink the post-'#' silence for speed; the fake's guard time shrinks with it."""
    monkeypatch.setattr(cli_session, "_ENTER_SILENCE_S", 0.03)


@pytest.fixture
def link() -> FakeCliLink:
    return make_link()


@pytest.fixture
def session(fast_enter: None, link: FakeCliLink) -> Iterator[CliSession]:
    """An entered session on a port that started in MSP state."""
    yield CliSession(link, timeout_s=1.0).enter()


# --- entering and leaving -----------------------------------------------------------------------


def test_enter_from_msp_state_with_firmware_timing() -> None:
    """With the firmware's 100 ms guard time, enter() gets the port into the CLI."""
    link = make_link(enter_silence_s=0.1)
    session = CliSession(link, timeout_s=1.0).enter()
    assert session.active
    assert link.state == "cli" and link.cli_entries == 1
    assert "Entering CLI Mode" in session.banner
    assert session.run("get small_angle").splitlines()[0] == "small_angle = 25"


def test_enter_tries_once_more_with_a_longer_silence(monkeypatch: pytest.MonkeyPatch) -> None:
    """A starved SITL that needs more silence than the first try gives still enters."""
    monkeypatch.setattr(cli_session, "_ENTER_SILENCE_S", 0.03)
    monkeypatch.setattr(cli_session, "_ENTER_RETRY_SILENCE_S", 0.2)
    link = make_link(enter_silence_s=0.1)
    session = CliSession(link, timeout_s=0.5).enter()
    assert session.active and link.state == "cli" and link.cli_entries == 1


def test_a_port_that_never_enters_fails_after_the_second_try(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(cli_session, "_ENTER_SILENCE_S", 0.03)
    monkeypatch.setattr(cli_session, "_ENTER_RETRY_SILENCE_S", 0.05)
    link = make_link(enter_silence_s=0.1)
    with pytest.raises(CliError, match="did not answer"):
        CliSession(link, timeout_s=0.3).enter()
    assert link.cli_entries == 0


def test_enter_when_port_was_left_in_cli(fast_enter: None) -> None:
    """A port a dropped client left in CLI mode is taken over, and commands work at once."""
    link = make_link(state="cli")
    session = CliSession(link, timeout_s=1.0).enter()
    assert session.active and link.state == "cli"
    assert session.run("get small_angle").splitlines() == [
        "small_angle = 25",
        "Allowed range: 0 - 180",
    ]
    assert link.commands_run == [("cli", "get small_angle")]


def test_enter_when_port_was_left_in_stx_mode(fast_enter: None) -> None:
    """A stray 0x02 left the port in the non-interactive CLI: enter() ends it and gets in."""
    link = make_link(state="stx")
    session = CliSession(link, timeout_s=1.0).enter()
    assert session.active and link.state == "cli" and link.cli_entries == 1
    assert session.get("small_angle") == "25"


def test_leave_returns_the_port_to_msp(session: CliSession, link: FakeCliLink) -> None:
    """leave() sends ``exit noreboot``: no reboot, and MSP requests are answered again."""
    output = session.leave()
    assert "leaving CLI mode" in output
    assert not session.active
    assert link.state == "msp"
    assert ("cli", "exit noreboot") in link.commands_run
    client = MspClient(link, timeout_s=0.1)
    assert client.api_version() == API_VERSION


def test_port_left_in_cli_is_recovered_for_msp(fast_enter: None) -> None:
    """MSP times out naming CLI mode on a port left in CLI; enter() + leave() fixes it."""
    link = make_link(state="cli")
    client = MspClient(link, timeout_s=0.05)
    with pytest.raises(MspTimeoutError, match="CLI mode"):
        client.request(MspCommand.API_VERSION, retries=0)
    CliSession(link, timeout_s=1.0).enter().leave()
    assert client.api_version() == API_VERSION


def test_context_manager_leaves(fast_enter: None, link: FakeCliLink) -> None:
    """Leaving the ``with`` block returns the port to MSP."""
    with CliSession(link, timeout_s=1.0) as session:
        assert session.active and link.state == "cli"
    assert not session.active and link.state == "msp"


def test_run_before_enter_is_refused(link: FakeCliLink) -> None:
    """Commands need an entered session; nothing is sent otherwise."""
    with pytest.raises(CliError):
        CliSession(link, timeout_s=1.0).run("get small_angle")
    assert link.raw_written == b""


# --- run ----------------------------------------------------------------------------------------


def test_run_returns_only_the_output(session: CliSession) -> None:
    """Echo, the prompt and the sync marker are stripped; the output lines remain."""
    output = session.run("get small_angle")
    assert output.splitlines() == ["small_angle = 25", "Allowed range: 0 - 180"]
    assert "#" not in output and "bfsync" not in output


def test_run_returns_empty_output_for_silent_command(
    session: CliSession, link: FakeCliLink
) -> None:
    """A command that prints nothing gives an empty string, not a prompt or an echo."""
    link.overrides["aux 0 0 0 1700 2100 0 0"] = ""
    assert session.run("aux 0 0 0 1700 2100 0 0") == ""


def test_diff_all_is_returned_whole(session: CliSession) -> None:
    """``diff all`` lines starting with "# " look like prompts, yet none is cut off."""
    output = session.diff_all()
    assert output.splitlines() == DIFF_ALL.strip("\r\n").splitlines()
    assert output.splitlines()[-1] == "save"
    assert sum(line.startswith("# ") for line in output.splitlines()) >= 8


def test_successive_commands_stay_in_sync(session: CliSession, link: FakeCliLink) -> None:
    """Each run() gets its own output, also after an error and a long output."""
    session.run("diff all")
    with pytest.raises(CliCommandError):
        session.run("frobnicate")
    assert session.run("get small_angle").startswith("small_angle = 25")
    assert session.run("set small_angle = 30") == "small_angle set to 30"
    assert [line for _, line in link.commands_run] == [
        "diff all",
        "frobnicate",
        "get small_angle",
        "set small_angle = 30",
    ]


def test_error_output_raises_cli_command_error(session: CliSession) -> None:
    """``###ERROR`` output raises CliCommandError carrying the command and the output."""
    with pytest.raises(CliCommandError) as info:
        session.run("frobnicate")
    assert info.value.command == "frobnicate"
    assert "UNKNOWN COMMAND" in info.value.output


def test_error_output_is_returned_with_check_false(session: CliSession) -> None:
    """check=False hands the ``###ERROR`` output back instead of raising."""
    output = session.run("frobnicate", check=False)
    assert output.startswith("###ERROR IN input: UNKNOWN COMMAND")


@pytest.mark.parametrize("command", ["save", "exit", "SAVE", "  exit  ", "defaults"])
def test_run_refuses_rebooting_commands(
    session: CliSession, link: FakeCliLink, command: str
) -> None:
    """Commands that reboot (and so end a SITL process) are refused before anything is sent."""
    before = bytes(link.raw_written)
    with pytest.raises(CliError):
        session.run(command)
    assert link.raw_written == before
    assert link.state == "cli" and link.saves == 0


@pytest.mark.parametrize(
    "command",
    [
        "get small_angle\nsave",
        "get small_angle\rsave",
        "set name = " + "x" * 200,
        "set name = caf\u00e9",
        "get \x02small_angle",
    ],
    ids=["newline", "carriage-return", "overlong", "non-ascii", "stx"],
)
def test_run_refuses_malformed_commands(
    session: CliSession, link: FakeCliLink, command: str
) -> None:
    """Multi-line, overlong, non-ASCII and STX-carrying commands never reach the port."""
    before = bytes(link.raw_written)
    with pytest.raises(CliError) as info:
        session.run(command)
    assert not isinstance(info.value, CliCommandError)
    assert link.raw_written == before


@pytest.mark.parametrize(
    "command",
    ["\x04", "get\tsmall_angle", "get small_angle\x7f"],
    ids=["ctrl-d", "tab", "del"],
)
def test_run_refuses_control_characters(
    session: CliSession, link: FakeCliLink, command: str
) -> None:
    """Only printable ASCII is typed into the CLI; control characters are refused unsent.

    Regression: they passed validation, and the CLI acts on them as keys (CTRL-D on an empty
    line exits and reboots, TAB completes, DEL erases).
    """
    before = bytes(link.raw_written)
    with pytest.raises(CliError):
        session.run(command)
    assert link.raw_written == before


def test_run_refuses_exit_noreboot(fast_enter: None, link: FakeCliLink) -> None:
    """Leaving the CLI goes through leave(), which knows no prompt follows.

    Regression: run() let it through, timed out on the missing sync echo and kept
    active=True.
    """
    session = CliSession(link, timeout_s=0.2).enter()
    before = bytes(link.raw_written)
    with pytest.raises(CliError):
        session.run("exit noreboot")
    assert link.raw_written == before
    assert link.state == "cli"


def test_defaults_nosave_is_allowed(session: CliSession, link: FakeCliLink) -> None:
    """``defaults nosave`` resets without rebooting: run() and batch() let it through."""
    assert "resetting to defaults" in session.run("defaults nosave")
    assert link.state == "cli"
    session.leave()
    session.batch(["defaults nosave", "set small_angle = 40"])
    assert link.settings["small_angle"][0] == 40
    assert link.state == "msp"


def test_run_many_skips_blank_lines_and_comments(session: CliSession, link: FakeCliLink) -> None:
    """run_many runs the command lines in order and skips blanks and ``#`` comments."""
    outputs = session.run_many(["# a comment", "", "get small_angle", "  ", "set small_angle = 40"])
    assert len(outputs) == 2
    assert [line for _, line in link.commands_run] == ["get small_angle", "set small_angle = 40"]


# --- get / set ----------------------------------------------------------------------------------


def test_get_returns_the_exact_setting(session: CliSession) -> None:
    """``get`` matches substrings; get() picks the line of exactly the name asked for."""
    assert session.get("rc_smoothing_auto_factor") == "30"
    assert session.get("rc_smoothing_auto_factor_throttle") == "45"
    assert session.get("small_angle") == "25"


def test_get_unknown_setting_raises(session: CliSession) -> None:
    """A name the FC does not know raises CliCommandError."""
    with pytest.raises(CliCommandError):
        session.get("no_such_setting")


def test_get_substring_only_match_raises(session: CliSession) -> None:
    """A name that only matches as a substring of other settings is not silently accepted."""
    with pytest.raises(CliCommandError):
        session.get("smoothing")


def test_set_changes_the_value(session: CliSession, link: FakeCliLink) -> None:
    """set() sends ``set name = value`` and the FC's new value reads back."""
    session.set("small_angle", 30)
    assert link.settings["small_angle"][0] == 30
    assert session.get("small_angle") == "30"


def test_set_out_of_range_raises(session: CliSession, link: FakeCliLink) -> None:
    """The FC's ``###ERROR`` for an invalid value raises CliCommandError."""
    with pytest.raises(CliCommandError):
        session.set("small_angle", 500)
    assert link.settings["small_angle"][0] == 25


def test_set_without_set_to_confirmation_raises(session: CliSession, link: FakeCliLink) -> None:
    """Output without "set to" (older firmware prints errors without ###ERROR) is a failure."""
    link.overrides["set small_angle = 31"] = "Invalid name\r\n"
    with pytest.raises(CliCommandError):
        session.set("small_angle", 31)


# --- backup -------------------------------------------------------------------------------------


def test_backup_writes_the_diff_atomically(session: CliSession, tmp_path: Path) -> None:
    """backup() writes the whole ``diff all`` with LF line ends and leaves no .partial file."""
    target = tmp_path / "fc.diff"
    target.write_text("old backup\n")
    assert session.backup(target) == target
    text = target.read_text()
    assert "\r" not in text
    assert text.splitlines() == DIFF_ALL.strip("\r\n").splitlines()
    assert text.endswith("save\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fc.diff"]


def test_failed_backup_keeps_the_old_file(
    session: CliSession, link: FakeCliLink, tmp_path: Path
) -> None:
    """When ``diff all`` fails, the previous backup stays and no partial file appears."""
    target = tmp_path / "fc.diff"
    target.write_text("old backup\n")
    link.overrides["diff all"] = "###ERROR IN diff: PARSING FAILED###\r\n"
    with pytest.raises(CliCommandError):
        session.backup(target)
    assert target.read_text() == "old backup\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fc.diff"]


# --- save ---------------------------------------------------------------------------------------


def test_save_survives_eof_and_restarts_once(session: CliSession, link: FakeCliLink) -> None:
    """save(): the FC reboots and the stream ends; restart is called once, after the EOF."""
    states: list[str] = []
    output = session.save(restart=lambda: states.append(link.state))
    assert states == ["rebooted"]
    assert link.saves == 1
    assert not session.active
    assert "saving" in output


def test_save_without_restart_callback(session: CliSession, link: FakeCliLink) -> None:
    """Without a callback save() still ends the session cleanly at the EOF."""
    session.save()
    assert link.saves == 1 and not session.active
    with pytest.raises(CliError):
        session.run("get small_angle")


# --- batch (STX/ETX) ----------------------------------------------------------------------------


def test_batch_uses_stx_etx_from_msp_state(fast_enter: None, link: FakeCliLink) -> None:
    """batch() frames the lines in 0x02 ... 0x03, never enters the interactive CLI, and
    returns the outputs; the port is back in MSP afterwards."""
    session = CliSession(link, timeout_s=1.0)
    output = session.batch(["get small_angle", "# comment", "set small_angle = 40"])
    assert bytes(link.raw_written).endswith(b"\x02get small_angle\nset small_angle = 40\n\x03")
    assert link.commands_run == [("stx", "get small_angle"), ("stx", "set small_angle = 40")]
    assert "small_angle = 25" in output and "small_angle set to 40" in output
    assert "\x02" not in output and "\x03" not in output
    assert link.cli_entries == 0 and link.state == "msp"
    assert MspClient(link, timeout_s=0.1).api_version() == API_VERSION


def test_batch_raises_on_err_cmd_na(link: FakeCliLink) -> None:
    """An unknown command in a batch (``ERR_CMD_NA``) raises CliCommandError."""
    with pytest.raises(CliCommandError) as info:
        CliSession(link, timeout_s=1.0).batch(["get small_angle", "frobnicate"])
    assert "ERR_CMD_NA" in info.value.output


def test_batch_raises_on_error_line(link: FakeCliLink) -> None:
    """A ``###ERROR`` in batch output raises too; check=False returns the output."""
    session = CliSession(link, timeout_s=1.0)
    with pytest.raises(CliCommandError):
        session.batch(["set small_angle = 500"])
    assert "###ERROR" in session.batch(["set small_angle = 500"], check=False)


def test_batch_refused_inside_interactive_session(session: CliSession, link: FakeCliLink) -> None:
    """batch() runs from MSP state only; inside the interactive CLI it is refused unsent."""
    before = bytes(link.raw_written)
    with pytest.raises(CliError):
        session.batch(["get small_angle"])
    assert link.raw_written == before


def test_batch_refuses_rebooting_commands(link: FakeCliLink) -> None:
    """``save`` in a batch would end the SITL process: refused before anything is sent.

    Regression: batch() did not apply run()'s refusal of rebooting commands.
    """
    with pytest.raises(CliError):
        CliSession(link, timeout_s=0.3).batch(["set small_angle = 40", "save"])
    assert link.raw_written == b""


def test_a_byte_changed_in_the_markers_echo_still_ends_the_output(
    session: CliSession, link: FakeCliLink, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Seen once on CI: the SITL echoed '#bfsync-...' as '#ifsync-...'; waiting for the whole
    token timed out after 10 s. The tail (pid and counter) ends the output just as well."""
    original = link._interactive_char
    changed = []

    def corrupt(byte: int) -> None:
        if byte == ord("b") and link._line == bytearray(b"#") and not changed:
            changed.append(byte)
            byte = ord("i")
        original(byte)

    monkeypatch.setattr(link, "_interactive_char", corrupt)
    output = session.run("get small_angle")
    assert changed, "the fake did not see the marker"
    assert output.splitlines() == ["small_angle = 25", "Allowed range: 0 - 180"]
    assert session.run("get small_angle").startswith("small_angle = 25")  # still in step


def test_a_failed_command_says_the_error_alone_even_among_run_together_echoes() -> None:
    from bfsitl.errors import CliCommandError

    output = (
        "set blackbox_sample_rate = 1/16blackbox_device set to VIRTUAL"
        "###ERROR IN set: INVALID NAME: ap_hover_throtle###\nset debug_mode = FAILSAFE"
    )
    error = CliCommandError("set ap_hover_throtle = 1275", output)
    assert str(error) == (
        "CLI command 'set ap_hover_throtle = 1275' failed: "
        "###ERROR IN set: INVALID NAME: ap_hover_throtle###"
    )
    assert error.output == output  # the whole output is kept for whoever wants it
    assert str(CliCommandError("x", "ERR_CMD_NA\n")).endswith("failed: ERR_CMD_NA")
