"""The real Betaflight Configurator (web build) in headless Chromium, driven as a user drives it.

The web build is the user's own: a built ``dist/`` of betaflight-configurator (``npm run build``
in a clone of it, or an extracted release archive) named by ``BFSITL_CONFIGURATOR_DIST``.  The
project carries no Configurator; without that variable the app's tests are skipped with one line
that says what to set, whatever ``BFSITL_REQUIRE_BROWSER`` says.  (What the bridge must do for
the app is tested without it, by a client that speaks like it from recorded frames.)  It is served
from 127.0.0.1 by a static HTTP server in a thread, opened in Debian's Chromium through the
``playwright`` package (no browser download: ``executable_path`` is the system's chromium), and
operated with :class:`ConfiguratorPage`: Expert Mode on, Connect menu, Setup tab, CLI tab...

pytest fixtures; import them into a test module (as ``firmware_builds``' are), and ask for them
with ``request.getfixturevalue`` (a parameter of the same name would be a redefinition to
ruff)::

    from configurator_app import (  # noqa: F401  (pytest fixtures)
        configurator_app_url, configurator_browser, configurator_chromium, configurator_dist,
        watch_flight,
    )

    def test_watch(request, tmp_path):
        seen = watch_flight(url, browser=request.getfixturevalue("configurator_browser"),
                            app_url=request.getfixturevalue("configurator_app_url"),
                            screenshot=tmp_path / "setup.png")

* ``configurator_dist`` (session): the extracted ``dist/`` directory;
* ``configurator_app_url`` (session): ``http://127.0.0.1:PORT/index.html`` serving it;
* ``configurator_chromium`` (session): the chromium binary;
* ``configurator_browser`` (module): one headless Chromium (a Playwright ``Browser``); open a
  page per test with :func:`open_configurator`, which gives each its own browser context.

Given the build, without chromium or the ``playwright`` package they skip, unless
``BFSITL_REQUIRE_BROWSER=1``, where they fail.

Selectors, chosen to survive restyling (the app is Vue + Nuxt UI; its utility classes change
often, its ids, roles, i18n texts and component class names rarely):

* Options dialog: ``role=dialog`` named "Options"; a switch is the ``role=switch`` button of the
  row whose label span reads the i18n text (``expertMode``: "Enable Expert Mode") - the switch
  has no accessible name of its own;
* Connect: ``.sidebar-connect`` (ConnectButton's root).  Disconnected it holds a button group:
  ``.sidebar-connect__main`` (its title is the remembered port, or "Connect") and the menu
  trigger ``[aria-haspopup=menu]``; connected it holds one button, "Disconnect (Manual)";
* Connect menu: ``role=menuitem`` "Betaflight SITL" (a saved connection, ws://127.0.0.1:6761:
  selecting it connects) and "Manual Selection" (``portsSelectManual``), which opens the dialog
  "Manual Selection" with the textbox "Port:" and the button "Connect";
* tabs: the sidebar ``nav``'s buttons by their i18n label ("Setup", "CLI", "Motors"); the active
  one has ``aria-current=page``;
* Setup: ``#board-name-value``, ``#firmware-version-value``, ``#api-version-value`` (ids of the
  firmware info box); the attitude readout beside the 3D model,
  ``#canvas_wrapper .attitude_info dd.heading|.pitch|.roll`` ("12.3 deg", updated every 33 ms);
* CLI: output ``.cli-window .cli-wrapper``, input ``textarea[name=commands]`` (disabled while
  the app builds its autocomplete cache right after entering the CLI);
* Receiver: each channel's name ``#content .bars li.name`` ("Throttle [T]") and its value, the
  text of the element after it;
* Motors: the value above each motor's bar, ``.motors > ul:nth-of-type(2) > li > div`` (live
  only in motor test mode, see :meth:`ConfiguratorPage.motor_values`).

Things about the app that the helpers take care of:

* served from 127.0.0.1 the app opens the Options dialog by itself on load ("development
  settings"); :meth:`ConfiguratorPage.enable_expert_mode` uses that dialog when it is open;
* its service worker precaches the whole build (400 files, 46 MB) and then shows a modal "The
  application is ready to be used offline" at a random moment, which would swallow a click; the
  pages here block service workers (a browser-context option; nothing of the app changes), and
  dismiss that notice anyway should it show;
* after a reboot it asked for (leaving the CLI, ``save``) it drops any link still open 1.5 s
  later as stale, the user's new one included: :meth:`ConfiguratorPage.reconnect` waits that
  out.

Leaving the CLI tab or pressing Disconnect in it sends ``exit``: the SITL reboots, which ends the
process; ``bfsitl configurator --start`` restarts it when the next client connects.  A browser
that goes away *inside* the CLI leaves the SITL in CLI mode, where it answers no MSP and the next
connection fails its handshake; :meth:`ConfiguratorPage.close` therefore leaves the CLI first.
"""

