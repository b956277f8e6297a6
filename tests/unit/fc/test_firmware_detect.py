"""detect_profile: what it asks the FC, and the profile it makes of the answers."""

from __future__ import annotations

from bfsitl.fc.firmware_detect import detect_profile
from bfsitl.protocol import messages as msg
from bfsitl.protocol.firmware_profile import Generation


class RecordingClient:
    """Answers like a 4.6.0 or a master SITL and records what it was asked."""

    def __init__(self, api: msg.ApiVersion, version: msg.FcVersion) -> None:
        self.answers = {msg.ApiVersion: api, msg.FcVersion: version}
        self.asked: list[type] = []

    def get(self, message_type: type) -> object:
        self.asked.append(message_type)
        return self.answers[message_type]


V46 = (msg.ApiVersion(0, 1, 47), msg.FcVersion(4, 6, 0))
MASTER = (msg.ApiVersion(0, 1, 49), msg.FcVersion(26, 12, 0, "2026.12.0-alpha"))


def test_each_generation_is_told_by_what_the_fc_says():
    assert detect_profile(RecordingClient(*V46)).generation is Generation.V4_6  # type: ignore[arg-type]
    assert detect_profile(RecordingClient(*MASTER)).generation is Generation.MASTER  # type: ignore[arg-type]


def test_an_api_version_already_read_is_not_asked_again():
    client = RecordingClient(*MASTER)
    profile = detect_profile(client, api=MASTER[0])  # type: ignore[arg-type]
    assert client.asked == [msg.FcVersion]
    assert profile == detect_profile(RecordingClient(*MASTER))  # type: ignore[arg-type]
