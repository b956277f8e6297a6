"""Typed MSP payloads of Betaflight 4.6 (MSP API 1.47), both directions: the names of
:mod:`bfsitl.protocol.messages`, where each layout is declared once, under the module name
code has always imported (``from bfsitl.protocol import msp_messages as msg``).

Also re-exported, because this module used to import them and callers may have reached them
here: the errors, :class:`MspCommand`, the arming-flag decoder, the box names, the request
size limit and the payload reader and writer.
"""

from __future__ import annotations

from bfsitl.protocol.arming import ArmingFlagInfo, decode_arming_flags
from bfsitl.protocol.boxes import BOX_NAMES
from bfsitl.protocol.messages import *  # noqa: F403 - the facade is the whole package
from bfsitl.protocol.messages import __all__ as _messages_all
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MAX_REQUEST_PAYLOAD
from bfsitl.protocol.payload import PayloadReader, PayloadWriter

__all__ = [
    *_messages_all,
    "ArmingFlagInfo", "BOX_NAMES", "MAX_REQUEST_PAYLOAD", "MspCommand", "PayloadReader",
    "PayloadWriter", "decode_arming_flags",
]  # fmt: skip
