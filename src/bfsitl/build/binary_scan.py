"""What a SITL binary is, read from its bytes without running it.

* The command-line form: master's ``targetParseArgs`` prints a usage text that contains
  ``--ip <address>``, takes the address only as ``--ip ADDR`` and exits 1 on anything else, a
  bare address included; 4.6.0 copies ``argv[1]`` as the address and has no such text.  The
  file name says nothing reliable (binaries get renamed and copied), so the bytes decide.
* Compiled-in features: the CLI's setting names are NUL-terminated strings in the binary, and a
  setting exists only when its feature is compiled in (``gps_provider`` only with USE_GPS,
  ``gps_rescue_*`` with USE_GPS_RESCUE, ``alt_hold_*`` / ``pos_hold_*`` with altitude and
  position hold).

A SITL is half a megabyte; the scan maps it and searches it in a few milliseconds, and its
result is kept per (path, size, mtime, inode), so asking twice costs a ``stat``.
"""

from __future__ import annotations

import functools
import mmap
import os
from dataclasses import dataclass

IP_FLAG_MARKER = b"--ip <address>"
"""In master's usage text (sitl.c ``targetParseArgs``); absent from 4.6.0."""
LOCKSTEP_MARKER = b"[LOCKSTEP] bfsitl lockstep build"
"""Printed at boot by a ``--lockstep`` build (:mod:`bfsitl.build.lockstep`)."""
SHM_EXCHANGE_MARKER = b"BFSITL_LOCKSTEP_SHM\x00"
"""The variable a lockstep build that has the shared-memory exchange reads (earlier lockstep
builds have only UDP: :mod:`bfsitl.link.shm_exchange`)."""

RX_FRAMES_MARKER = b"BFSITL_LOCKSTEP_RX_FRAMES\x00"
"""The variable a 4.6.0 lockstep build reads to count a receiver frame per RC trailer, not at
every check (earlier lockstep builds count one at every loop; master's receiver needs none)."""
RX_FRAMES_ENV = ("BFSITL_LOCKSTEP_RX_FRAMES", "1")
"""Set in the SITL's environment, that variable asks for it (sitl_lockstep.c): log replay,
the gym environment's ``rc_frame_per_step``."""

FEATURE_MARKERS: dict[str, bytes] = {
    "gps": b"\x00gps_provider\x00",
    "gps_rescue": b"\x00gps_rescue_",
    "altitude_hold": b"\x00alt_hold_",
    "position_hold": b"\x00pos_hold_",
    # Master's flight plans (ENABLE_FLIGHT_PLAN): the FC's own waypoint missions, the
    # AUTOPILOT mode, its RC-loss policy and the geofence, all compiled in together.
    "flight_plan": b"\x00ap_rx_loss_policy\x00",
    "geofence": b"\x00ap_geofence_action\x00",
}
"""Feature name -> a CLI setting name that exists only when the feature is compiled in."""


@dataclass(frozen=True)
class BinaryTraits:
    """What the bytes of one SITL binary say."""

    #: The address is passed as ``--ip ADDR`` (master), not as a bare ``argv[1]`` (4.6.0).
    takes_ip_flag: bool
    #: Names from :data:`FEATURE_MARKERS` whose settings the binary contains.
    features: tuple[str, ...]
    #: Built with ``--lockstep``: its clock follows fdm packets, RC rides in them.
    lockstep: bool = False
    #: A lockstep build that can also take its packets through shared memory.
    shm_exchange: bool = False
    #: A 4.6.0 lockstep build that can count a receiver frame per RC trailer.
    rx_frames: bool = False

    @property
    def has_gps(self) -> bool:
        return "gps" in self.features


def binary_traits(path: str | os.PathLike[str]) -> BinaryTraits:
    """Scan ``path`` (following symlinks); raises OSError when it cannot be read."""
    info = os.stat(path)
    return _scan(os.path.realpath(path), info.st_size, info.st_mtime_ns, info.st_ino, info.st_dev)


@functools.lru_cache(maxsize=64)
def _scan(real_path: str, _size: int, _mtime_ns: int, _ino: int, _dev: int) -> BinaryTraits:
    # The stat fields are only part of the cache key: a rebuilt binary is scanned afresh.
    with open(real_path, "rb") as handle:
        if os.fstat(handle.fileno()).st_size == 0:
            return BinaryTraits(False, ())
        with mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) as mapped:
            takes_ip = mapped.find(IP_FLAG_MARKER) >= 0
            lockstep = mapped.find(LOCKSTEP_MARKER) >= 0
            shm_exchange = lockstep and mapped.find(SHM_EXCHANGE_MARKER) >= 0
            rx_frames = lockstep and mapped.find(RX_FRAMES_MARKER) >= 0
            features = tuple(
                name for name, marker in FEATURE_MARKERS.items() if mapped.find(marker) >= 0
            )
    return BinaryTraits(takes_ip, features, lockstep, shm_exchange, rx_frames)


def clear_cache() -> None:
    """Forget every scan (tests that rewrite a file within one mtime tick)."""
    _scan.cache_clear()


def names_missing(path: str | os.PathLike[str], names: frozenset[str]) -> frozenset[str]:
    """Which of ``names`` (CLI setting or feature names) the binary at ``path`` has no string
    for: a setting the build does not have (master dropped some of 4.6.0's, a feature compiled
    out drops its own).  A name counts as there when it ends a NUL-terminated string, not only
    when it is one: the linker stores a string that ends another only once, inside it (4.6.0's
    ``d_roll`` is the tail of ``align_board_roll``).  So a missing name that ends a longer one
    reads as there; the FC refuses it when it is sent.  Raises OSError when it cannot be
    read."""
    with open(path, "rb") as handle:
        if os.fstat(handle.fileno()).st_size == 0:
            return names
        with mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) as mapped:
            return frozenset(name for name in names if mapped.find(name.encode() + b"\x00") < 0)
