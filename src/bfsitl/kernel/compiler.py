"""Build the compiled code (the physics, the lockstep loop, the blackbox frame decoder) once per
machine and load it.

Every ``*.c`` file of this package goes into one shared library, compiled with the system's C
compiler (the one ``bfsitl firmware build`` needs anyway) the first time a process asks for
it, and kept in the cache under a name made from the sources' and the flags' hash: a new
bfsitl builds a new one, two processes building at once each write their own temporary file
and the last rename wins (both are the same bytes).

The flags keep the arithmetic as written: IEEE doubles in program order, no fused
multiply-add (``-ffp-contract=off``), no fast-math; the libm functions are the ones CPython's
``math`` calls.  That is what keeps the flights the model flew when it was written in Python
(``tests/data/physics_golden.json``) the same, bit for bit.  Without a C compiler there is no
embedded physics: the error says what to install, where a user first meets it (``bfsitl
fly``, ``bfsitl doctor``, any flight).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import subprocess
import sys
import threading
from pathlib import Path

from bfsitl.cache_location import cache_root
from bfsitl.errors import KernelUnavailableError

#: The compiler's flags; part of the cache key.
CFLAGS = (
    "-O2",
    "-std=c11",
    "-fPIC",
    "-shared",
    "-ffp-contract=off",
    "-fno-fast-math",
    "-D_GNU_SOURCE",
)
#: ``cc`` unless ``$CC`` names another.
CC_ENV = "CC"
COMPILE_TIMEOUT_S = 120.0
_SOURCE_DIR = Path(__file__).parent

_lock = threading.Lock()
_library: ctypes.CDLL | None = None
_failure: str | None = None


def kernel_sources() -> list[Path]:
    """The C sources and headers that make the library (sorted: the hash is stable)."""
    return sorted([*_SOURCE_DIR.glob("*.c"), *_SOURCE_DIR.glob("*.h")])


def kernel_key() -> str:
    """The hash naming this bfsitl's build of the kernel on this machine."""
    digest = hashlib.sha256()
    for part in (*CFLAGS, platform.machine(), str(sys.maxsize)):
        digest.update(part.encode() + b"\0")
    for source in kernel_sources():
        digest.update(source.name.encode() + b"\0" + source.read_bytes() + b"\0")
    return digest.hexdigest()[:20]


def kernel_path() -> Path:
    """Where the built library is (or will be) kept."""
    return cache_root() / "kernel" / f"bfsitl-kernel-{kernel_key()}.so"


def find_compiler() -> str | None:
    named = os.environ.get(CC_ENV)
    for candidate in ([named] if named else []) + ["cc", "gcc", "clang"]:
        found = shutil.which(candidate)
        if found:
            return found
    return None


def build_kernel(target: Path) -> None:
    """Compile the sources into ``target``; KernelUnavailableError says why not."""
    compiler = find_compiler()
    if compiler is None:
        raise KernelUnavailableError(
            "no C compiler for the embedded physics, which is C built once per machine "
            "(looked for $CC, cc, gcc, clang): install one (Debian/Ubuntu: apt-get install "
            "gcc; the firmware build needs it too), or set $CC to yours"
        )
    target.parent.mkdir(parents=True, exist_ok=True)
    scratch = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    sources = [str(p) for p in kernel_sources() if p.suffix == ".c"]
    command = [compiler, *CFLAGS, "-o", str(scratch), *sources, "-lm"]
    try:
        done = subprocess.run(
            command, capture_output=True, text=True, timeout=COMPILE_TIMEOUT_S, check=False
        )
        if done.returncode != 0:
            raise KernelUnavailableError(
                f"the embedded physics did not build ({Path(compiler).name} exited "
                f"{done.returncode}; set $CC to another C compiler):\n"
                f"{done.stderr.strip()[-2000:]}"
            )
        os.replace(scratch, target)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise KernelUnavailableError(f"the embedded physics did not build: {exc}") from exc
    finally:
        scratch.unlink(missing_ok=True)


def load_kernel() -> ctypes.CDLL:
    """The compiled library, built first if this machine has none for this bfsitl.

    Raises KernelUnavailableError (and remembers it for the process) when it cannot be had.
    """
    global _library, _failure
    with _lock:
        if _library is not None:
            return _library
        if _failure is not None:
            raise KernelUnavailableError(_failure)
        target = kernel_path()
        try:
            if not target.exists():
                build_kernel(target)
            try:
                _library = ctypes.CDLL(str(target))
            except OSError as exc:
                raise KernelUnavailableError(
                    f"the compiled physics {target} would not load ({exc}): delete it to rebuild"
                ) from exc
        except KernelUnavailableError as exc:
            _failure = str(exc)
            raise
        return _library


def kernel_available() -> bool:
    """Whether :func:`load_kernel` succeeds here (it builds the kernel if it must)."""
    try:
        load_kernel()
    except KernelUnavailableError:
        return False
    return True
