"""A whole log's frames decoded by the compiled kernel (``bfsitl/kernel/blackbox_frames.c``),
by the same plans :class:`~bfsitl.blackbox.frame_plan.FramePlan` follows in Python.

Why: decoding was a scenario run's largest cost after the flight, and no compiled Betaflight
log decoder is on PyPI (docs/scenarios.md, why these libraries).  The C loop reads the bytes
and applies the predictors; Python builds the frames from its arrays.

It is only a faster road to the same numbers.  :func:`compiled_log` returns None, and the
log is decoded in Python, wherever the compiled loop could differ from orangebox: no C
compiler, a frame type with no plan or a predictor the kernel does not know, anything a clean
log does not hold (damage, a log cut short, an unknown event; orangebox's handling of those
is kept by its own loop), a number past 64 bits.  ``tests/unit/blackbox/test_compiled_frames.py``
decodes every log at hand both ways and compares them.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from orangebox.predictors import predictor_map
from orangebox.types import FrameType

from bfsitl.blackbox.events import EventKeepingParser, read_event
from bfsitl.blackbox.frame_plan import FramePlan
from bfsitl.errors import KernelUnavailableError
from bfsitl.kernel.compiler import load_kernel

__all__ = ["CompiledLog", "compiled_log"]

#: The frame types in the kernel's plan table, in its order.
_FRAME_TYPES = (
    FrameType.INTRA,
    FrameType.INTER,
    FrameType.SLOW,
    FrameType.GPS,
    FrameType.GPS_HOME,
)
#: orangebox's own predictors (FramePlan calls them) the kernel applies itself: motor[0],
#: the GPS home's two coordinates, the main frame before the last's time.
_CALLED = {
    predictor_map[5]: 6,
    predictor_map[7]: 7,
    predictor_map[256]: 8,
    predictor_map[10]: 9,
}
#: FramePlan's own predictor numbers are the kernel's up to the increment (5).
_CALL = 6
_OK = 0
_INT64_LIMIT = 1 << 63
#: An event's payload is at most 11 bytes (LOG_END's text).
_EVENT_BYTES = 16

_I64 = ctypes.c_int64
_P64 = ctypes.POINTER(ctypes.c_int64)


@dataclass(frozen=True, slots=True)
class CompiledLog:
    """What the kernel found: the main frames' values, the slow and GPS frames, and for each
    main frame the slow and GPS frame in force (-1: none yet); the events as
    :class:`~bfsitl.blackbox.events.EventKeepingParser` keeps them."""

    main: npt.NDArray[np.int64]  # a row per main frame, the intra frame's fields
    slow_of: npt.NDArray[np.int64]
    gps_of: npt.NDArray[np.int64]
    slow: npt.NDArray[np.int64]  # a row per slow frame
    gps: npt.NDArray[np.int64]  # a row per GPS frame, its time first
    #: (main frames before it, kind, data)
    kept: list[tuple[int, str, dict[str, Any]]]

    def rows(self) -> list[list[Any]]:
        """Each main frame's values as orangebox's Parser gives them: the slow frame in force
        appended, then the GPS frame's but its time ('' for each before the first)."""
        slow_count, gps_count = self.slow.shape[1], self.gps.shape[1]
        slow_rows: list[list[Any]] = self.slow.tolist()
        gps_rows: list[list[Any]] = [row[1:] for row in self.gps.tolist()]
        no_slow: list[Any] = [""] * slow_count
        no_gps: list[Any] = [""] * (gps_count - 1) if gps_count else []
        rows: list[list[Any]] = self.main.tolist()
        if slow_count or gps_count:
            slow_of, gps_of = self.slow_of.tolist(), self.gps_of.tolist()
            for row, slow, gps in zip(rows, slow_of, gps_of, strict=True):
                if slow_count:
                    row += slow_rows[slow] if slow >= 0 else no_slow
                if gps_count:
                    row += gps_rows[gps] if gps >= 0 else no_gps
        return rows

    def column(self, index: int) -> list[int | None]:
        """The field at ``index`` of :meth:`rows` for every frame, None where it is ''."""
        main_count, slow_count = self.main.shape[1], self.slow.shape[1]
        if index < main_count:
            values: list[int | None] = self.main[:, index].tolist()
            return values
        if index < main_count + slow_count:
            return _looked_up(self.slow[:, index - main_count], self.slow_of)
        return _looked_up(self.gps[:, index - main_count - slow_count + 1], self.gps_of)


