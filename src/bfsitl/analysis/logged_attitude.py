"""A log's attitude (tilt, roll, pitch) from its logged quaternions, computed by the compiled
kernel (``bfsitl/kernel/logged_attitude.c``) for a whole log at once.

Why: one frame at a time with ``math`` it was a fifth of the time a log's track took.  numpy
is not used because its acos and atan2 need not match libm's to the last bit; the kernel
calls the libm functions CPython's ``math`` calls, in the same order, so the floats are the
same (``tests/unit/analysis/test_track.py`` compares the two).
"""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np
import numpy.typing as npt

from bfsitl.errors import KernelUnavailableError
from bfsitl.kernel.compiler import load_kernel

__all__ = ["compiled_attitudes_deg"]

_function: Any = None


def compiled_attitudes_deg(
    xyz: npt.NDArray[np.int64],
) -> list[tuple[float, float, float]] | None:
    """(tilt, roll, pitch) in degrees for each row of ``xyz`` (a frame's quaternion x, y, z
    scaled by 0x7FFF), or None without a compiled kernel (the caller computes them itself)."""
    try:
        function = _kernel_function()
    except KernelUnavailableError:
        return None
    values = np.ascontiguousarray(xyz, dtype=np.int64).reshape(-1, 3)
    out = np.empty((len(values), 3), dtype=np.float64)
    function(
        values.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
        len(values),
        out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
    )
    rows: list[tuple[float, float, float]] = [(a, b, c) for a, b, c in out.tolist()]
    return rows


def _kernel_function() -> Any:
    global _function
    if _function is None:
        function = load_kernel().bb_logged_attitudes
        function.restype = None
        function.argtypes = [
            ctypes.POINTER(ctypes.c_int64),
            ctypes.c_int64,
            ctypes.POINTER(ctypes.c_double),
        ]
        _function = function
    return _function
