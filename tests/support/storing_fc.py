"""A fake FC that keeps mode ranges and counts EEPROM writes, as msp.c does."""

from __future__ import annotations

from bfsitl.protocol import messages as msg
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MspFrame
from support.fake_fc import FakeFcLink

STATUS = msg.StatusEx(
    cycle_time_us=125,
    i2c_errors=0,
    sensors_mask=0x23,
    flight_mode_flags=0,
    pid_profile=0,
    cpu_load_percent=0,
    pid_profile_count=4,
    rate_profile_index=0,
    arming_disable_flag_count=29,
    arming_disable_flags=0,
    config_state=0,
    cpu_temp_c=0,
    rate_profile_count=4,
)


class StoringFc:
    """MODE_RANGES / SET_MODE_RANGE / EEPROM_WRITE with state, as msp.c keeps them."""

    def __init__(self, accept_writes: bool = True) -> None:
        self.slots = [msg.ModeRange(0, 0, 0, 0)] * 20
        self.accept_writes = accept_writes
        self.eeprom_writes = 0
        self.link = FakeFcLink(
            {
                MspCommand.MODE_RANGES: lambda _r: msg.ModeRanges(tuple(self.slots)).encode(),
                MspCommand.SET_MODE_RANGE: self._set,
                MspCommand.EEPROM_WRITE: self._save,
                MspCommand.STATUS_EX: lambda _r: STATUS.encode(),
            }
        )

    def _set(self, request: MspFrame) -> bytes:
        command = msg.SetModeRange.decode(request.payload)
        if self.accept_writes:
            self.slots[command.index] = command.range
        return b""

    def _save(self, _request: MspFrame) -> bytes:
        self.eeprom_writes += 1
        return b""
