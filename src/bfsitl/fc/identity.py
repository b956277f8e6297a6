"""Who a flight controller is: firmware, API, board, build, craft name, sensors.

Read once, printed by ``bfsitl status`` and kept in logs, so that a result can always be traced
to the exact firmware that produced it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from bfsitl.errors import MspErrorReply
from bfsitl.fc.msp_client import MspClient
from bfsitl.protocol import messages as msg


@dataclass(frozen=True, slots=True)
class FcIdentity:
    variant: str
    firmware_version: str
    api_version: str
    board_id: str
    target_name: str
    build_date: str
    build_time: str
    git_revision: str
    craft_name: str
    gyro_sample_rate_hz: int | None

    @property
    def is_sitl(self) -> bool:
        return self.board_id == "SITL" or self.target_name == "SITL"

    def describe(self) -> str:
        name = f' "{self.craft_name}"' if self.craft_name else ""
        return (
            f"{self.variant} {self.firmware_version} (MSP API {self.api_version}) on "
            f"{self.target_name or self.board_id}{name}, built {self.build_date} "
            f"{self.build_time} ({self.git_revision or 'no git revision'})"
        )

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def read_identity(client: MspClient) -> FcIdentity:
    """Read the identity messages (six requests; about 60 ms at the default MSP rate)."""
    api = client.get(msg.ApiVersion)
    variant = client.get(msg.FcVariant)
    version = client.get(msg.FcVersion)
    board = client.get(msg.BoardInfo)
    build = client.get(msg.BuildInfo)
    try:
        craft = client.get(msg.CraftName).name
    except MspErrorReply:
        craft = ""
    return FcIdentity(
        variant=variant.identifier,
        firmware_version=version.text,
        api_version=f"{api.api_major}.{api.api_minor}",
        board_id=board.board_id,
        target_name=board.target_name,
        build_date=build.date,
        build_time=build.time,
        # 4.6 SITL built without git reads the revision out of neighbouring memory.
        git_revision=build.git_revision if build.git_revision.isprintable() else "",
        craft_name=craft,
        gyro_sample_rate_hz=board.gyro_sample_rate_hz,
    )
