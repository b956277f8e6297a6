"""What a SITL process says its binary was built with: a 4.6.0 lockstep build that can count
receiver frames counts them only when its environment asks, and the firmware profile (which
the fault catalogue reads: rc_loss's ``auto``) follows what the process was asked."""

from __future__ import annotations

from pathlib import Path

import pytest

from bfsitl.build import metadata
from bfsitl.build.binary_scan import RX_FRAMES_ENV
from bfsitl.protocol.firmware_profile import BuildOptions, profile_for
from bfsitl.sitl.firmware import FirmwareBinary
from bfsitl.sitl.process import SitlProcess


@pytest.fixture
def counting_build(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> FirmwareBinary:
    path = tmp_path / "betaflight_4.6.0_SITL"
    path.write_bytes(b"\x00")
    monkeypatch.setattr(
        metadata,
        "build_options_for_binary",
        lambda _path: BuildOptions(gps=True, receiver_frames=True),
    )
    monkeypatch.delenv(RX_FRAMES_ENV[0], raising=False)
    return FirmwareBinary(path, "test")


def silence_after_s(process: SitlProcess) -> float | None:
    return profile_for("1.47", "4.6.0", process.build_options()).rc.rxloss_after_silence_s


def test_a_build_that_can_count_frames_counts_them_only_when_asked(
    counting_build: FirmwareBinary, tmp_path: Path
) -> None:
    asked = SitlProcess(counting_build, workdir=tmp_path / "a", env=dict([RX_FRAMES_ENV]))
    not_asked = SitlProcess(counting_build, workdir=tmp_path / "b", env={"OTHER": "1"})
    inherits = SitlProcess(counting_build, workdir=tmp_path / "c")
    assert asked.build_options() == BuildOptions(gps=True, receiver_frames=True)
    assert silence_after_s(asked) == pytest.approx(0.15)
    for process in (not_asked, inherits):
        assert process.build_options() == BuildOptions(gps=True, receiver_frames=None)
        assert silence_after_s(process) is None  # the stock receiver: no loss on silence


def test_the_variable_in_bfsitls_own_environment_counts_too(
    counting_build: FirmwareBinary, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(*RX_FRAMES_ENV)  # a process that inherits it is asked
    assert SitlProcess(counting_build, workdir=tmp_path).build_options() == BuildOptions(
        gps=True, receiver_frames=True
    )