from __future__ import annotations

import contextlib
import functools
import http.server
import os
import re
import shutil
import threading
import time
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:  # playwright is imported lazily: without it, the fixtures skip
    from playwright.sync_api import Browser, Locator, Page, WebSocket

#: A built ``dist/`` (the directory holding index.html), or the directory above it.
DIST_ENV_VAR = "BFSITL_CONFIGURATOR_DIST"
#: The one line every app test is skipped with when no build is given.
DIST_SKIP_REASON = (
    f"Configurator not given: set {DIST_ENV_VAR} to a built "
    f"betaflight-configurator dist/ to run the app tests"
)
REQUIRE_ENV_VAR = "BFSITL_REQUIRE_BROWSER"

#: The Connect menu's built-in "Betaflight SITL" entry.
DEFAULT_SITL_URL = "ws://127.0.0.1:6761"
SITL_BOOKMARK = "Betaflight SITL"
#: The app drops a link still open this long after it asked for a reboot (``Dle`` in its
#: serial backend) as stale.
REBOOT_TIMER_MS = 1500

CHROMIUM_ARGS = (
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
)
#: Every http(s) request not to this machine: analytics, sponsors, icon CDNs.  Aborted at once,
#: so nothing waits for a network that is not there (the app copes with each failing).
_REMOTE_REQUEST = re.compile(r"^https?://(?!(127\.0\.0\.1|localhost|\[::1\])(:\d+)?/)")
_NUMBER = re.compile(r"-?\d+(?:\.\d+)?")


class ConfiguratorAppError(AssertionError):
    """The app did not do what a user would have seen it do; the message says what it showed."""


# --- the build, served ----------------------------------------------------------------------


def _unavailable(reason: str) -> None:
    if os.environ.get(REQUIRE_ENV_VAR) == "1":
        pytest.fail(f"{REQUIRE_ENV_VAR}=1 but {reason}")
    pytest.skip(reason)


def _dist_from_env() -> Path:
    """The build named by ``BFSITL_CONFIGURATOR_DIST``; skips when none is named (the project
    has none of its own) and fails when the named one is not a build (the user's mistake)."""
    configured = os.environ.get(DIST_ENV_VAR, "").strip()
    if not configured:
        pytest.skip(DIST_SKIP_REASON)
    path = Path(configured).expanduser()
    for candidate in (path, path / "dist"):
        if (candidate / "index.html").is_file():
            return candidate.resolve()
    pytest.fail(
        f"{DIST_ENV_VAR}={configured} holds no index.html (nor dist/index.html): "
        f"point it at the Configurator's built dist/"
    )


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: Any) -> None:
        pass

    def log_error(self, format: str, *args: Any) -> None:
        pass

    def handle(self) -> None:
        # The browser drops keep-alive connections when a page closes; that is no error.
        with contextlib.suppress(ConnectionError):
            super().handle()


class StaticServer:
    """``directory`` served over HTTP on 127.0.0.1 (a free port) from a daemon thread.

    Use as a context manager; ``url`` is the app's address (``.../index.html``).
    """

    def __init__(self, directory: Path, host: str = "127.0.0.1", port: int = 0) -> None:
        handler = functools.partial(_QuietHandler, directory=str(directory))
        self._server = http.server.ThreadingHTTPServer((host, port), handler)
        self._server.daemon_threads = True
        self.port: int = self._server.server_address[1]
        self.url = f"http://{host}:{self.port}/index.html"
        self._thread = threading.Thread(
            target=self._server.serve_forever, name="configurator-http", daemon=True
        )

    def __enter__(self) -> StaticServer:
        self._thread.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=5)


def find_chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@contextlib.contextmanager
def launch_chromium(executable: str | None = None) -> Iterator[Browser]:
    """Headless Debian Chromium driven by Playwright; closed (process tree and all) on exit.

    Playwright's sync API allows one of these per thread at a time: share it (the
    ``configurator_browser`` fixture) rather than nesting a second.
    """
    from playwright.sync_api import sync_playwright

    path = executable or find_chromium()
    if path is None:
        raise FileNotFoundError("chromium is not installed (apt-get install chromium)")
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=path, headless=True, args=list(CHROMIUM_ARGS)
        )
        try:
            yield browser
        finally:
            browser.close()


# --- fixtures -------------------------------------------------------------------------------


@pytest.fixture(scope="session")
def configurator_dist() -> Path:
    """The web build's ``dist/``, from ``$BFSITL_CONFIGURATOR_DIST``."""
    return _dist_from_env()


@pytest.fixture(scope="session")
def configurator_app_url(configurator_dist: Path) -> Iterator[str]:
    """The app's URL, served from 127.0.0.1 (where it turns manual connections on)."""
    with StaticServer(configurator_dist) as server:
        yield server.url


