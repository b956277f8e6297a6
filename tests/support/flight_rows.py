"""Rows of a flight's shape without flying, and an MCAP file read back."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from bfsitl.mission.flight_row import FlightRow


def make_row(index: int, **changes: object) -> FlightRow:
    row = FlightRow(
        time_s=3.0 + index * 0.02,
        phase="hold",
        target_alt_m=2.0,
        sim_alt_m=1.9 + index * 0.01,
        fc_alt_m=1.95,
        climb_m_s=0.1,
        sim_climb_m_s=0.1,
        fc_accel_up_m_s2=0.02,
        roll_deg=1.0,
        pitch_deg=-2.0,
        yaw_deg=90.5,
        sim_tilt_deg=2.2,
        sim_roll_deg=1.2,
        sim_pitch_deg=-2.1,
        sim_yaw_deg=90.2,
        rc_roll_us=1490,
        rc_pitch_us=1510,
        rc_throttle_us=1540 + index,
        rc_yaw_us=1500,
        rc_aux1_us=1800,
        rc_aux2_us=1800,
        motor1=0.51,
        motor2=0.52,
        motor3=0.53,
        motor4=0.54,
        armed=index >= 2,
        wall_s=0.1 * index,
        sim_north_m=0.5,
        sim_east_m=-0.25,
    )
    return replace(row, **changes)  # type: ignore[arg-type]


def read_mcap(path: Path) -> tuple[dict[str, int], dict[str, list]]:
    """Per-topic counts from the file's statistics, and (schema name, message, decoded) per
    topic: protobuf (Foxglove's schemas) by mcap-protobuf-support, JSON by json."""
    protobuf = DecoderFactory()
    with path.open("rb") as file:
        reader = make_reader(file)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        counts = {
            channel.topic: summary.statistics.channel_message_counts.get(channel.id, 0)
            for channel in summary.channels.values()
        }
        messages: dict[str, list] = {}
        for schema, channel, message in reader.iter_messages():
            assert schema is not None
            if channel.message_encoding == "json":
                decoded = json.loads(message.data)
            else:
                decoder = protobuf.decoder_for(channel.message_encoding, schema)
                assert decoder is not None
                decoded = decoder(message.data)
            messages.setdefault(channel.topic, []).append((schema.name, message, decoded))
    return counts, messages