def _looked_up(values: npt.NDArray[np.int64], which: npt.NDArray[np.int64]) -> list[int | None]:
    table: list[int | None] = [*values.tolist(), None]  # -1 (none yet) takes the last
    return [table[row] for row in which.tolist()]


def compiled_log(parser: EventKeepingParser) -> CompiledLog | None:
    """The log ``parser`` was made for, decoded by the kernel, or None where it must be decoded
    in Python (module docstring).  ``parser`` itself is not advanced."""
    table = _plan_table(parser)
    if table is None:
        return None
    try:
        decode = _kernel_function()
    except KernelUnavailableError:
        return None
    ctx = parser._ctx
    reader = parser.reader
    data: bytes = reader._frame_data
    intra_names = [fdef.name for fdef in reader.field_defs[FrameType.INTRA]]
    where = {name: index for index, name in enumerate(intra_names)}  # the last of a name wins
    numbers = [
        ctx.i_interval,
        ctx.p_interval_num,
        ctx.p_interval_denom,
        where.get("loopIteration", -1),
        where.get("motor[0]", -1),
    ]
    if not all(type(number) is int and abs(number) < _INT64_LIMIT for number in numbers):
        return None  # a header orangebox read as something else: its own loop decides
    settings = np.array(numbers, dtype=np.int64)
    counts = _field_counts(reader.field_defs)
    found = np.zeros(5, dtype=np.int64)
    # First only counted (the outputs NULL), then decoded into arrays of just that size: a
    # guess from the log's size would be hundreds of MB for a long real log.
    status = decode(
        data, len(data), reader._frame_data_ptr, _pointer(table), _pointer(settings),
        None, None, None, 0, None, 0, None, 0, None, 0, _pointer(found),
    )  # fmt: skip
    if status != _OK:
        return None
    out = _Outputs(counts, found)
    status = decode(
        data, len(data), reader._frame_data_ptr, _pointer(table), _pointer(settings),
        *out.pointers(),
    )  # fmt: skip
    if status != _OK or not np.array_equal(out.counts, found):
        raise AssertionError("the kernel found another log the second time")  # a bug
    return _assembled(out, data, counts)


def _field_counts(field_defs: dict[Any, Any]) -> dict[Any, int]:
    return {kind: len(field_defs.get(kind, ())) for kind in _FRAME_TYPES}


class _Outputs:
    """The arrays the kernel fills, as large as the counting pass found."""

    def __init__(self, counts: dict[Any, int], found: npt.NDArray[np.int64]) -> None:
        n_main, n_slow, n_gps, n_events, _ = (max(int(n), 1) for n in found)
        self.main = np.empty((n_main, counts[FrameType.INTRA]), dtype=np.int64)
        self.main_slow = np.empty(n_main, dtype=np.int64)
        self.main_gps = np.empty(n_main, dtype=np.int64)
        self.slow = np.empty((n_slow, max(counts[FrameType.SLOW], 1)), dtype=np.int64)
        self.gps = np.empty((n_gps, max(counts[FrameType.GPS], 1)), dtype=np.int64)
        self.events = np.empty((n_events, 3), dtype=np.int64)
        self.counts = np.zeros(5, dtype=np.int64)

    def pointers(self) -> tuple[Any, ...]:
        return (
            _pointer(self.main),
            _pointer(self.main_slow),
            _pointer(self.main_gps),
            len(self.main),
            _pointer(self.slow),
            len(self.slow),
            _pointer(self.gps),
            len(self.gps),
            _pointer(self.events),
            len(self.events),
            _pointer(self.counts),
        )


