"""A run's flight controller started configured, from a state prepared once per build and
configuration (on bfsitl's own physics; with Gazebo the run configures the FC itself).

Every scenario run configures the FC before it flies: bfsitl's flight profile, the blackbox,
the simulated quad's hover throttle, the scenario's own lines, the GPS of a GPS build.  Some
of it is read at boot only (the blackbox's device and rate, the GPS port; and a filter or
any setting the firmware reads once at start-up without flagging a reboot), so that
configuration ended with a reboot, most of a run's start-up.  Now a SITL of its own is given
the configuration and stops, its ``eeprom.bin`` is kept in the cache, and each run with the
same build and configuration starts its SITL from a copy: configured at boot, nothing to
write, no reboot.  The run that finds none pays for making it, a little more than the reboot
(docs/scenarios.md#scale).

Every run takes that same way, whether the prepared state was in the cache or made for it,
so a run flies the same flight either way (tests/integration/test_scenarios_sitl.py compares
them byte for byte).  A leftover ``eeprom.bin`` from an earlier run into the same directory
is replaced: a run that started from the last one's configuration skipped the reboot and so
flew another flight than a run into a new directory.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from bfsitl.atomic_file import write_atomically
from bfsitl.cache_location import cache_root
from bfsitl.fc.firmware_detect import profile_of_binary
from bfsitl.fc.provisioning import Profile
from bfsitl.mission.session import FlightSession, SessionConfig
from bfsitl.protocol.firmware_profile import FirmwareProfile
from bfsitl.version import __version__

#: The SITL's own name for its saved configuration, in its run directory.
EEPROM_NAME = "eeprom.bin"
#: Under the cache: one prepared ``eeprom.bin`` per build, set-up and bfsitl version, named
#: ``<build>-<set-up>.bin``.
PREPARED_DIR = "prepared-fc"


def prepared_eeprom(
    binary: Path,
    firmware: FirmwareProfile,
    profile: Profile,
    prepare: Callable[[Path], None],
    *,
    cache: Path | None = None,
) -> Path | None:
    """The saved configuration of ``binary`` (``firmware``) provisioned with ``profile``:
    from the cache, or made now by ``prepare(run_dir)`` (which starts a SITL in ``run_dir``,
    provisions it and stops it) and kept.  None where ``prepare`` left no ``eeprom.bin``."""
    key = _key(binary, firmware, profile)
    kept = (cache or cache_root()) / PREPARED_DIR / f"{key}.bin"
    if kept.is_file():
        return kept
    with tempfile.TemporaryDirectory(prefix="bfsitl-prepare-") as where:
        run_dir = Path(where)
        prepare(run_dir)
        made = run_dir / EEPROM_NAME
        if not made.is_file():
            return None
        # Several runs side by side may make the same one: each writes it whole, the last wins.
        write_atomically(kept, made.read_bytes())
    return kept


def start_from(run_dir: Path, eeprom: Path | None) -> None:
    """``run_dir`` (a SITL's) without an earlier run's ``eeprom.bin``, with ``eeprom`` in its
    place if given."""
    run_dir.mkdir(parents=True, exist_ok=True)
    target = run_dir / EEPROM_NAME
    with contextlib.suppress(FileNotFoundError):
        target.unlink()
    if eeprom is not None:
        shutil.copyfile(eeprom, target)


def forget_prepared(binary: Path, *, cache: Path | None = None) -> int:
    """Delete every state prepared for ``binary`` (``bfsitl firmware clean NAME``, before
    the build goes); returns how many there were."""
    states = ((cache or cache_root()) / PREPARED_DIR).glob(f"{_binary_key(binary)}-*.bin")
    count = 0
    for state in states:
        with contextlib.suppress(FileNotFoundError):
            state.unlink()
            count += 1
    return count


def _key(binary: Path, firmware: FirmwareProfile, profile: Profile) -> str:
    """The build (a digest of its bytes, first, so that a build's states are found by
    name), then what is provisioned (the profile, and what the session adds for the build:
    its GPS and compass lines) with the bfsitl that provisions it."""
    digest = hashlib.sha256()
    digest.update(repr(firmware).encode())
    digest.update(repr(profile).encode())
    digest.update(__version__.encode())
    return f"{_binary_key(binary)}-{digest.hexdigest()[:16]}"


def _binary_key(binary: Path) -> str:
    return hashlib.sha256(binary.read_bytes()).hexdigest()[:16]


def fresh_run_dir(
    config: SessionConfig,
    prepared: bool,
    session_factory: Callable[..., FlightSession],
    say: Callable[[str], None],
) -> None:
    """A run's SITL directory (``config.sitl.workdir``) without an earlier run's
    configuration; ``prepared``: with the state ``config.fc.profile`` provisions in its
    place, from the cache or made first by a session of ``session_factory``'s in a directory
    of its own."""
    run_dir = Path(config.sitl.workdir or "")
    profile = config.fc.profile
    # Gazebo would be started only to configure the FC: there the run configures it itself.
    if not prepared or profile is None or config.world.physics != "embedded":
        start_from(run_dir, None)
        return
    assert config.sitl.firmware is not None  # a run names its binary
    binary = Path(config.sitl.firmware)
    firmware = profile_of_binary(binary)

    def prepare(where: Path) -> None:
        say("preparing the FC's configuration (once per build and configuration)")
        elsewhere = dataclasses.replace(
            config, sitl=dataclasses.replace(config.sitl, workdir=where)
        )
        with session_factory(elsewhere, progress=lambda line: say(f"[prepare] {line}")):
            pass

    start_from(run_dir, prepared_eeprom(binary, firmware, profile, prepare))
