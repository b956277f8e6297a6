"""The compiled frame decoder against the Python one: the same frames, events and ends from the
same bytes, and the Python road wherever the kernel is not sure.

Every SITL log in tests/data is decoded both ways (the kernel must have decoded each that
ends with LOG_END: a kernel that always gave up would pass the comparison); damaged copies
(bytes changed, the file cut) must decode alike too, whether the kernel gives up on them or
not; each encoding's reader is compared with FramePlan's on random bytes.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from orangebox.reader import Reader
from support.real_logs import real_log_files

from bfsitl.blackbox import compiled_frames, decode
from bfsitl.blackbox.events import EventKeepingParser
from bfsitl.blackbox.frame_plan import (
    _NEG_14BIT,
    _NULL,
    _SIGNED_VB,
    _TAG2_3S32,
    _TAG8_4S16,
    _TAG8_8SVB,
    _UNSIGNED_VB,
    _read,
)
from bfsitl.errors import KernelUnavailableError
from bfsitl.kernel.compiler import kernel_available

pytestmark = pytest.mark.skipif(not kernel_available(), reason="no C compiler for the kernel")

DATA = Path(__file__).resolve().parents[2] / "data" / "blackbox"
SITL_LOGS = sorted(DATA.glob("*.BF*"))
#: The two logs of tests/data that end without LOG_END (a SITL killed armed, a file cut).
CUT_SHORT = {"killed-master.BFL", "plain-4.6.0-cut.BF"}
#: Real logs up to this size are decoded whole both ways (the larger take seconds each).
REAL_LOG_BYTES = 1_000_000


def _in_python(path: Path, monkeypatch: pytest.MonkeyPatch) -> list[decode.BlackboxLog]:
    with monkeypatch.context() as patch:
        patch.setattr(decode, "compiled_log", lambda parser: None)
        return decode.decode_blackbox(path)


def _assert_same(path: Path, monkeypatch: pytest.MonkeyPatch) -> list[bool]:
    """Decode ``path`` both ways and compare; which of its logs the kernel decoded."""
    compiled = decode.decode_blackbox(path)
    python = _in_python(path, monkeypatch)
    assert len(compiled) == len(python)
    for ours, theirs in zip(compiled, python, strict=True):
        assert ours.frames == theirs.frames
        assert ours.events == theirs.events
        assert (ours.truncated, ours.disarm_reason) == (theirs.truncated, theirs.disarm_reason)
    return [
        compiled_frames.compiled_log(EventKeepingParser(Reader(str(path), log_index=index)))
        is not None
        for index in range(1, len(compiled) + 1)
    ]


@pytest.mark.parametrize("path", SITL_LOGS, ids=lambda p: p.name)
def test_every_sitl_log_decodes_to_the_python_decoder_s_frames(path, monkeypatch):
    used = _assert_same(path, monkeypatch)
    assert used == [path.name not in CUT_SHORT] * len(used)


def test_the_real_logs_decode_alike(monkeypatch):
    files = [path for path in real_log_files() if path.stat().st_size <= REAL_LOG_BYTES]
    if not files:
        pytest.skip("no small real blackbox log beside the clone (set BFSITL_REAL_LOGS)")
    for path in files:
        _assert_same(path, monkeypatch)


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    st.sampled_from(["drop-4.6.0.BF", "plain-master.BFL", "switch-landing-master.BFL"]),
    st.lists(st.tuples(st.floats(0.2, 1.0), st.integers(0, 255)), min_size=1, max_size=4),
    st.one_of(st.none(), st.floats(0.2, 1.0)),
)
def test_a_damaged_log_decodes_alike(monkeypatch, tmp_path_factory, name, changes, cut):
    data = bytearray((DATA / name).read_bytes())
    frames_start = data.index(b"\nI") + 1  # damage the frames, not the headers
    for where, value in changes:
        data[frames_start + int(where * (len(data) - frames_start - 1))] = value
    if cut is not None:
        data = data[: frames_start + int(cut * (len(data) - frames_start))]
    path = tmp_path_factory.mktemp("damaged") / name
    path.write_bytes(bytes(data))
    _assert_same(path, monkeypatch)


def test_the_arrays_are_as_large_as_the_log_and_no_larger():
    """A counting pass first, then arrays of just that size (a guess from the bytes would
    have been hundreds of MB for a long real log)."""
    path = DATA / "drop-4.6.0.BF"
    (log,) = decode.decode_blackbox(path)
    compiled = compiled_frames.compiled_log(EventKeepingParser(Reader(str(path), log_index=1)))
    assert compiled is not None
    assert compiled.main.base is not None and compiled.main.base.shape[0] == len(log.frames)
    assert len(compiled.kept) == len(log.events) > 0


def test_without_a_compiled_kernel_the_log_is_decoded_in_python(monkeypatch):
    def unavailable() -> None:
        raise KernelUnavailableError("no C compiler")

    path = DATA / "plain-4.6.0.BF"
    expected = decode.decode_blackbox(path)
    monkeypatch.setattr(compiled_frames, "_kernel_function", unavailable)
    parser = EventKeepingParser(Reader(str(path), log_index=1))
    assert compiled_frames.compiled_log(parser) is None
    assert decode.decode_blackbox(path)[0].frames == expected[0].frames


PADDING = bytes(40)  # neither side runs out: the longest reading is 4 x 5 varint bytes


@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=1, max_size=48), st.integers(1, 8))
def test_each_encoding_reads_what_the_python_plan_reads(data, count):
    padded = data + PADDING
    for steps in (
        ((_SIGNED_VB, count),),
        ((_UNSIGNED_VB, 1),),
        ((_NEG_14BIT, 1),),
        ((_TAG2_3S32, 3),),
        ((_TAG8_4S16, 4),),
        ((_TAG8_8SVB, count),),
        ((_NULL, 1), (_UNSIGNED_VB, 1)),
    ):
        try:
            expected = _read(steps, padded, 0)
        except struct.error:  # orangebox's 14-bit sign extension of a varint over 32 bits
            assert compiled_frames._read_raw(steps, padded, 0) is None
            continue
        assert compiled_frames._read_raw(steps, padded, 0) == expected
        # Cut anywhere inside the frame, the kernel says so (Python raises IndexError).
        assert compiled_frames._read_raw(steps, padded[: expected[1] - 1], 0) is None
