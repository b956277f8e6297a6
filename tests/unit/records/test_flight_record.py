"""A flight's rows as MCAP and live Foxglove channels: frames, counts, times, the Origin rule."""

from __future__ import annotations

import json
import math
import socket

import pytest

pytest.importorskip("foxglove", reason="the foxglove extra is not installed")

from support.flight_rows import make_row, read_mcap  # noqa: E402
from websockets.exceptions import ConnectionClosed  # noqa: E402
from websockets.sync.client import connect  # noqa: E402

from bfsitl.bridges.origin_policy import CLOSE_POLICY_VIOLATION  # noqa: E402
from bfsitl.errors import BfsitlError, ListenAddressInUseError  # noqa: E402
from bfsitl.records.foxglove import FoxgloveRecorder  # noqa: E402
from bfsitl.records.foxglove.channels import PER_ROW_TOPICS, row_messages  # noqa: E402
from bfsitl.records.foxglove.frames import betaflight_to_enu_quaternion, enu_flu_rotation  # noqa: E402,E501


def body_axis_in_enu(roll: float, pitch: float, yaw: float, axis: int) -> tuple[float, ...]:
    matrix = enu_flu_rotation(roll, pitch, yaw)
    return tuple(matrix[i][axis] for i in range(3))


def test_heading_east_is_enu_identity_and_north_a_quarter_turn_left():
    assert betaflight_to_enu_quaternion(0, 0, 90) == pytest.approx((0, 0, 0, 1), abs=1e-12)
    half = math.sqrt(0.5)
    # Facing north, the body's x (forward) is ENU's y: +90 deg about z.
    assert betaflight_to_enu_quaternion(0, 0, 0) == pytest.approx((0, 0, half, half))
    # Clockwise heading is counter-clockwise ENU yaw: facing west is 180 deg, south -90.
    forward_west = body_axis_in_enu(0, 0, 270, 0)
    assert forward_west == pytest.approx((-1, 0, 0), abs=1e-12)


def test_nose_down_pitch_points_forward_down_and_right_wing_down_lifts_left():
    # Betaflight: pitch positive nose down.
    forward = body_axis_in_enu(0, 10, 90, 0)
    assert forward[2] == pytest.approx(-math.sin(math.radians(10)))
    # Roll positive right wing down: the body's left (y) points up.
    left = body_axis_in_enu(10, 0, 90, 1)
    assert left[2] == pytest.approx(math.sin(math.radians(10)))
    for roll, pitch, yaw in ((10, -20, 33), (-45, 60, 300)):
        q = betaflight_to_enu_quaternion(roll, pitch, yaw)
        assert math.fsum(c * c for c in q) == pytest.approx(1.0) and q[3] >= 0


def test_mcap_holds_one_message_per_row_on_every_topic_in_simulation_time(tmp_path):
    rows = [make_row(i) for i in range(25)]
    with FoxgloveRecorder(mcap_path=tmp_path / "out" / "flight.mcap") as recorder:
        for row in rows:
            recorder.write(row)
        recorder.event(rows[5].time_s, "take-off to 2.00 m")
    counts, messages = read_mcap(tmp_path / "out" / "flight.mcap")
    assert {topic: counts[topic] for topic in PER_ROW_TOPICS} == dict.fromkeys(PER_ROW_TOPICS, 25)
    # The event, and the arming at row 2 as an event of its own.
    assert [d.message for _s, _m, d in messages["/events"]] == ["FC armed", "take-off to 2.00 m"]
    for topic in PER_ROW_TOPICS:
        times = [m.log_time for _s, m, _d in messages[topic]]
        assert times == [round(r.time_s * 1e9) for r in rows], topic
    schema, _message, pose = messages["/sim/pose"][3]
    assert schema == "foxglove.FrameTransform"
    assert (pose.parent_frame_id, pose.child_frame_id) == ("world", "sim_body")
    # ENU: x east, y north, z up.
    assert (pose.translation.x, pose.translation.y, pose.translation.z) == pytest.approx(
        (-0.25, 0.5, 1.93)
    )
    assert pose.timestamp.seconds == 3 and pose.timestamp.nanos == 60_000_000  # protobuf names
    altitude = messages["/flight/altitude"][0][2]
    assert altitude["sim_alt_m"] == pytest.approx(1.9)
    rc = messages["/rc"][7][2]
    assert rc["throttle_us"] == 1547


