"""The Python side of the compiled lockstep loop (``lockstep_loop.c``).

:class:`KernelStepper` holds the loop's state (where the shared region's datagram and reply
are, the encoder's settings for the firmware's generation, the totals) in a ctypes structure
laid out as ``bk_lockstep``, and runs the loop for a :class:`~bfsitl.sim.lockstep.LockstepBridge`:
many steps per call, so a step costs no Python at all.  The bridge decides when it may be used
(the shared-memory exchange, no callback or pace per step, no RC fault) and handles every
status but "done" with its own code.  The structure and the statuses are lockstep_loop.c's:
``tests/unit/kernel/test_layout.py`` reads them there and fails when the two differ.
"""

from __future__ import annotations

import ctypes
from typing import TYPE_CHECKING, NamedTuple

from bfsitl.errors import KernelUnavailableError
from bfsitl.kernel.compiler import load_kernel
from bfsitl.physics.constants import SEA_LEVEL_PRESSURE_PA
from bfsitl.protocol import fdm_encoding
from bfsitl.protocol.firmware_profile import AltitudeSource, QuaternionConvention

if TYPE_CHECKING:
    from bfsitl.link.shm_exchange import ShmExchange
    from bfsitl.protocol.fdm_encoding import FdmEncoder
    from bfsitl.sim.rc_frames import RcFrameClock

#: Why a run of the loop stopped (lockstep_loop.c's BK_LOCKSTEP_* values).
DONE = 0
PENDING = 1
OUT_OF_STEP = 2
BAD_READING = 3
BAD_MOTORS = 4
TOO_BIG = 5
NO_FUTEX = 6

_D3 = ctypes.c_double * 3
_D4 = ctypes.c_double * 4


class _Lockstep(ctypes.Structure):
    """``bk_lockstep`` of lockstep_loop.c, field for field."""

    _fields_ = [
        ("region", ctypes.c_void_p),
        ("datagram_offset", ctypes.c_uint32),
        ("reply_offset", ctypes.c_uint32),
        ("seq", ctypes.c_uint32),
        ("status", ctypes.c_int32),
        ("gyro_k", _D3),
        ("acc_k", _D3),
        ("rz_minus_90", _D4),
        ("home_lon_deg", ctypes.c_double),
        ("home_lat_deg", ctypes.c_double),
        ("sea_level_pa", ctypes.c_double),
        ("lapse_per_m", ctypes.c_double),
        ("exponent", ctypes.c_double),
        ("lost_lon_deg", ctypes.c_double),
        ("lost_lat_deg", ctypes.c_double),
        ("gazebo_quaternion", ctypes.c_int32),
        ("altitude_z_up", ctypes.c_int32),
        ("has_gps", ctypes.c_int32),
        ("send_gps_lost", ctypes.c_int32),
        ("mirrored", ctypes.c_int32),
        ("motor_slot", ctypes.c_int32 * 4),
        ("step_s", ctypes.c_double),
        ("spin_s", ctypes.c_double),
        ("wait_s", ctypes.c_double),
        ("rc_period_s", ctypes.c_double),
        ("rc_next_s", ctypes.c_double),
        ("rc_sent_s", ctypes.c_double),
        ("rc_frames", ctypes.c_int64),
        ("exchange_s", ctypes.c_double),
        ("physics_s", ctypes.c_double),
        ("steps", ctypes.c_int64),
        ("motors", _D4),
        ("stamp_s", ctypes.c_double),
        ("began_s", ctypes.c_double),
        ("answered_s", ctypes.c_double),
        ("fc_sleeping_word", ctypes.c_int32),
        ("sim_polling_word", ctypes.c_int32),
        ("wakes", ctypes.c_int64),
    ]


class KernelRun(NamedTuple):
    """What one call did: steps taken, why it stopped, and the last datagram's details (a
    named tuple: made twice per control step, where a frozen dataclass costs three times
    more)."""

    steps: int
    status: int
    seq: int
    stamp_s: float
    began_s: float
    motors: tuple[float, float, float, float]
    answered_s: float


