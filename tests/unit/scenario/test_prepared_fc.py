"""The FC's configuration, prepared once per build and set-up and kept: when it is made,
when it is taken from the cache, and what a run directory starts from.  (The real SITL's:
a run from the cache and a run that made it fly the same flight,
tests/integration/test_scenarios_sitl.py.)"""

from __future__ import annotations

from pathlib import Path

from bfsitl.fc.provisioning import Profile
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE
from bfsitl.scenario.prepared_fc import (
    EEPROM_NAME,
    forget_prepared,
    prepared_eeprom,
    start_from,
)


class Preparer:
    """A ``prepare`` that writes what a provisioned SITL would save, and counts its calls."""

    def __init__(self, content: bytes = b"configured") -> None:
        self.content = content
        self.calls: list[Path] = []

    def __call__(self, run_dir: Path) -> None:
        self.calls.append(run_dir)
        (run_dir / EEPROM_NAME).write_bytes(self.content)


def _binary(tmp_path: Path, content: bytes = b"\x7fELF a build") -> Path:
    tmp_path.mkdir(parents=True, exist_ok=True)
    binary = tmp_path / "betaflight_SITL"
    binary.write_bytes(content)
    return binary


def test_it_is_made_once_and_then_taken_from_the_cache(tmp_path):
    prepare = Preparer()
    binary = _binary(tmp_path)
    profile = Profile(cli_lines=("set blackbox_sample_rate = 1/16",))
    first = prepared_eeprom(binary, DEFAULT_PROFILE, profile, prepare, cache=tmp_path / "c")
    again = prepared_eeprom(binary, DEFAULT_PROFILE, profile, prepare, cache=tmp_path / "c")
    assert first == again and first is not None and first.read_bytes() == b"configured"
    assert len(prepare.calls) == 1
    assert not prepare.calls[0].exists()  # the preparing SITL's directory is removed


def test_another_build_or_set_up_is_prepared_apart(tmp_path):
    prepare = Preparer()
    cache = tmp_path / "c"
    profile = Profile(cli_lines=("set blackbox_sample_rate = 1/16",))
    other_lines = Profile(cli_lines=("set blackbox_sample_rate = 1/8",))
    kept = {
        prepared_eeprom(_binary(tmp_path), DEFAULT_PROFILE, profile, prepare, cache=cache),
        prepared_eeprom(_binary(tmp_path), DEFAULT_PROFILE, other_lines, prepare, cache=cache),
        prepared_eeprom(
            _binary(tmp_path, b"rebuilt"), DEFAULT_PROFILE, profile, prepare, cache=cache
        ),
    }
    assert len(kept) == 3 and len(prepare.calls) == 3


def test_forgetting_a_build_deletes_its_states_and_no_other_build_s(tmp_path):
    """``bfsitl firmware clean NAME`` left that build's states behind."""
    prepare = Preparer()
    cache = tmp_path / "c"
    going, staying = _binary(tmp_path / "a", b"going"), _binary(tmp_path / "b", b"staying")
    first = Profile(cli_lines=("set blackbox_sample_rate = 1/16",))
    second = Profile(cli_lines=("set blackbox_sample_rate = 1/8",))
    gone = [
        prepared_eeprom(going, DEFAULT_PROFILE, p, prepare, cache=cache) for p in (first, second)
    ]
    kept = prepared_eeprom(staying, DEFAULT_PROFILE, first, prepare, cache=cache)
    assert forget_prepared(going, cache=cache) == 2
    assert all(state is not None and not state.exists() for state in gone)
    assert kept is not None and kept.is_file()
    assert forget_prepared(going, cache=cache) == 0


def test_a_preparation_that_saves_nothing_keeps_nothing(tmp_path):
    def prepare(_run_dir: Path) -> None:
        pass  # a SITL that never saved

    kept = prepared_eeprom(_binary(tmp_path), DEFAULT_PROFILE, Profile(), prepare, cache=tmp_path)
    assert kept is None
    assert not (tmp_path / "prepared-fc").exists()


def test_a_run_directory_loses_an_earlier_run_s_configuration(tmp_path):
    """A second run into the same --out started from the first one's eeprom.bin, skipped
    the reboot and flew another flight: now each starts from the prepared state, or none."""
    run_dir = tmp_path / "out" / "sitl"
    run_dir.mkdir(parents=True)
    (run_dir / EEPROM_NAME).write_bytes(b"the last run's")
    start_from(run_dir, None)
    assert not (run_dir / EEPROM_NAME).exists()
    prepared = tmp_path / "prepared.bin"
    prepared.write_bytes(b"shared")
    (run_dir / EEPROM_NAME).write_bytes(b"the last run's")
    start_from(run_dir, prepared)
    assert (run_dir / EEPROM_NAME).read_bytes() == b"shared"
    fresh = tmp_path / "new" / "sitl"
    start_from(fresh, prepared)
    assert (fresh / EEPROM_NAME).read_bytes() == b"shared"


def test_a_gazebo_run_configures_its_fc_itself(tmp_path):
    """Preparing would start Gazebo only to configure the FC."""
    from bfsitl.backend.options import World
    from bfsitl.mission.session import FcSetup, SessionConfig, SitlLaunch
    from bfsitl.scenario.prepared_fc import fresh_run_dir

    def no_session(*_args, **_kwargs):
        raise AssertionError("nothing is prepared for a Gazebo run")

    run_dir = tmp_path / "sitl"
    run_dir.mkdir()
    (run_dir / EEPROM_NAME).write_bytes(b"the last run's")
    config = SessionConfig(
        sitl=SitlLaunch(firmware=_binary(tmp_path), workdir=run_dir),
        fc=FcSetup(profile=Profile(cli_lines=("set blackbox_sample_rate = 1/16",))),
        world=World(physics="gazebo"),
    )
    fresh_run_dir(config, True, no_session, lambda _line: None)
    assert not (run_dir / EEPROM_NAME).exists()
