"""MSP payload codecs on the telemetry hot path: operations per second, before and after the
messages were declared once (``bfsitl.protocol.messages``), in the same run.

The "old" codecs are the hand-written module ``src/bfsitl/protocol/msp_messages.py`` as it was
before the split: by default the newest commit in which that file still defined the messages
itself (``--old-rev`` picks another), taken with ``git show``, written to a temporary file and
imported under another module name. Both decode the same payloads and encode equal messages.

Rows: decode and encode of ATTITUDE, ALTITUDE, STATUS, STATUS_EX, ANALOG, RC, MOTOR, RAW_IMU,
RAW_GPS; the telemetry batch (MSP_MULTIPLE_MSP reply decoded and its sub-replies decoded with
``decode_replies``); MSP_SET_RAW_RC encode. Each figure is the best of ``--repeats`` timeit runs.
Run: ``python benchmarks/msp_codec.py [--repeats 5] [--old-rev REV] [--json]``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import subprocess
import sys
import tempfile
import timeit
from collections.abc import Callable
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path
from types import ModuleType
from typing import Any

from bfsitl.fc.telemetry import TELEMETRY_COMMANDS
from bfsitl.protocol import messages as new

REPO = Path(__file__).resolve().parents[1]
OLD_PATH = "src/bfsitl/protocol/msp_messages.py"
OLD_MODULE = "bfsitl_msp_messages_before_split"


@dataclass
class Row:
    message: str
    operation: str
    old_ops_per_s: float
    new_ops_per_s: float

    @property
    def ratio(self) -> float:
        return self.new_ops_per_s / self.old_ops_per_s


def _git(*args: str) -> str:
    return subprocess.run(
        ["git", *args], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout


def old_source(rev: str | None) -> tuple[str, str]:
    """(revision, text) of the hand-written module: ``rev``, or the newest commit whose file
    still defines the message classes (later commits hold the facade, then delete it)."""
    if rev is not None:
        return rev, _git("show", f"{rev}:{OLD_PATH}")
    for commit in _git("log", "--format=%H", "--diff-filter=AM", "--", OLD_PATH).split():
        text = _git("show", f"{commit}:{OLD_PATH}")
        if "class Attitude" in text:
            return commit, text
    raise SystemExit(f"no commit of {OLD_PATH} defines the messages itself; pass --old-rev")


def load_old(text: str, workdir: Path) -> ModuleType:
    path = workdir / f"{OLD_MODULE}.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location(OLD_MODULE, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[OLD_MODULE] = module  # dataclasses look their module up while building
    spec.loader.exec_module(module)
    return module


def sample_messages(m: Any) -> dict[str, Any]:
    """One message of each hot-path type, with the values a flying SITL reports."""
    return {
        "Attitude": m.Attitude(-15, 100, 359),
        "Altitude": m.Altitude(1041, -5),
        "Status": m.Status(145, 0, 0x23, 0b11, 0, 12, 29, 0x304, 0, 0, 4),
        "StatusEx": m.StatusEx(145, 0, 0x23, 0b11, 0, 12, 4, 0, 29, 0x304, 0, 0, 4),
        "Analog": m.Analog(168, 258, 1023, -150, 1680),
        "Rc": m.Rc((1500, 1500, 1500, 1000, 1800) + (1500,) * 13),
        "Motor": m.Motor((1342, 1337, 1351, 1329, 0, 0, 0, 0)),
        "RawImu": m.RawImu((3, -5, 256), (939, 0, -939), (0, 0, 0)),
        "RawGps": m.RawGps(2, 12, 475_000_000, 85_000_000, 512, 300, 1800, 150),
    }


def _ops_per_s(fn: Callable[[], object], repeats: int) -> float:
    timer = timeit.Timer(fn)
    number, _ = timer.autorange()
    return number / min(timer.repeat(repeats, number))


def measure(old: ModuleType, repeats: int) -> list[Row]:
    new_msgs, old_msgs = sample_messages(new), sample_messages(old)
    rows: list[Row] = []
    for name, msg in new_msgs.items():
        payload = msg.encode()
        old_cls, new_cls, old_msg = getattr(old, name), type(msg), old_msgs[name]
        assert old_cls.decode(payload).encode() == payload == old_msg.encode()
        rows.append(
            Row(
                name,
                "decode",
                _ops_per_s(partial(old_cls.decode, payload), repeats),
                _ops_per_s(partial(new_cls.decode, payload), repeats),
            )
        )
        rows.append(
            Row(
                name, "encode", _ops_per_s(old_msg.encode, repeats), _ops_per_s(msg.encode, repeats)
            )
        )
    by_command = {type(msg).COMMAND: msg.encode() for msg in new_msgs.values()}
    batch = new.MultipleMspReply(tuple(by_command[c] for c in TELEMETRY_COMMANDS)).encode()
    commands = list(TELEMETRY_COMMANDS)

    def batch_of(m: Any) -> Callable[[], object]:
        return lambda: m.MultipleMspReply.decode(batch).decode_replies(commands)

    rows.append(
        Row(
            "MultipleMspReply (telemetry)",
            "decode_replies",
            _ops_per_s(batch_of(old), repeats),
            _ops_per_s(batch_of(new), repeats),
        )
    )
    sticks = (1500, 1500, 1000, 1500, 1800, 1000, 1000, 1000)
    old_rc, new_rc = old.SetRawRc(sticks), new.SetRawRc(sticks)
    assert old_rc.encode() == new_rc.encode()
    rows.append(
        Row(
            "SetRawRc (8 channels)",
            "encode",
            _ops_per_s(old_rc.encode, repeats),
            _ops_per_s(new_rc.encode, repeats),
        )
    )
    return rows


def print_table(rows: list[Row], rev: str) -> None:
    print(f"old: {OLD_PATH} at {rev[:12]}; new: bfsitl.protocol.messages")
    header = f"{'message':<30} {'operation':<15} {'old ops/s':>12} {'new ops/s':>12} {'new/old':>8}"
    print(header)
    print("-" * len(header))
    for row in rows:
        print(
            f"{row.message:<30} {row.operation:<15} {row.old_ops_per_s:>12,.0f} "
            f"{row.new_ops_per_s:>12,.0f} {row.ratio:>8.2f}"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timeit runs per figure")
    parser.add_argument("--old-rev", help="git revision of the hand-written msp_messages.py")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = parser.parse_args(argv)
    rev, text = old_source(args.old_rev)
    with tempfile.TemporaryDirectory(prefix="msp-codec-bench-") as workdir:
        old = load_old(text, Path(workdir))
        rows = measure(old, args.repeats)
    if args.json:
        print(json.dumps([{**asdict(row), "ratio": row.ratio} for row in rows], indent=2))
    else:
        print_table(rows, rev)
    return 0


if __name__ == "__main__":
    sys.exit(main())
