"""The lockstep patch: hooks added to the SITL platform's ``sitl.c``, and the code they call.

The code is ``sitl_lockstep.c`` beside this file (its header says why it works as it does).
It is included at the end of ``src/platform/SIMULATOR/sitl.c``, so it sees that file's static
sockets and packets, and the edits below route the platform's clock, delays, main-loop pause,
motor output and I/O threads to it.  Each edit is anchored on a line of ``sitl.c`` that 4.6.0
and master share and must match exactly once; a tree where any anchor is missing (another
release reorganised the file) is refused with the anchor's name instead of being half-patched.
A few optional edits only take out locks that a single thread does not need (4.6.0's motor
writes in ``sitl.c``, the gyro and accelerometer in ``accgyro.h``): where a release has no
such lock there is nothing to take out.  Only the copy bfsitl builds is changed, never the
user's source.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from bfsitl.errors import FirmwareBuildError

SITL_C = Path("src/platform/SIMULATOR/sitl.c")
#: The sensor drivers' header, whose gyro and accelerometer locks a lockstep build drops.
ACCGYRO_H = Path("src/main/drivers/accgyro/accgyro.h")
LOCKSTEP_C_NAME = "sitl_lockstep.c"
#: Written into the patched sitl.c; `binary_traits` finds it in the binary's strings.
MARKER = "[LOCKSTEP] bfsitl lockstep build"


@dataclass(frozen=True)
class Edit:
    """Insert ``text`` after (or instead of) the one match of ``anchor`` in ``file_name``.

    An ``optional`` edit changes what only some releases have: where its anchor is missing
    there is nothing to change and the source is left as it is (twice is still refused)."""

    name: str
    anchor: str  # a regular expression (re.MULTILINE)
    text: str
    replace: bool = False
    optional: bool = False
    file_name: str = "sitl.c"

    def apply(self, source: str) -> str:
        matches = list(re.finditer(self.anchor, source, re.MULTILINE))
        if not matches and self.optional:
            return source
        if len(matches) != 1:
            found = "not found" if not matches else f"found {len(matches)} times"
            raise FirmwareBuildError(
                f"--lockstep does not fit this tree: {self.file_name}'s {self.name} ({found}). "
                f"The patch knows Betaflight 4.6 and master (2026.12); build this tree without "
                f"--lockstep"
            )
        match = matches[0]
        if self.replace:
            return source[: match.start()] + self.text + source[match.end() :]
        return source[: match.end()] + self.text + source[match.end() :]


def _body_start(signature: str) -> str:
    """A function definition's opening: its signature line and the brace line."""
    return r"^" + signature + r"\s*\n\{\n"


def _thread_start(name: str) -> str:
    """A thread function's opening, through its ``UNUSED(data);`` line."""
    return _body_start(rf"static void\s*\*\s*{name}\(void\s*\*\s*data\)") + r"    UNUSED\(data\);\n"


def _early_return(value: str) -> str:
    return f"#if defined(SITL_LOCKSTEP)\n    return {value};\n#endif\n"


EDITS: tuple[Edit, ...] = (
    Edit(
        'includes (#include "udplink.h")',
        r'^#include "udplink\.h"\n',
        "\n#define SITL_LOCKSTEP 1\n"
        "static uint64_t lockstepNowUs(void);\n"
        "static uint32_t lockstepCycleCounter(void);\n"
        "static void lockstepAdvanceBy(uint64_t us);\n"
        "static void lockstepLoopEnd(void);\n"
        "static void lockstepInit(void);\n",
    ),
    Edit(
        "fdm thread (udpThread)",
        _thread_start("udpThread"),
        "#if defined(SITL_LOCKSTEP)\n    return NULL;  // the main loop reads fdm packets\n"
        "#endif\n",
    ),
    Edit(
        "TCP thread (tcpThread)",
        _thread_start("tcpThread"),
        "#if defined(SITL_LOCKSTEP)\n    return NULL;  // the main loop services dyad\n#endif\n",
    ),
    Edit(
        "system start (systemInit's clock_gettime)",
        r"^    clock_gettime\(CLOCK_MONOTONIC, &start_time\);\n",
        "#if defined(SITL_LOCKSTEP)\n    lockstepInit();\n#endif\n",
    ),
    Edit(
        "clock (micros64)",
        _body_start(r"uint64_t micros64\(void\)"),
        _early_return("lockstepNowUs()"),
    ),
    Edit(
        "clock (millis64)",
        _body_start(r"uint64_t millis64\(void\)"),
        _early_return("lockstepNowUs() / 1000"),
    ),
    Edit(
        "cycle counter (getCycleCounter)",
        _body_start(r"uint32_t getCycleCounter\(void\)"),
        _early_return("lockstepCycleCounter()"),
    ),
    Edit(
        "delay (delayMicroseconds)",
        _body_start(r"void delayMicroseconds\(uint32_t us\)"),
        "#if defined(SITL_LOCKSTEP)\n    lockstepAdvanceBy(us);\n    return;\n#endif\n",
    ),
    Edit(
        "delay (delay)",
        _body_start(r"void delay\(uint32_t ms\)"),
        "#if defined(SITL_LOCKSTEP)\n    lockstepAdvanceBy((uint64_t)ms * 1000);\n"
        "    return;\n#endif\n",
    ),
    Edit(
        "main-loop pause (delayMicroseconds_real)",
        _body_start(r"void delayMicroseconds_real\(uint32_t us\)"),
        "#if defined(SITL_LOCKSTEP)\n    UNUSED(us);\n    lockstepLoopEnd();\n    return;\n"
        "#endif\n",
    ),
    Edit(
        "motor output (pwmCompleteMotorUpdate's reply)",
        r'^    // get one "fdm_packet" can only send one "servo_packet"!!\n',
        "#if defined(SITL_LOCKSTEP)\n    return;  // the main loop sends one reply per packet\n"
        "#endif\n",
    ),
    # 4.6's pwmWriteMotor tries the update lock for every motor of every pass (master's takes
    # none).  With the fdm and TCP threads gone nothing else holds it, so the try always
    # succeeds: the write is the same without it, and the try and release were 11 % of the
    # SITL's time when stepping.
    Edit(
        "motor write lock (pwmWriteMotor's trylock)",
        _body_start(r"static void pwmWriteMotor\(uint8_t index, float value\)")
        + r"    if \(pthread_mutex_trylock\(&updateLock\) != 0\) return;\n",
        "static void pwmWriteMotor(uint8_t index, float value)\n{\n"
        "#if !defined(SITL_LOCKSTEP)  // a single thread: the lock is always free\n"
        "    if (pthread_mutex_trylock(&updateLock) != 0) return;\n#endif\n",
        replace=True,
        optional=True,
    ),
    Edit(
        "motor write unlock (pwmWriteMotor's unlock)",
        r"^    pthread_mutex_unlock\(&updateLock\); // can send PWM output now\n\}\n"
        r"(?=\nstatic void pwmWriteMotorInt\()",
        "#if !defined(SITL_LOCKSTEP)\n"
        "    pthread_mutex_unlock(&updateLock); // can send PWM output now\n#endif\n}\n",
        replace=True,
        optional=True,
    ),
    Edit(
        "fdm wall-clock timeout (updateState)",
        r"^    if \(realtime_now > last_realtime \+ 500\*1e3\) \{",
        "    if (!SITL_LOCKSTEP && realtime_now > last_realtime + 500*1e3) {",
        replace=True,
    ),
)