def _assembled(out: _Outputs, data: bytes, counts: dict[Any, int]) -> CompiledLog:
    n_main, n_slow, n_gps, n_events, _ = (int(value) for value in out.counts)
    kept: list[tuple[int, str, dict[str, Any]]] = []
    for payload, code, before in out.events[:n_events].tolist():
        event = read_event(code, iter(data[payload : payload + _EVENT_BYTES]))
        if event is None:  # the kernel checked every payload: this is a bug, not a log
            raise AssertionError(f"the kernel passed an event read_event refuses ({code})")
        kept.append((before, *event))
    return CompiledLog(
        main=out.main[:n_main],
        slow_of=out.main_slow[:n_main],
        gps_of=out.main_gps[:n_main],
        slow=out.slow[:n_slow, : counts[FrameType.SLOW]],
        gps=out.gps[:n_gps, : counts[FrameType.GPS]],
        kept=kept,
    )


def _plan_table(parser: EventKeepingParser) -> npt.NDArray[np.int64] | None:
    """The plans as the kernel reads them (``load_plans`` in the C file), or None where a frame
    type has no plan or a predictor the kernel does not apply."""
    field_defs = parser.reader.field_defs
    ctx = parser._ctx
    header: list[int] = []
    body: list[int] = []
    for kind in _FRAME_TYPES:
        fdefs = field_defs.get(kind)
        if not fdefs:
            header.append(-1)
            continue
        plan = FramePlan.of(fdefs, ctx)
        if plan is None:
            return None
        runs = _kernel_runs(plan.runs)
        if runs is None:
            return None
        header.append(len(_FRAME_TYPES) + len(body))
        body += [len(fdefs), len(plan.steps), len(runs)]
        body += [number for step in plan.steps for number in step]
        body += [number for run in runs for number in run]
    return np.array(header + body, dtype=np.int64)


def _kernel_runs(runs: Sequence[tuple[int, int, int, Any]]) -> list[tuple[int, ...]] | None:
    kernel_runs: list[tuple[int, ...]] = []
    for how, first, end, what in runs:
        if how == _CALL:
            called = _CALLED.get(what)
            if called is None:
                return None
            kernel_runs.append((called, first, end, 0))
        elif isinstance(what, int) and not -_INT64_LIMIT <= what < _INT64_LIMIT:
            return None  # a header's constant past 64 bits
        else:
            kernel_runs.append((how, first, end, what if isinstance(what, int) else 0))
    return kernel_runs


def _read_raw(
    steps: tuple[tuple[int, int], ...], data: bytes, at: int
) -> tuple[list[int], int] | None:
    """One frame's raw values read by the kernel as FramePlan's ``_read`` reads them, and where
    the frame ends; None where the data ends inside it (the tests compare the two)."""
    read = load_kernel().bb_read_raw
    read.restype = _I64
    read.argtypes = [ctypes.c_char_p, _I64, _I64, _P64, _I64, _P64]
    table = np.array([number for step in steps for number in step] or [0], dtype=np.int64)
    raw = np.zeros(max(sum(count for _what, count in steps), 1), dtype=np.int64)
    end = read(data, len(data), at, _pointer(table), len(steps), _pointer(raw))
    if end < 0:
        return None
    values: list[int] = raw[: sum(count for _what, count in steps)].tolist()
    return values, int(end)


def _pointer(array: npt.NDArray[np.int64]) -> Any:
    return array.ctypes.data_as(_P64)


_function: Any = None


def _kernel_function() -> Any:
    """``bb_decode_frames``, typed (KernelUnavailableError without a compiled kernel)."""
    global _function
    if _function is None:
        function = load_kernel().bb_decode_frames
        function.restype = ctypes.c_int
        function.argtypes = [
            ctypes.c_char_p,
            _I64,
            _I64,
            _P64,
            _P64,
            _P64,
            _P64,
            _P64,
            _I64,
            _P64,
            _I64,
            _P64,
            _I64,
            _P64,
            _I64,
            _P64,
        ]
        _function = function
    return _function