def test_unknown_values_are_json_nulls_and_the_fc_is_drawn_at_the_truth():
    row = make_row(0, fc_north_m=math.nan, fc_east_m=math.nan, target_heading_deg=math.nan)
    position = row_messages(row)["/flight/position"]
    assert position["fc_north_m"] is None and position["target_heading_deg"] is None
    json.dumps(position, allow_nan=False)  # valid JSON: no NaN


def test_a_flight_that_ends_in_an_exception_still_leaves_a_readable_file(tmp_path):
    path = tmp_path / "crash.mcap"
    with pytest.raises(RuntimeError), FoxgloveRecorder(mcap_path=path) as recorder:
        for index in range(7):
            recorder.write(make_row(index))
        raise RuntimeError("the SITL crashed")
    counts, _messages = read_mcap(path)
    assert counts["/fc/pose"] == 7


def test_an_unwritable_path_is_a_clear_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(BfsitlError, match="cannot write the MCAP file"):
        FoxgloveRecorder(mcap_path=blocker / "flight.mcap").start()


def advertised(ws) -> dict[str, int]:
    info = json.loads(ws.recv(timeout=3.0))
    assert info["op"] == "serverInfo"
    channels: dict[str, int] = {}
    while set(channels) != set(PER_ROW_TOPICS) | {"/events"}:
        message = json.loads(ws.recv(timeout=3.0))
        if message["op"] == "advertise":
            channels.update({c["topic"]: c["id"] for c in message["channels"]})
    return channels


def test_live_server_advertises_the_channels_and_streams_rows(tmp_path):
    with FoxgloveRecorder(live_port=0) as recorder:
        assert recorder.live_url is not None
        with connect(
            recorder.live_url, subprotocols=["foxglove.sdk.v1"], origin="http://127.0.0.1:8080"
        ) as ws:
            channels = advertised(ws)
            ws.send(
                json.dumps(
                    {"op": "subscribe", "subscriptions": [{"id": 5, "channelId": channels["/rc"]}]}
                )
            )
            deadline_rows = 0
            payload = b""
            while not payload and deadline_rows < 50:
                recorder.write(make_row(deadline_rows))
                deadline_rows += 1
                try:
                    data = ws.recv(timeout=0.2)
                except TimeoutError:
                    continue
                if isinstance(data, bytes) and data[0] == 1:  # opcode 1: message data
                    payload = data
    assert int.from_bytes(payload[1:5], "little") == 5  # our subscription id
    log_time_ns = int.from_bytes(payload[5:13], "little")
    body = json.loads(payload[13:])
    assert body["throttle_us"] >= 1540
    assert log_time_ns == round((3.0 + (body["throttle_us"] - 1540) * 0.02) * 1e9)


@pytest.mark.parametrize("origin", ["https://evil.example", "http://localhost.evil.example"])
def test_live_server_refuses_a_foreign_page(origin):
    events: list[str] = []
    with FoxgloveRecorder(live_port=0, on_event=events.append) as recorder:
        assert recorder.live_url is not None
        with connect(recorder.live_url, subprotocols=["foxglove.sdk.v1"], origin=origin) as ws:
            with pytest.raises(ConnectionClosed):
                ws.recv(timeout=3.0)
            assert ws.close_code == CLOSE_POLICY_VIOLATION
            assert "--allow-origin" in (ws.close_reason or "")
    assert any(origin in line for line in events)


def test_foxgloves_own_app_and_an_allowed_origin_are_served():
    with FoxgloveRecorder(live_port=0, allow_origins=["https://viewer.example"]) as recorder:
        assert recorder.live_url is not None
        for origin in ("https://app.foxglove.dev", "https://viewer.example", None):
            with connect(recorder.live_url, subprotocols=["foxglove.sdk.v1"], origin=origin) as ws:
                assert "/sim/pose" in advertised(ws)


def test_a_taken_port_names_the_option_that_moves_it():
    with socket.create_server(("127.0.0.1", 0)) as holder:
        port = holder.getsockname()[1]
        with pytest.raises(ListenAddressInUseError, match="--foxglove-port"):
            FoxgloveRecorder(live_port=port).start()