def _sensor_lock_edit(call: str, device: str) -> Edit:
    """The line ``call`` of accgyro.h's lock helpers, made a no-op: the gyro and the
    accelerometer are written (updateState) and read (their tasks) by the main thread alone
    here; the gyro's lock and release at every gyro pass cost 1-2 % of the SITL's time.
    Optional: a release without these locks has nothing to drop."""
    return Edit(
        f"sensor lock ({call})",
        rf"^    {re.escape(call)}\n",
        f"    (void){device};  // bfsitl lockstep: one thread, no lock\n",
        replace=True,
        optional=True,
        file_name="accgyro.h",
    )


SENSOR_LOCK_EDITS: tuple[Edit, ...] = tuple(
    _sensor_lock_edit(f"pthread_mutex_{verb}(&{device}->lock);", device)
    for device in ("acc", "gyro")
    for verb in ("lock", "unlock")
)


def patch_sensor_header(source: str) -> str:
    """accgyro.h with the sensor locks dropped (as it is where it has none)."""
    for edit in SENSOR_LOCK_EDITS:
        source = edit.apply(source)
    return source


def lockstep_source() -> str:
    return resources.files(__package__).joinpath(LOCKSTEP_C_NAME).read_text()


def patch_sitl_source(source: str) -> str:
    """sitl.c with the lockstep hooks and code; raises FirmwareBuildError if it does not fit."""
    if MARKER in source or "lockstepLoopEnd" in source:
        raise FirmwareBuildError("this sitl.c already carries the lockstep patch")
    patched = source
    for edit in EDITS:
        patched = edit.apply(patched)
    # master feeds UDP RC through rx.c's rxUpdateUdpChannels; 4.6 sets the rx callbacks itself.
    rc_via_rx_udp = int("rxUpdateUdpChannels(" in source)
    return (
        patched.rstrip("\n") + "\n\n/* bfsitl lockstep (see sitl_lockstep.c) */\n"
        f"#define LOCKSTEP_RC_VIA_RX_UDP {rc_via_rx_udp}\n"
        f'#include "{LOCKSTEP_C_NAME}"\n'
    )


@dataclass(frozen=True)
class LockstepPatch:
    """The tree hook of ``bfsitl firmware build --lockstep``."""

    description: str = "apply the lockstep patch (FC clock driven by fdm packets)"

    def key_material(self) -> str:
        digest = hashlib.sha256(lockstep_source().encode())
        for edit in (*EDITS, *SENSOR_LOCK_EDITS):
            digest.update(
                f"{edit.file_name}\0{edit.name}\0{edit.anchor}\0{edit.text}\0{edit.replace}"
                f"\0{edit.optional}".encode()
            )
        return "lockstep:" + digest.hexdigest()[:16]

    def __call__(self, tree: Path) -> None:
        sitl_c = tree / SITL_C
        if not sitl_c.is_file():
            raise FirmwareBuildError(
                f"--lockstep: this tree has no {SITL_C} (the SIMULATOR platform the patch "
                f"changes); build it without --lockstep"
            )
        sitl_c.write_text(patch_sitl_source(sitl_c.read_text()))
        (sitl_c.parent / LOCKSTEP_C_NAME).write_text(lockstep_source())
        header = tree / ACCGYRO_H
        # The locks are a speed-up, not a condition of lockstep; a link is left alone.
        if header.is_file() and not header.is_symlink():
            header.write_text(patch_sensor_header(header.read_text()))
