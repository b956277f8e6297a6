"""The physics flies the recorded flights bit for bit (tests/support/physics_golden.py): every
state, reading and error of thirteen scripts that take every branch of the step, against the
digests written with the model as it was when its C source became the only one."""

from __future__ import annotations

import json

import pytest
from support.physics_golden import CHECKPOINT, GOLDEN_PATH, SCRIPTS, summary

GOLDEN = json.loads(GOLDEN_PATH.read_text())


def test_every_script_is_recorded() -> None:
    assert sorted(GOLDEN) == sorted(SCRIPTS)


@pytest.mark.parametrize("name", sorted(SCRIPTS))
def test_the_recorded_flight_repeats_bit_for_bit(name: str) -> None:
    flown, recorded = summary(SCRIPTS[name]()), GOLDEN[name]
    assert flown["records"] == recorded["records"]
    parted = next(
        (
            i
            for i, (a, b) in enumerate(
                zip(flown["checkpoints"], recorded["checkpoints"], strict=True)
            )
            if a != b
        ),
        None,
    )
    assert parted is None, (
        f"{name}: the flight parts from the recording within records "
        f"{parted * CHECKPOINT}..{(parted + 1) * CHECKPOINT}"
    )
    assert flown["last_state"] == recorded["last_state"]


def test_the_comparison_can_tell() -> None:
    # One bit of one state float changes the digests (the check is not vacuous).
    recorder = SCRIPTS["other_number_types"]()
    honest = summary(recorder)
    recorder.records[5] = bytes([recorder.records[5][0] ^ 1]) + recorder.records[5][1:]
    assert summary(recorder)["checkpoints"] != honest["checkpoints"]
