"""The planned frame decoder against orangebox's own: the same numbers from the same bytes.

Every log at hand is decoded both ways and compared frame by frame and event by event (the
SITL logs in tests/data whole, the real logs beside the clone up to a few thousand frames);
each encoding's reader is compared with orangebox's decoder on random bytes, since the logs
do not use every branch of every encoding.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from orangebox.decoders import decoder_map
from orangebox.reader import Reader
from support.real_logs import real_log_files

from bfsitl.blackbox.events import EventKeepingParser
from bfsitl.blackbox.frame_plan import (
    _NEG_14BIT,
    _SIGNED_VB,
    _TAG2_3S32,
    _TAG8_4S16,
    _TAG8_8SVB,
    _UNSIGNED_VB,
    FramePlan,
    _read,
)

DATA = Path(__file__).resolve().parents[2] / "data" / "blackbox"
SITL_LOGS = sorted(DATA.glob("*.BF*"))
#: Enough of a real log to meet every frame type it has, many times.
REAL_FRAMES = 3000


def _decoded(path: Path, index: int, planned: bool, limit: int | None) -> tuple[Any, ...]:
    parser = EventKeepingParser(Reader(str(path), log_index=index), planned=planned)
    frames = []
    ended = None
    try:
        for frame in parser.frames():
            frames.append(frame.data)
            if limit is not None and len(frames) >= limit:
                break
    except (TypeError, IndexError) as exc:  # a log cut short: orangebox reads None, the
        ended = "cut"  # plan past the end of the bytes; both keep the frames before
        assert "None" in str(exc) or isinstance(exc, IndexError)
    return tuple(frames), parser.kept, ended, parser._plans


def _log_count(path: Path) -> int:
    return len(Reader(str(path)).log_pointers)


def _compare(path: Path, limit: int | None) -> int:
    compared = 0
    for index in range(1, _log_count(path) + 1):
        plain = _decoded(path, index, planned=False, limit=limit)
        planned = _decoded(path, index, planned=True, limit=limit)
        assert planned[:3] == plain[:3], f"{path.name} log {index}"
        assert planned[3] and all(plan is not None for plan in planned[3].values())
        compared += len(plain[0])
    return compared


@pytest.mark.parametrize("path", SITL_LOGS, ids=lambda p: p.name)
def test_every_sitl_log_decodes_to_orangebox_s_frames(path):
    assert _compare(path, None) > 0


def test_the_real_logs_decode_to_orangebox_s_frames():
    files = real_log_files()
    if not files:
        pytest.skip("no real blackbox logs beside the clone (set BFSITL_REAL_LOGS)")
    assert sum(_compare(path, REAL_FRAMES) for path in files) > len(files) * 1000


def test_a_log_cut_inside_a_frame_keeps_the_frames_before_the_cut():
    frames, _events, ended, _plans = _decoded(DATA / "plain-4.6.0-cut.BF", 1, True, None)
    assert ended == "cut" and len(frames) > 100


def test_a_frame_type_whose_encodings_it_does_not_read_is_left_to_orangebox():
    def field(encoding: int) -> SimpleNamespace:
        decoder = decoder_map[encoding]
        return SimpleNamespace(decoderfun=decoder, predictorfun=None)

    assert FramePlan.of([field(0), field(10)], ctx=None) is None  # tag2_3svariable: a TODO
    # A tag8_8svb group reaching the end of the frame: orangebox ends it a field early.
    assert FramePlan.of([field(0), field(6), field(6)], ctx=None) is None


class _Counting:
    """orangebox's decoders read with next(); this counts the bytes they took."""

    def __init__(self, data: bytes) -> None:
        self._bytes: Iterator[int] = iter(data)
        self.taken = 0

    def __iter__(self) -> _Counting:
        return self

    def __next__(self) -> int:
        self.taken += 1
        return next(self._bytes)


PADDING = bytes(40)  # neither side runs out: the longest reading is 4 x 5 varint bytes


@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=1, max_size=24))
def test_each_encoding_reads_what_orangebox_reads(data):
    padded = data + PADDING
    for what, encoding, count in (
        (_SIGNED_VB, 0, 1),
        (_UNSIGNED_VB, 1, 1),
        (_NEG_14BIT, 3, 1),
        (_TAG2_3S32, 7, 3),
    ):
        stream = _Counting(padded)
        try:
            theirs = decoder_map[encoding](stream, None)
        except struct.error:  # orangebox's 14-bit sign extension of a varint over 32 bits
            with pytest.raises(struct.error):
                _read(((what, count),), padded, 0)
            continue
        ours, end = _read(((what, count),), padded, 0)
        assert ours == (list(theirs) if isinstance(theirs, tuple) else [theirs])
        assert end == stream.taken
    stream = _Counting(padded)
    theirs = decoder_map[8](2)(stream, None)
    ours, end = _read(((_TAG8_4S16, 4),), padded, 0)
    assert (ours, end) == (list(theirs), stream.taken)


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=1, max_size=48), st.integers(2, 8))
def test_a_tag8_8svb_group_reads_what_orangebox_reads(data, count):
    padded = data + PADDING
    # orangebox counts the group from the field definitions after the current one.
    fields = [SimpleNamespace(encoding=6)] * count + [SimpleNamespace(encoding=0)]
    ctx = SimpleNamespace(
        frame_type="P", field_index=0, field_def_counts={"P": len(fields)}, field_defs={"P": fields}
    )
    stream = _Counting(padded)
    theirs = decoder_map[6](stream, ctx)
    ours, end = _read(((_TAG8_8SVB, count),), padded, 0)
    assert (ours, end) == (list(theirs), stream.taken)