@pytest.fixture(scope="session")
def configurator_chromium() -> str:
    """The chromium binary, with the ``playwright`` package to drive it."""
    path = find_chromium()
    if path is None:
        _unavailable("chromium is not installed (apt-get install chromium)")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        _unavailable(
            "the playwright package is not installed (pip install playwright; the "
            "system's chromium is used, no `playwright install`)"
        )
    assert path is not None
    return path


@pytest.fixture(scope="module")
def configurator_browser(configurator_chromium: str) -> Iterator[Browser]:
    """One headless Chromium per test module; :func:`open_configurator` gives each page its own
    context (storage, settings), so tests do not see each other's."""
    with launch_chromium(configurator_chromium) as browser:
        yield browser


# --- the app --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Attitude:
    """The Setup tab's readout beside the 3D model, in degrees; ``t`` is seconds since the
    first sample of a series (0 for a single reading)."""

    heading: float
    pitch: float
    roll: float
    t: float = 0.0


@dataclass
class _Socket:
    """What the app's WebSocket received, as bytes in order (for the CLI's prompt)."""

    url: str
    received: bytearray = field(default_factory=bytearray)
    closed: bool = False


class ConfiguratorPage:
    """One tab of the real Configurator, with the steps a user takes.

    Create it with :func:`open_configurator` (or :meth:`open`), which loads the app.  Waits are
    bounded by ``timeout_s`` unless a method takes its own; a step that fails raises
    :class:`ConfiguratorAppError` saying what the app showed, with the app's last console lines.
    """

    #: The app is ready once its sidebar Connect control is there.
    READY = ".sidebar-connect"

    def __init__(self, page: Page, app_url: str, *, timeout_s: float = 15.0) -> None:
        self.page = page
        self.app_url = app_url
        self.timeout_s = timeout_s
        #: The app's last console lines (and page errors), for the messages of failures.
        self.console: deque[str] = deque(maxlen=200)
        self.sockets: list[_Socket] = []
        self._in_cli = False
        page.on(
            "console", lambda message: self.console.append(f"{message.type}: {message.text[:300]}")
        )
        page.on("pageerror", lambda error: self.console.append(f"pageerror: {error}"))
        page.on("websocket", self._track_socket)
        page.set_default_timeout(timeout_s * 1000)
        # Only with service workers allowed: the "offline ready" modal shows at a random time.
        page.add_locator_handler(
            page.get_by_role("dialog", name="The application is ready to be used offline"),
            lambda dialog: dialog.get_by_role("button", name="OK").click(),
        )

    # -- loading -------------------------------------------------------------------------------

    @classmethod
    def open(cls, page: Page, app_url: str, *, timeout_s: float = 15.0) -> ConfiguratorPage:
        app = cls(page, app_url, timeout_s=timeout_s)
        app.load()
        return app

    def load(self) -> None:
        """Open the app and wait until it is ready (and for the Options dialog it opens by
        itself when served from 127.0.0.1)."""
        self.page.goto(self.app_url, wait_until="domcontentloaded")
        self.page.locator(self.READY).wait_for(state="visible")
        if _local_host(self.app_url):
            with contextlib.suppress(_playwright_timeout()):
                self._options_dialog().wait_for(state="visible", timeout=5_000)

    def _track_socket(self, ws: WebSocket) -> None:
        socket = _Socket(ws.url)
        self.sockets.append(socket)

        def received(payload: bytes | str) -> None:
            socket.received += payload if isinstance(payload, bytes) else payload.encode()

        def closed(_ws: WebSocket) -> None:
            socket.closed = True

        ws.on("framereceived", received)
        ws.on("close", closed)

    # -- Options -------------------------------------------------------------------------------

    def _options_dialog(self) -> Locator:
        return self.page.get_by_role("dialog", name="Options", exact=True)

    def _option_switch(self, label: str) -> Locator:
        """The switch of the Options row labelled ``label`` (the switch itself has no name)."""
        return self._options_dialog().locator(
            f"xpath=.//span[normalize-space()={_xpath_string(label)}]"
            f"/ancestor::div[.//button[@role='switch']][1]//button[@role='switch']"
        )

    def open_options(self) -> None:
        if not self._options_dialog().is_visible():
            self.page.get_by_role("button", name="Options", exact=True).click()
        self._options_dialog().wait_for(state="visible")

    def close_options(self) -> None:
        dialog = self._options_dialog()
        if dialog.is_visible():
            dialog.get_by_role("button", name="Close").click()
        dialog.wait_for(state="hidden")

    def set_option(self, label: str, on: bool) -> None:
        """Turn the Options switch ``label`` (its English text) on or off; Options stays open."""
        self.open_options()
        switch = self._option_switch(label)
        want = "true" if on else "false"
        if switch.get_attribute("aria-checked") != want:
            switch.click()
        _expect(switch).to_have_attribute("aria-checked", want)

    def enable_expert_mode(self) -> None:
        """Options > "Enable Expert Mode" on, dialog closed: as the README tells a user."""
        self.set_option("Enable Expert Mode", True)
        self.close_options()

    # -- connecting ----------------------------------------------------------------------------

    def _connect_area(self) -> Locator:
        return self.page.locator(".sidebar-connect")

    def _connect_button(self) -> Locator:
        """Disconnected: the main Connect button (title: the remembered port or "Connect")."""
        return self.page.locator(".sidebar-connect .sidebar-connect__main")

    def _disconnect_button(self) -> Locator:
        """Connected: ConnectButton holds this one button, "Disconnect (Manual)"."""
        return self.page.locator(".sidebar-connect > button")

    def is_connected(self) -> bool:
        return self._disconnect_button().is_visible()

    def connect_label(self) -> str:
        """What the Connect control says: "Connect", a remembered URL, "Disconnect (Manual)"."""
        return self._connect_area().inner_text().strip()

    def _open_connect_menu(self) -> Locator:
        if self._options_dialog().is_visible():  # the modal the app opened by itself
            self.close_options()
        self._connect_area().locator(".sidebar-connect__group [aria-haspopup=menu]").click()
        menu = self.page.get_by_role("menu")
        menu.wait_for(state="visible")
        return menu

    def connect_menu_items(self) -> list[str]:
        """The Connect menu's entries as the user sees them (the menu is closed again)."""
        menu = self._open_connect_menu()
        items = [text.strip() for text in menu.get_by_role("menuitem").all_inner_texts()]
        self.page.keyboard.press("Escape")
        menu.wait_for(state="hidden")
        return items

    def connect(self, ws_url: str, *, via: str = "auto", timeout_s: float = 20.0) -> None:
        """Connect to ``ws_url`` from the Connect menu and wait for the Setup tab.

        ``via``: "manual" (Manual Selection, the URL typed into Port), "bookmark" (the
        built-in "Betaflight SITL" entry, only for ws://127.0.0.1:6761), or "auto" (the
        bookmark for that URL, Manual Selection otherwise).  Both need Expert Mode on.
        """
        url = ws_url.rstrip("/")
        if self.is_connected():
            raise ConfiguratorAppError(f"already connected ({self.connect_label()!r})")
        if via == "auto":
            via = "bookmark" if url == DEFAULT_SITL_URL else "manual"
        if via == "bookmark" and url != DEFAULT_SITL_URL:
            raise ValueError(f"the {SITL_BOOKMARK!r} entry is {DEFAULT_SITL_URL}, not {url}")
        if via not in ("manual", "bookmark"):
            raise ValueError(f"via: 'auto', 'manual' or 'bookmark', not {via!r}")
        menu = self._open_connect_menu()
        entry = SITL_BOOKMARK if via == "bookmark" else "Manual Selection"
        item = menu.get_by_role("menuitem", name=entry, exact=True)
        if not item.is_visible():
            raise ConfiguratorAppError(
                f"no {entry!r} in the Connect menu (Expert Mode off?): "
                f"{[t.strip() for t in menu.get_by_role('menuitem').all_inner_texts()]}"
            )
        sockets_before = len(self.sockets)
        item.click()
        if via == "manual":
            dialog = self.page.get_by_role("dialog", name="Manual Selection")
            dialog.wait_for(state="visible")
            dialog.get_by_role("textbox", name="Port").fill(url)
            dialog.get_by_role("button", name="Connect", exact=True).click()
            dialog.wait_for(state="hidden")
        self._wait_connected(sockets_before, timeout_s)

    def reconnect(self, *, timeout_s: float = 20.0) -> None:
        """Click Connect again: after a disconnect it shows the last URL and connects to it.

        After a reboot (leaving the CLI, ``save``) the app keeps a timer: 1.5 s after the
        reboot request it drops whatever link is open as stale ("Dropping stale link for
        reboot (flush timeout)"), so a Connect within 1.5 s is undone.  A user is rarely that
        quick; this waits for the page timer set at the disconnect, which fires after the app's.
        """
        button = self._connect_button()
        button.wait_for(state="visible")
        self.page.evaluate("() => window.__bfsitlRebootTimerPassed")
        sockets_before = len(self.sockets)
        button.click()
        self._wait_connected(sockets_before, timeout_s)

    def _wait_connected(self, sockets_before: int, timeout_s: float) -> None:
        """Until Setup shows the firmware; fails early when the WebSocket the click opened
        closes first (refused, or the app gave a failed handshake up after ~10 s)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.is_connected() and self._text("#firmware-version-value"):
                self._in_cli = False
                return
            opened = self.sockets[sockets_before:]
            if opened and all(s.closed for s in opened) and not self.is_connected():
                raise ConfiguratorAppError(
                    f"the app's WebSocket to {opened[-1].url} closed before it was connected "
                    f"({len(opened[-1].received)} B received); the Connect control says "
                    f"{self.connect_label()!r}{self._console_tail()}\n(a SITL left in CLI mode "
                    f"by an earlier client answers no MSP, and the app gives up after 10 s)"
                )
            self.page.wait_for_timeout(100)
        raise ConfiguratorAppError(
            f"not connected within {timeout_s:.0f} s; the Connect control says "
            f"{self.connect_label()!r}{self._console_tail()}"
        )

    def wait_disconnected(self, *, timeout_s: float = 15.0) -> None:
        """Until the Connect control offers to connect again (after a reboot or a lost link)."""
        try:
            self._connect_button().wait_for(state="visible", timeout=timeout_s * 1000)
        except _playwright_timeout() as exc:
            raise ConfiguratorAppError(
                f"still connected after {timeout_s:.0f} s: {self.connect_label()!r}"
                f"{self._console_tail()}"
            ) from exc
        self._in_cli = False
        # Set after the app's own 1.5 s reboot timer (if a reboot started it), and longer.
        self.page.evaluate(f"""() => {{ window.__bfsitlRebootTimerPassed =
            new Promise((resolve) => setTimeout(resolve, {REBOOT_TIMER_MS + 250})); }}""")

    def disconnect(self) -> None:
        """Press Disconnect (in the CLI tab this sends ``exit`` first: the SITL reboots)."""
        self._disconnect_button().click()
        self.wait_disconnected()

    # -- tabs ----------------------------------------------------------------------------------

    def _tab_button(self, name: str) -> Locator:
        return self.page.locator("nav").get_by_role("button", name=name, exact=True)

    def tabs(self) -> list[str]:
        return [t.strip() for t in self.page.locator("nav").get_by_role("button").all_inner_texts()]

    def active_tab(self) -> str:
        return self.page.locator("nav [aria-current=page]").inner_text().strip()

    def open_tab(self, name: str) -> None:
        """Click the sidebar tab ``name`` ("Setup", "Motors", "CLI"...) and wait until it is
        the active one and its content is there (its title).  Not from the CLI tab: leaving it
        reboots the SITL (:meth:`leave_cli`)."""
        if name == "CLI":
            self.open_cli()
            return
        if self._in_cli:
            raise ConfiguratorAppError(
                f"in the CLI tab, clicking {name!r} sends `exit` (the SITL reboots, the app "
                f"disconnects): call leave_cli() for that"
            )
        button = self._tab_button(name)
        button.click()
        _expect(button).to_have_attribute("aria-current", "page")
        # Most tabs title their content with their name (not Autotune, Blackbox Viewer).
        title = self.page.locator("#content .tab_title")
        started = time.monotonic()
        while time.monotonic() - started < self.timeout_s:
            titles = [text.strip() for text in title.all_inner_texts()]
            if name in titles or (not titles and time.monotonic() - started > 1.0):
                return
            self.page.wait_for_timeout(50)
        raise ConfiguratorAppError(
            f"the {name!r} tab did not show; the content's title is "
            f"{title.all_inner_texts()}{self._console_tail()}"
        )

    # -- Setup ---------------------------------------------------------------------------------

    def _text(self, selector: str) -> str:
        """The element's text now, "" if there is none (no waiting)."""
        text = self.page.evaluate(
            "(selector) => document.querySelector(selector)?.innerText ?? ''", selector
        )
        return str(text).strip()

    def _setup_value(self, element_id: str) -> str:
        if self.active_tab() != "Setup":
            self.open_tab("Setup")
        locator = self.page.locator(f"#{element_id}")
        _expect(locator).not_to_have_text(re.compile(r"^\s*$"))
        return locator.inner_text().strip()

    def firmware_text(self) -> str:
        """Setup > Firmware info > Firmware, e.g. "BTFL 4.6.0"."""
        return self._setup_value("firmware-version-value")

    def api_version_text(self) -> str:
        """Setup > Firmware info > MSP API, e.g. "1.47.0"."""
        return self._setup_value("api-version-value")

    def board_text(self) -> str:
        """Setup > Firmware info > Board, e.g. "SITL"."""
        return self._setup_value("board-name-value")

    def attitude(self) -> Attitude:
        """The Setup tab's Yaw (heading), Pitch and Roll beside the 3D model, in degrees."""
        if self.active_tab() != "Setup":
            self.open_tab("Setup")
        texts = self.page.evaluate(
            """() => ['heading', 'pitch', 'roll'].map((axis) => document
                   .querySelector(`#canvas_wrapper .attitude_info dd.${axis}`)?.textContent)"""
        )
        return Attitude(*(_number(text, "attitude") for text in texts))

    def motor_values(self) -> list[int]:
        """The Motors tab's value above each motor's bar, in motor order.

        This build shows the FC's live motor outputs there only in motor test mode ("I
        understand the risks", which enables arming over MSP); otherwise every bar shows the
        disarmed value (``motor_stop``/min command, 1000), in flight too.  For a reading that
        moves while the quad flies use :meth:`attitude` or :meth:`rc_channels`.
        """
        if self.active_tab() != "Motors":
            self.open_tab("Motors")
        # The bars come once the tab has read the mixer (how many motors) from the FC.
        self.page.locator(".motors > ul:nth-of-type(2) > li > div").first.wait_for()
        texts = self.page.evaluate(
            """() => [...document.querySelectorAll('.motors > ul:nth-of-type(2) > li')]
                   .map((li) => li.querySelector(':scope > div')?.textContent)
                   .filter((text) => text !== undefined)"""
        )
        return [int(_number(text, "motor value")) for text in texts]

    def rc_channels(self) -> dict[str, int]:
        """The Receiver tab's channel bars, live from MSP_RC: {"Roll": 1500, "Pitch": ...,
        "Throttle": 885, "AUX 1": ...} (the map's letters, " [A]", dropped).  In failsafe (no
        RC) the tab shows the failsafe values."""
        if self.active_tab() != "Receiver":
            self.open_tab("Receiver")
        names = self.page.locator("#content .bars li.name")
        names.first.wait_for()
        pairs = self.page.evaluate(
            """() => [...document.querySelectorAll('#content .bars li.name')]
                   .map((li) => [li.textContent, li.nextElementSibling?.innerText])"""
        )
        return {
            re.sub(r"\s*\[\w\]\s*$", "", name.strip()): int(_number(value, name))
            for name, value in pairs
        }

    def _sample(self, read: Any, seconds: float, interval_s: float) -> list[Any]:
        read()  # the tab is there, with its data
        samples: list[Any] = []
        start = time.monotonic()
        while True:
            samples.append((time.monotonic() - start, read()))
            if samples[-1][0] >= seconds:
                return samples
            self.page.wait_for_timeout(interval_s * 1000)

    def sample_attitudes(self, seconds: float, interval_s: float = 0.2) -> list[Attitude]:
        """Readings of :meth:`attitude` every ``interval_s`` for ``seconds`` (``t`` set)."""
        return [
            Attitude(a.heading, a.pitch, a.roll, round(t, 3))
            for t, a in self._sample(self.attitude, seconds, interval_s)
        ]

    def sample_rc(self, seconds: float, interval_s: float = 0.2) -> list[dict[str, int]]:
        """Readings of :meth:`rc_channels` every ``interval_s`` for ``seconds``."""
        return [reading for _t, reading in self._sample(self.rc_channels, seconds, interval_s)]

    def sample_motors(self, seconds: float, interval_s: float = 0.2) -> list[list[int]]:
        """Readings of :meth:`motor_values` every ``interval_s`` for ``seconds``."""
        return [reading for _t, reading in self._sample(self.motor_values, seconds, interval_s)]

    # -- CLI -----------------------------------------------------------------------------------

    def _cli_output(self) -> Locator:
        return self.page.locator(".cli-window .cli-wrapper")

    def _cli_input(self) -> Locator:
        return self.page.locator("textarea[name=commands]")

    def cli_text(self) -> str:
        """Everything the CLI tab's output window shows."""
        return self._cli_output().inner_text()

    def open_cli(self, *, timeout_s: float = 15.0) -> str:
        """Open the CLI tab; wait for "Entering CLI Mode" and for the app's autocomplete cache
        (it runs help, dump, get and mixer list first, the input disabled meanwhile).
        Returns the output window's text."""
        self._tab_button("CLI").click()
        self._in_cli = True
        deadline = time.monotonic() + timeout_s
        entered_at: float | None = None
        while time.monotonic() < deadline:
            text = self._text(".cli-window .cli-wrapper")
            if "Entering CLI Mode" in text:
                entered_at = entered_at or time.monotonic()
                building = "Building AutoComplete Cache" in text
                built = re.search(r"AutoComplete Cache \.\.\. (Done|Failed|Cancelled)!", text)
                quiet = not building and time.monotonic() - entered_at > 1.5
                if (built or quiet) and self._cli_input().is_enabled():
                    return text
            self.page.wait_for_timeout(100)
        raise ConfiguratorAppError(
            f"the CLI tab was not ready within {timeout_s:.0f} s; it shows "
            f"{self._text('.cli-window .cli-wrapper')[-300:]!r}"
            f"{self._console_tail()}"
        )

    def _cli_socket(self) -> _Socket:
        open_sockets = [s for s in self.sockets if not s.closed]
        if not open_sockets:
            raise ConfiguratorAppError("the app has no open WebSocket (not connected?)")
        return open_sockets[-1]

    def _type_command(self, command: str) -> None:
        field_ = self._cli_input()
        _expect(field_).to_be_enabled()
        field_.fill(command)
        field_.press("Enter")

    def cli(self, command: str, *, timeout_s: float = 10.0) -> str:
        """Type ``command`` in the CLI tab and return the output it shows, without the echoed
        command line.  Done when the firmware's prompt (``\\r\\n# ``) has come back over the
        WebSocket and the output window shows the answer's last line."""
        if not self._in_cli:
            self.open_cli()
        socket = self._cli_socket()
        before_raw = len(socket.received)
        before = self.cli_text()
        self._type_command(command)
        deadline = time.monotonic() + timeout_s
        prompt_at = -1  # how much had come when the prompt was last seen at the end
        while time.monotonic() < deadline:
            raw = bytes(socket.received[before_raw:]).decode("utf-8", "replace")
            # A prompt at the end that stays there for one more poll: output such as `dump`'s
            # "# comment" lines may be cut by a frame boundary right after a "# ".
            settled = raw.endswith("\r\n# ") and prompt_at == len(raw)
            prompt_at = len(raw) if raw.endswith("\r\n# ") else -1
            if settled:
                answer = [ln for ln in raw[: -len("\r\n# ")].split("\r\n") if ln.strip()]
                shown = self.cli_text()[len(before) :]
                if not answer or answer[-1].strip() in shown:
                    return _strip_echo(shown, command)
            if socket.closed:
                raise ConfiguratorAppError(
                    f"the connection closed after {command!r} (a reboot?); the SITL sent "
                    f"{raw[-300:]!r}"
                )
            self.page.wait_for_timeout(80)
        raise ConfiguratorAppError(
            f"no prompt after {command!r} within {timeout_s:.0f} s; the CLI shows "
            f"{self.cli_text()[len(before) :][-300:]!r}"
        )

    def cli_save(self, *, timeout_s: float = 15.0) -> str:
        """Type ``save`` in the CLI: the SITL writes eeprom.bin and reboots, which ends the
        connection; waits until the app offers Connect again.  Returns what the SITL sent."""
        if not self._in_cli:
            self.open_cli()
        socket = self._cli_socket()
        before_raw = len(socket.received)
        self._type_command("save")
        self.wait_disconnected(timeout_s=timeout_s)
        return bytes(socket.received[before_raw:]).decode("utf-8", "replace")

    def leave_cli(self, to: str = "Setup", *, timeout_s: float = 15.0) -> None:
        """Click another tab while in the CLI: the app sends ``exit``, the SITL reboots (its
        process ends) and the app ends up disconnected, offering Connect for the same URL."""
        self._tab_button(to).click()
        self.wait_disconnected(timeout_s=timeout_s)

    # -- the rest ------------------------------------------------------------------------------

    def screenshot(self, path: Path | str) -> Path:
        """The window as the user sees it, as PNG; returns the path."""
        target = Path(path)
        target.parent.mkdir(parents=True, exist_ok=True)
        self.page.screenshot(path=str(target))
        return target

    def close(self) -> None:
        """Leave the CLI if in it (so the SITL is not left in CLI mode), then close the page's
        browser context."""
        with contextlib.suppress(Exception):
            if self._in_cli and self.is_connected():
                self.leave_cli(timeout_s=5.0)
        self.page.context.close()

    def _console_tail(self, lines: int = 12) -> str:
        noise = ("Failed to load resource", "Loading progress", "[Sponsor]", "GL Driver")
        tail = [
            line.splitlines()[0]
            for line in self.console
            if line.strip() and not any(n in line for n in noise)
        ][-lines:]
        return "\n  app console:\n    " + "\n    ".join(tail) if tail else ""


