"""`--speed max`, the lockstep switch and the build option, without a SITL."""

from __future__ import annotations

import argparse
import math

import pytest

from bfsitl.build.binary_scan import LOCKSTEP_MARKER, binary_traits, clear_cache
from bfsitl.build.lockstep import MARKER
from bfsitl.cli.arg_types import parse_speed


def test_speed_takes_a_positive_number_or_max() -> None:
    assert parse_speed("max") == math.inf and parse_speed("MAX") == math.inf
    assert parse_speed("2.5") == 2.5
    for bad in ("0", "-1", "fast", "inf", "nan"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_speed(bad)


def test_the_binary_scan_finds_the_lockstep_marker(tmp_path) -> None:
    assert LOCKSTEP_MARKER == MARKER.encode()
    plain, patched = tmp_path / "plain", tmp_path / "patched"
    plain.write_bytes(b"\x00" * 64 + b"--ip <address>\x00")
    patched.write_bytes(b"\x00" * 64 + MARKER.encode() + b": FC time follows\x00")
    clear_cache()
    assert not binary_traits(plain).lockstep and binary_traits(plain).takes_ip_flag
    assert binary_traits(patched).lockstep and not binary_traits(patched).takes_ip_flag
