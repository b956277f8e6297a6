"""The Configurator's conversation with the real 4.6.0 SITL through the bridge, spoken by a
client that speaks like the app (frames from ``tests/data/configurator/``): the connect
sequence is answered as the app needs it, the CLI round-trips, and leaving the CLI reboots the
SITL, after which the app's reconnect reaches the restarted SITL.  With the user's own build
of the app (``BFSITL_CONFIGURATOR_DIST``) test_configurator_app.py drives the real thing."""

from __future__ import annotations

import pytest
from support.configurator_client import ConfiguratorLikeClient, frames

from bfsitl.bridges.websocket_relay import CLOSE_UPSTREAM_GONE
from bfsitl.protocol import messages as msg

pytestmark = pytest.mark.sitl


def test_the_apps_connect_sequence_gets_what_the_app_needs(relay_url) -> None:
    with ConfiguratorLikeClient(relay_url) as app:
        replies = app.connect_sequence()
        # The app aborts unless each of these is right (serial_backend.js).
        assert msg.ApiVersion.decode(replies["MSP_API_VERSION"].payload).api == (1, 47)
        assert msg.FcVariant.decode(replies["MSP_FC_VARIANT"].payload).identifier == "BTFL"
        assert msg.FcVersion.decode(replies["MSP_FC_VERSION"].payload).text == "4.6.0"
        assert msg.BoardInfo.decode(replies["MSP_BOARD_INFO"].payload).board_id == "SITL"
        for name in ("MSP_BUILD_INFO", "MSP_STATUS", "MSP_UID", "MSP_SET_RTC"):
            assert not replies[name].error, name
        # MSP v2 requests pass through the bridge and are answered (an error reply is an
        # answer: 4.6.0 has no build key; the app carries on).
        assert set(replies) == {step["name"] for step in frames()["connect"]}
        # Then the Setup tab's polling.
        for step in frames()["setup_tab_poll"]:
            assert not app.request(step["hex"], step["command"]).error, step["name"]


def test_the_cli_round_trips_and_leaving_it_reconnects_to_the_restarted_sitl(
    sitl, relay_url
) -> None:
    cli = frames()["cli"]
    first_pid = sitl.pid
    with ConfiguratorLikeClient(relay_url) as app:
        assert "# " in app.cli_text(cli["enter"], until=b"\r\n# ")
        answer = app.cli_text(cli["command"], until=b"small_angle = ")
        assert "get small_angle" in answer
        app.ws.send(bytes.fromhex(cli["leave"]))  # type: ignore[union-attr]
        # `exit` reboots the FC, which ends a SITL process: the bridge closes the app's socket
        # with its "the SITL went away" code.
        assert app.wait_closed(timeout_s=15.0) == CLOSE_UPSTREAM_GONE
    # The app reconnects; the bridge starts the SITL again for it (a whole boot: up to 15 s on
    # a loaded machine) and the connect sequence is answered by the new process.
    with ConfiguratorLikeClient(relay_url, open_timeout_s=20.0) as app:
        api = frames()["connect"][0]
        assert msg.ApiVersion.decode(
            app.request(api["hex"], api["command"], timeout_s=15.0).payload
        ).api == (1, 47)
    assert sitl.starts == 2 and sitl.pid != first_pid