@contextlib.contextmanager
def open_configurator(
    browser: Browser, app_url: str, *, timeout_s: float = 15.0, service_workers: str = "block"
) -> Iterator[ConfiguratorPage]:
    """A new browser context (fresh settings, English UI, 1400x900) with the app loaded.

    Requests to anything but this machine are aborted at once.  ``service_workers="allow"``
    lets the app precache itself as it would for a user (slower; see the module's notes).
    """
    context = browser.new_context(
        viewport={"width": 1400, "height": 900}, locale="en-US", service_workers=service_workers
    )  # type: ignore[arg-type]
    context.route(_REMOTE_REQUEST, lambda route: route.abort())
    app = ConfiguratorPage(context.new_page(), app_url, timeout_s=timeout_s)
    try:
        app.load()
        yield app
    finally:
        app.close()


# --- watching a flight ----------------------------------------------------------------------


@dataclass(frozen=True)
class FlightWatch:
    """What the real app showed while connected during a flight.

    ``firmware``, ``api_version``, ``board``: Setup's Firmware info ("BTFL 4.6.0", "1.47.0",
    "SITL"); ``attitudes``: Setup's Yaw/Pitch/Roll readout sampled for ``seconds`` (``t``
    from the first sample); ``rc``: the Receiver tab's channels per sample (empty unless
    ``rc_seconds`` > 0); ``screenshot``: the Setup tab (3D model, attitude) at the end of its
    sampling, if a path was given.
    """

    firmware: str
    api_version: str
    board: str
    attitudes: list[Attitude]
    rc: list[dict[str, int]]
    screenshot: Path | None

    def attitude_span_deg(self) -> float:
        """The largest change of one attitude axis over the samples (heading wraps at 360)."""
        if len(self.attitudes) < 2:
            return 0.0
        spans = [
            max(v) - min(v)
            for v in ([a.pitch for a in self.attitudes], [a.roll for a in self.attitudes])
        ]
        headings = [a.heading for a in self.attitudes]
        spans.append(max(_angle_diff(h, headings[0]) for h in headings))
        return max(spans)

    def moved(self, threshold_deg: float = 0.5) -> bool:
        """Whether any attitude axis changed by more than ``threshold_deg``."""
        return self.attitude_span_deg() > threshold_deg


