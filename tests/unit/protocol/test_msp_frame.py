"""MSP framing: byte-exact frames from the firmware's layouts, and a fuzzed parser."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bfsitl.errors import MspFrameError
from bfsitl.protocol.msp_frame import (
    MAX_REQUEST_PAYLOAD,
    ChecksumFailure,
    Direction,
    MspFrame,
    MspParser,
    MspVersion,
    crc8_dvb_s2,
    encode_frame,
    encode_request,
)


def frames_of(events):
    return [e for e in events if isinstance(e, MspFrame)]


# --- encoder, against byte strings written out by hand from msp_serial.c ---------------------


def test_v1_request_api_version_is_the_six_bytes_everyone_sends():
    assert encode_request(1) == b"$M<\x00\x01\x01"


def test_v1_request_with_payload_xors_size_command_and_payload():
    # SET_MODE_RANGE [0, 0, 0, 32, 48]: xor = 5 ^ 35 ^ 0 ^ 0 ^ 0 ^ 32 ^ 48
    frame = encode_request(35, bytes([0, 0, 0, 32, 48]))
    assert frame == b"$M<\x05\x23\x00\x00\x00\x20\x30" + bytes([5 ^ 35 ^ 32 ^ 48])


def test_crc8_dvb_s2_check_value():
    # The catalogued check value of CRC-8/DVB-S2 over "123456789".
    assert crc8_dvb_s2(b"123456789") == 0xBC


def test_v2_native_request_layout():
    frame = encode_request(0x3006, b"\x02")
    body = bytes([0, 0x06, 0x30, 1, 0, 2])
    assert frame == b"$X<" + body + bytes([crc8_dvb_s2(body)])


def test_v2_over_v1_wraps_a_v2_block_in_command_255():
    frame = encode_request(1, b"", MspVersion.V2_OVER_V1)
    inner = bytes([0, 1, 0, 0, 0])
    inner += bytes([crc8_dvb_s2(inner)])
    assert frame[:5] == b"$M<" + bytes([len(inner), 255])
    assert frame[5:-1] == inner


def test_request_payload_over_192_bytes_is_refused_in_every_version():
    for version in (None, MspVersion.V1, MspVersion.V2, MspVersion.V2_OVER_V1):
        with pytest.raises(MspFrameError, match="192"):
            encode_request(200, bytes(MAX_REQUEST_PAYLOAD + 1), version)
    assert encode_request(200, bytes(MAX_REQUEST_PAYLOAD))  # the limit itself is fine


def test_jumbo_requests_and_v2_ids_in_v1_are_refused():
    with pytest.raises(MspFrameError):
        encode_request(1, b"", MspVersion.V1_JUMBO)
    with pytest.raises(MspFrameError):
        encode_request(0x3006, b"", MspVersion.V1)


def test_default_version_is_v2_for_ids_above_254():
    assert encode_request(0x300C).startswith(b"$X<")


# --- parser --------------------------------------------------------------------------------


def test_parses_the_sitl_api_version_reply():
    (frame,) = MspParser().feed(b"$M>\x03\x01\x00\x01/,")
    assert frame == MspFrame(1, b"\x00\x01\x2f", Direction.REPLY, MspVersion.V1)


def test_error_reply_is_reported_as_error_frame():
    (frame,) = MspParser().feed(b"$M!\x00\x17\x17")
    assert frame.is_error and frame.command == 23 and frame.payload == b""


def test_jumbo_reply_is_reassembled():
    payload = bytes(range(256)) * 2  # 512 bytes
    wire = encode_frame(MspFrame(230, payload, Direction.REPLY, MspVersion.V1_JUMBO))
    assert wire[3] == 0xFF and wire[5:7] == (512).to_bytes(2, "little")
    (frame,) = MspParser().feed(wire)
    assert frame.version is MspVersion.V1_JUMBO and frame.payload == payload


def test_v2_over_v1_reply_is_unwrapped():
    wire = encode_frame(MspFrame(0x3006, b"\x02\x03abc", Direction.REPLY, MspVersion.V2_OVER_V1))
    (frame,) = MspParser().feed(wire)
    assert (frame.command, frame.payload, frame.version) == (
        0x3006,
        b"\x02\x03abc",
        MspVersion.V2_OVER_V1,
    )


def test_bad_checksum_is_reported_and_the_next_frame_still_parses():
    good = encode_frame(MspFrame(108, b"\x01\x00\x02\x00\x03\x00"))
    bad = bytearray(good)
    bad[-1] ^= 0xFF
    parser = MspParser()
    events = parser.feed(bytes(bad) + good)
    assert isinstance(events[0], ChecksumFailure) and events[0].command == 108
    assert frames_of(events) == [MspFrame(108, b"\x01\x00\x02\x00\x03\x00")]
    assert parser.checksum_failures == 1


def test_cli_text_is_skipped_and_kept_for_diagnostics():
    parser = MspParser()
    events = parser.feed(b"\r\n# get x\r\n" + encode_frame(MspFrame(1, b"\x00\x01\x2f")))
    assert len(frames_of(events)) == 1
    assert b"get x" in parser.recent_garbage()
    assert parser.garbage_bytes == len(b"\r\n# get x\r\n")


def test_garbage_header_claiming_a_huge_size_does_not_hide_later_frames_forever():
    good = encode_frame(MspFrame(1, b"\x00\x01\x2f"))
    parser = MspParser()
    # "$M>" + size 200 announces a frame that would swallow the good one behind it.
    assert parser.feed(b"$M>\xc8\x6c" + good) == []
    # A client that times out asks the parser to look behind the stalled header.
    assert frames_of(parser.flush_stalled()) == [MspFrame(1, b"\x00\x01\x2f")]


def test_absurd_v2_length_is_rejected_at_once():
    good = encode_frame(MspFrame(1, b"\x00\x01\x2f"))
    assert frames_of(MspParser().feed(b"$X>\x00\x01\x00\xff\xff" + good)) == [
        MspFrame(1, b"\x00\x01\x2f")
    ]


# --- fuzz ----------------------------------------------------------------------------------


def _make_frame(version: MspVersion, command: int, payload: bytes) -> MspFrame:
    # v1 carries ids 0..254 only (255 means "v2 inside"); v2 forms carry 16-bit ids.
    if version is MspVersion.V1:
        command %= 255
        if len(payload) >= 255:
            version = MspVersion.V1_JUMBO
    return MspFrame(command, payload, Direction.REPLY, version)


_frame_strategy = st.builds(
    _make_frame,
    st.sampled_from([MspVersion.V1, MspVersion.V2, MspVersion.V2_OVER_V1]),
    st.integers(0, 0xFFFF),
    st.binary(max_size=300),  # > 254 exercises jumbo framing
)


@settings(max_examples=300, deadline=None)
@given(
    frames=st.lists(_frame_strategy, min_size=1, max_size=6),
    garbage=st.lists(st.binary(max_size=40), min_size=7, max_size=7),
    splits=st.lists(st.integers(1, 64), max_size=30),
)
def test_fuzz_every_frame_after_garbage_is_found_in_any_split(frames, garbage, splits):
    # Garbage must not itself contain '$', which could legitimately start a frame that then
    # swallows a real one until flush_stalled(); that case is tested separately above.
    garbage = [g.replace(b"$", b"#") for g in garbage]
    wire = bytearray(garbage[0])
    for index, frame in enumerate(frames):
        wire += encode_frame(frame) + garbage[index + 1]
    parser = MspParser()
    events: list = []
    position = 0
    for size in splits:
        events += parser.feed(bytes(wire[position : position + size]))
        position += size
    events += parser.feed(bytes(wire[position:]))
    assert [(f.command, f.payload) for f in frames_of(events)] == [
        (f.command, f.payload) for f in frames
    ]


@settings(max_examples=400, deadline=None)
@given(data=st.binary(max_size=600), splits=st.lists(st.integers(1, 50), max_size=20))
def test_fuzz_random_bytes_never_raise(data, splits):
    parser = MspParser()
    position = 0
    for size in splits:
        parser.feed(data[position : position + size])
        position += size
    parser.feed(data[position:])
    while parser.pending_bytes:
        parser.flush_stalled()
    assert parser.pending_bytes == 0


@settings(max_examples=300, deadline=None)
@given(
    frames=st.lists(_frame_strategy, min_size=2, max_size=5),
    corrupt_index=st.integers(0, 10_000),
    flip=st.integers(1, 255),
    offset=st.integers(0, 10_000),
)
def test_fuzz_one_corrupted_frame_loses_at_most_itself(frames, corrupt_index, flip, offset):
    corrupt_index %= len(frames)
    wires = [bytearray(encode_frame(f)) for f in frames]
    target = wires[corrupt_index]
    target[3 + offset % (len(target) - 3)] ^= flip  # corrupt after the '$M>' / '$X>'
    parser = MspParser()
    events = parser.feed(b"".join(bytes(w) for w in wires))
    while parser.pending_bytes:
        events += parser.flush_stalled()
    found = [(f.command, f.payload) for f in frames_of(events)]
    sent = [(f.command, f.payload) for f in frames]
    expected = [frame for i, frame in enumerate(sent) if i != corrupt_index]
    # Every intact frame is found, in order; the corrupted one may (rarely) still pass an
    # 8-bit checksum, so it is allowed but not required.  When its corrupted size passed too (a
    # frame that was never sent shows up: zero payloads make the XOR sum right by chance), the
    # bytes its size claimed went with it; the frames before it cannot have.
    if any(frame not in sent for frame in found):
        expected = expected[:corrupt_index]
    it = iter(found)
    assert all(any(x == e for x in it) for e in expected)
