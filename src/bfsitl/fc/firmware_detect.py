"""Choose the firmware profile from what a running flight controller says about itself.

Two MSP requests (about 20 ms at the default serial rate): MSP_API_VERSION picks the
generation and MSP_FC_VERSION names the version. Build options that leave no trace over MSP
(GPS, the Gazebo bridge, direct attitude) come from bfsitl's own build record when there is
one (:class:`BuildOptions`); on request MSP_RAW_GPS is asked whether the build has GPS.
"""

from __future__ import annotations

import os

from bfsitl.errors import MspErrorReply
from bfsitl.fc.msp_client import MspClient
from bfsitl.protocol import messages as msg
from bfsitl.protocol.firmware_profile import (
    DEFAULT_PROFILE,
    BuildOptions,
    FirmwareProfile,
    profile_for,
)

#: The first master API version (any >= 1.48 is master's generation).
MASTER_API_VERSION = "1.48"


def detect_profile(
    client: MspClient,
    build: BuildOptions | None = None,
    *,
    probe_gps: bool = False,
    api: msg.ApiVersion | None = None,
) -> FirmwareProfile:
    """The profile of the firmware behind ``client``; raises UnsupportedFirmwareError.

    Whether the build has GPS comes from its build record when there is one, else from the
    generation (the PyPI 4.6.0 has none, master always has it); ``probe_gps`` asks the FC
    instead (MSP_RAW_GPS answers or not). Not by default: a start should ask no more than it
    needs, and in two loaded test runs with this probe at every start a 4.6.0 SITL's port
    stayed silent to the CLI after a start (cause not established; the probe is a suspect).
    ``api`` is an MSP_API_VERSION reply the caller already has (a start's readiness probe).
    """
    if api is None:
        api = client.get(msg.ApiVersion)
    version = client.get(msg.FcVersion)
    has_gps: bool | None = None
    if probe_gps:
        try:
            client.get(msg.RawGps)
            has_gps = True
        except MspErrorReply:
            has_gps = False
    return profile_for(f"{api.api_major}.{api.api_minor}", version.text, build, has_gps=has_gps)


def profile_of_binary(path: str | os.PathLike[str]) -> FirmwareProfile:
    """The profile of a binary before it runs: from bfsitl's build record, else its bytes.

    A lockstep bridge needs the conventions for the packet that locks the booting FC, before
    MSP can say who it is; every lockstep build is bfsitl's and has a record.  Without one,
    master's command-line form marks master, and 4.6's profile is assumed otherwise.
    """
    from bfsitl.build.binary_scan import binary_traits
    from bfsitl.build.metadata import build_options_for_binary, metadata_for_binary

    metadata = metadata_for_binary(path)
    if metadata is not None:
        return profile_for(
            metadata.msp_api_version, metadata.firmware_version, build_options_for_binary(path)
        )
    try:
        takes_ip_flag = binary_traits(path).takes_ip_flag
    except OSError:
        takes_ip_flag = False
    return profile_for(MASTER_API_VERSION) if takes_ip_flag else DEFAULT_PROFILE