def watch_flight(
    ws_url: str,
    *,
    browser: Browser | None = None,
    app_url: str | None = None,
    dist: Path | None = None,
    seconds: float = 3.0,
    interval_s: float = 0.2,
    rc_seconds: float = 0.0,
    screenshot: Path | str | None = None,
    timeout_s: float = 20.0,
) -> FlightWatch:
    """Connect the real Configurator to ``ws_url`` as a user would, while the quad flies, and
    report what it shows: Setup's firmware, API and board; Setup's attitude readout sampled
    every ``interval_s`` for ``seconds``; a screenshot of Setup (``screenshot``: a .png path);
    with ``rc_seconds`` > 0, the Receiver tab's RC channels sampled as long (Throttle moves
    with the flight).  Then Disconnect, and close the page (its own browser context).

    Takes about 4 s plus the sampling.  In a test, pass the fixtures:
    ``browser=request.getfixturevalue("configurator_browser")`` and
    ``app_url=request.getfixturevalue("configurator_app_url")`` - a second ``sync_playwright``
    cannot start while the fixture's runs.  Without them it launches its own Chromium and
    serves ``dist`` (default: ``$BFSITL_CONFIGURATOR_DIST``).

    Not the Motors tab: this build shows live motor outputs there only in motor test mode (see
    :meth:`ConfiguratorPage.motor_values`).  What the app sends: at connect MSP_SET_RTC and
    MSP_SET_ARMING_DISABLED(1), which SITL builds ignore (an armed SITL stays armed; a real FC
    would disarm), then read-only requests (Setup polls attitude every 33 ms).
    """
    with contextlib.ExitStack() as stack:
        if browser is None:
            browser = stack.enter_context(launch_chromium())
        if app_url is None:
            if dist is None:
                dist = _dist_from_env()
            app_url = stack.enter_context(StaticServer(dist)).url
        app = stack.enter_context(open_configurator(browser, app_url, timeout_s=timeout_s))
        app.enable_expert_mode()
        app.connect(ws_url, timeout_s=timeout_s)
        firmware, api, board = app.firmware_text(), app.api_version_text(), app.board_text()
        attitudes = app.sample_attitudes(seconds, interval_s)
        shot = app.screenshot(screenshot) if screenshot is not None else None
        rc = app.sample_rc(rc_seconds, interval_s) if rc_seconds > 0 else []
        app.disconnect()
        return FlightWatch(firmware, api, board, attitudes, rc, shot)