class KernelStepper:
    """Runs lockstep steps of one compiled simulator through one shared region."""

    def __init__(
        self, simulator_pointer: int, exchange: ShmExchange, *, step_s: float, wait_s: float
    ) -> None:
        library = load_kernel()
        if ctypes.sizeof(_Lockstep) != library.bk_lockstep_size():
            raise KernelUnavailableError(
                "the compiled loop's bk_lockstep and its ctypes "
                "mirror differ in size: the two were changed apart"
            )
        self._run = library.bk_lockstep_run
        self._run.restype = ctypes.c_long
        self._run.argtypes = [
            ctypes.c_void_p,
            ctypes.c_void_p,
            ctypes.c_char_p,
            ctypes.c_uint32,
            ctypes.c_double,
            ctypes.c_double,
            ctypes.c_long,
            ctypes.c_int,
        ]
        self._sim = simulator_pointer
        self._state = _Lockstep()
        self._pointer = ctypes.addressof(self._state)
        self.exchange = exchange
        state = self._state
        state.region = exchange.base_address
        state.datagram_offset, state.reply_offset = exchange.offsets
        state.fc_sleeping_word, state.sim_polling_word = exchange.waiting_words
        state.step_s = step_s
        state.wait_s = wait_s
        state.sea_level_pa = SEA_LEVEL_PRESSURE_PA
        state.lapse_per_m = fdm_encoding._LAPSE_PER_M
        state.exponent = fdm_encoding._EXPONENT
        state.lost_lon_deg, state.lost_lat_deg = fdm_encoding.GPS_LOST_LON_LAT
        state.rz_minus_90[:] = fdm_encoding._RZ_MINUS_90
        self._encoder: FdmEncoder | None = None
        self._gps_lost: bool | None = None

    def _configure(self, encoder: FdmEncoder) -> None:
        state, fdm, profile = self._state, encoder.fdm, encoder.profile
        state.gyro_k[:] = [float(k) for k in encoder.gyro_factors]
        state.acc_k[:] = [float(k) for k in encoder.acc_factors]
        state.gazebo_quaternion = fdm.quaternion is QuaternionConvention.GAZEBO
        state.altitude_z_up = fdm.altitude is AltitudeSource.POSITION_Z_UP
        state.has_gps = profile.has_gps
        state.send_gps_lost = encoder.gps_lost and fdm.gps_loss_sentinel
        state.mirrored = fdm.gps_mirrored_about_first_fix
        state.home_lon_deg = encoder.home.lon_deg
        state.home_lat_deg = encoder.home.lat_deg
        state.motor_slot[:] = profile.motor_slot_of_betaflight_motor
        self._encoder, self._gps_lost = encoder, encoder.gps_lost

    @property
    def exchange_s(self) -> float:
        return self._state.exchange_s

    @property
    def physics_s(self) -> float:
        return self._state.physics_s

    @property
    def wakes(self) -> int:
        """FUTEX_WAKE calls the loop has made (none for an FC that was polling)."""
        return int(self._state.wakes)

    def run(
        self,
        encoder: FdmEncoder,
        rc: bytes,
        *,
        until_s: float,
        slack_s: float,
        max_steps: int,
        spin_s: float,
        frames: RcFrameClock,
        watch_fd: int = -1,
    ) -> KernelRun:
        """Step while the time plus ``slack_s`` is below ``until_s``, at most ``max_steps``,
        and (``watch_fd`` >= 0) until that descriptor has something to read; ``rc`` rides in
        the datagrams ``frames`` picks, and ``frames`` is moved on as they are sent."""
        if encoder is not self._encoder or encoder.gps_lost != self._gps_lost:
            self._configure(encoder)
        state, exchange = self._state, self.exchange
        state.spin_s = spin_s
        state.seq = exchange.seq
        state.rc_period_s, state.rc_next_s, state.rc_sent_s, state.rc_frames = (
            frames.period_s,
            frames.next_s,
            frames.sent_s,
            frames.sent,
        )
        taken = self._run(
            self._sim, self._pointer, rc, len(rc), until_s, slack_s, max_steps, watch_fd
        )
        exchange.seq = state.seq
        frames.next_s, frames.sent_s, frames.sent = (
            state.rc_next_s,
            state.rc_sent_s,
            state.rc_frames,
        )
        m = state.motors
        return KernelRun(
            taken,
            state.status,
            state.seq,
            state.stamp_s,
            state.began_s,
            (m[0], m[1], m[2], m[3]),
            state.answered_s,
        )