# --- small helpers --------------------------------------------------------------------------


def _playwright_timeout() -> type[Exception]:
    from playwright.sync_api import TimeoutError as PlaywrightTimeoutError

    return PlaywrightTimeoutError


def _expect(locator: Locator) -> Any:
    from playwright.sync_api import expect

    return expect(locator)


def _local_host(url: str) -> bool:
    return re.match(r"^https?://(127\.0\.0\.1|localhost)[:/]", url) is not None


def _angle_diff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def _number(text: str | None, what: str) -> float:
    match = _NUMBER.search(text or "")
    if match is None:
        raise ConfiguratorAppError(f"no number in the {what} {text!r}")
    return float(match.group())


def _strip_echo(shown: str, command: str) -> str:
    """The output after the echoed ``# command`` line, trailing blank lines dropped."""
    lines = shown.split("\n")
    for index, line in enumerate(lines):
        if line.strip().lstrip("#").strip() == command.strip():
            lines = lines[index + 1 :]
            break
    return "\n".join(lines).rstrip()


def _xpath_string(text: str) -> str:
    if "'" not in text:
        return f"'{text}'"
    if '"' not in text:
        return f'"{text}"'
    parts = text.split("'")
    return "concat(" + ', "\'", '.join(f"'{part}'" for part in parts) + ")"
