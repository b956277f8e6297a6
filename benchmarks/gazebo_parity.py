"""The embedded IRIS against Gazebo Harmonic's IRIS: one programme of manoeuvres, one firmware.

The same stock 4.6.0 SITL, with the same provisioning, flies the same programme twice at real
time: on Gazebo (``gz sim`` with the BetaflightPlugin and bfsitl's world, Gazebo's state read
by bfsitl's relay) and on the embedded physics with the IRIS profile, ideal sensors and the
same heading (east).  The programme: take off to 3 m and hold; a 0.5 s stick step to 1700 us
on roll, on pitch and on yaw, each followed by a hold; a climb to 6 m, a descent to 2 m, a
turn to the opposite heading; land.  Both flights log the FC's blackbox (``--out``), so
``bfsitl log replay`` and ``bfsitl log fit`` can measure Gazebo's flight the way they measure a
real one.

Per manoeuvre it prints each physics' figures side by side (the peak angle and when it came,
the climb's time and rate, the hover throttle) and the error between the two traces: the RMS
difference of the response (angle, altitude) over the manoeuvre on a common 10 ms grid,
aligned at its start.

Each kind of flight is flown ``--repeats`` times (default 2): the difference between two
flights on the same physics is the noise floor (real time, a stock SITL, two cores) the
difference between the physics is read against.  ``--own-stamps`` adds Gazebo flights with
the plugin's own fdm timestamps forwarded unchanged, as the tutorial has them.

``--record DIR`` keeps Gazebo's first flight as test data (``tests/data/gazebo``, see
:func:`compact_recording`): the plugin's fdm and servo packets as the relay saw them, Gazebo's
own poses from its scene broadcaster (``gz topic``, the world's ``dynamic_pose/info``), the
packets' arrival times and the FC's view of the flight (the flight log's rows).

Needs Gazebo Harmonic and the plugin (docs/gazebo.md).  Run:
``python benchmarks/gazebo_parity.py [--repeats 2] [--own-stamps] [--out DIR] [--plot PNG]
[--record DIR] [--json FILE]``; ``--from DIR`` reports flights flown before.
"""

from __future__ import annotations

import argparse
import dataclasses
import gzip
import json
import math
import os
import shutil
import statistics
import struct
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: The stick deflection of each step and how long it is held.
STEP_US = 1700
STEP_S = 0.5
#: How long the response of a step is followed (the step and the recovery after it).
STEP_WINDOW_S = 2.5
HOLD_S = 3.0
#: Gazebo's quad faces east at the start; the embedded one is turned to match.
HEADING_DEG = 90.0
#: The scene broadcaster's topic of the moving entities' poses in bfsitl's world.
POSE_TOPIC = "/world/empty_betaflight_world/dynamic_pose/info"


class StickStep:
    """A StickPilot that holds one stick at ``STEP_US`` and leaves the others as they are."""

    rate_hz: float | None = None
    target_alt_m: float | None = None

    def __init__(self, axis: str) -> None:
        self.axis = axis
        self.name = f"a {axis} step"

    def sticks(self, sample: Any, command: Any) -> Any:
        return dataclasses.replace(command, **{f"{self.axis}_us": STEP_US})


class PacketLog:
    """The relay's recorder: every packet's arrival (tap clock) and bytes."""

    def __init__(self) -> None:
        self.packets: dict[str, list[tuple[float, bytes]]] = {"fdm": [], "servo": []}

    def __call__(self, kind: str, wall_s: float, data: bytes) -> None:
        self.packets[kind].append((wall_s, data))


def fly(
    name: str,
    firmware: str,
    out: Path,
    record: PacketLog | None,
    progress: Callable[[str], None],
) -> dict[str, Any]:
    """One flight of the programme; its rows, the manoeuvres' times, the relay's counts and
    the FC's clock rate.  ``name``: ``gazebo``, ``gazebo-own-stamps`` (the plugin's timestamps
    forwarded as they are, as in the tutorial) or ``embedded``."""
    from bfsitl import Autopilot
    from bfsitl.backend.options import World
    from bfsitl.errors import BfsitlError
    from bfsitl.fc.provisioning import Profile
    from bfsitl.mission import FLY_PROFILE, FlightSession, SessionConfig
    from bfsitl.mission.session import FcSetup, SitlLaunch
    from bfsitl.physics.params import IRIS
    from bfsitl.physics.sensors import SensorConfig
    from bfsitl.protocol import messages as msg
    from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE
    from bfsitl.scenario.setup_lines import blackbox_cli

    physics = "embedded" if name.startswith("embedded") else "gazebo"
    workdir = out / name
    shutil.rmtree(workdir, ignore_errors=True)
    # 1 kHz of blackbox (8 kHz PID loop / 8) for the replay's step responses.
    lines = tuple(
        "set blackbox_sample_rate = 1/8" if line.startswith("set blackbox_sample_rate") else line
        for line in blackbox_cli(DEFAULT_PROFILE)
    )
    profile = Profile(
        mode_ranges=FLY_PROFILE.mode_ranges,
        cli_lines=(*FLY_PROFILE.cli_lines, *lines),
        reboot_when_changed=True,
    )
    config = SessionConfig.for_autopilot(
        sitl=SitlLaunch(firmware=firmware, workdir=workdir),
        world=World(
            physics=physics,  # type: ignore[arg-type]
            quad=IRIS,
            sensors=SensorConfig(),
            initial_heading_deg=HEADING_DEG if physics == "embedded" else 0.0,
        ),
        fc=FcSetup(profile=profile),
    )
    marks: dict[str, tuple[float, float]] = {}
    pose_log = workdir / "gazebo-poses.jsonl"
    with FlightSession(config, progress=progress) as vehicle:
        backend: Any = vehicle.backend
        if name.startswith("gazebo-own-stamps"):
            backend.tap.next_timestamp = None  # from the next packet on
        if physics == "gazebo":
            if record is not None:
                backend.tap.recorder = record
                sitl: Any = vehicle.sitl
                env = dict(os.environ, GZ_IP=os.environ.get("GZ_IP", "127.0.0.1"))
                sitl.network.spawn(
                    [shutil.which("gz") or "gz", "topic", "-e", "--json-output", "-t", POSE_TOPIC],
                    workdir,
                    pose_log,
                    env=env,
                )
        pilot = Autopilot(vehicle)
        # MSP_MOTOR in each sample's round trip: the FC's own motors, beside the servo packets.
        vehicle.read_with_samples(msg.Motor)
        fc_motors: list[list[float]] = []
        logged = pilot.loop._on_row

        def on_row(row: Any, sample: Any) -> None:
            motors_us = vehicle.reading(msg.Motor, sample).motors_us[:4]
            fc_motors.append([(us - 1000) / 1000.0 for us in motors_us])
            if logged is not None:
                logged(row, sample)

        pilot.loop._on_row = on_row

        def mark(name: str, manoeuvre: Callable[[], object]) -> None:
            start_s = vehicle.time_s
            manoeuvre()
            marks[name] = (start_s, vehicle.time_s)

        failed = None
        try:
            mark("takeoff", lambda: pilot.takeoff(3.0))
            mark("hover", lambda: pilot.hold(HOLD_S))
            for axis in ("roll", "pitch", "yaw"):
                mark(axis, lambda axis=axis: pilot.fly_sticks(StickStep(axis), STEP_S))
                mark(f"after {axis}", lambda: pilot.hold(HOLD_S))
            mark("climb", lambda: pilot.loop.climb_to(6.0))
            mark("hold high", lambda: pilot.hold(2.0))
            mark("descent", lambda: pilot.loop.climb_to(2.0))
            mark("hold low", lambda: pilot.hold(2.0))
            mark("turn", lambda: pilot.yaw_to((HEADING_DEG + 180.0) % 360.0))
            mark("land", pilot.land)
        except BfsitlError as exc:  # a flight that failed is a result too
            failed = str(exc)
            progress(f"the flight failed: {exc}")
        counts = backend.tap.counts() if physics == "gazebo" else None
    rows = [
        dataclasses.asdict(row) | {f"fc_motor{i + 1}": m for i, m in enumerate(motors)}
        for row, motors in zip(pilot.rows, fc_motors, strict=True)
    ]
    flight = {
        "physics": physics,
        "failed": failed,
        "fc_clock_rate": fc_clock_rate(workdir, rows),
        "rows": rows,
        "marks": marks,
        "real_time_factor": counts.real_time_factor if counts else None,
        "packets": dataclasses.asdict(counts) if counts else None,
        "pose_log": str(pose_log) if pose_log.is_file() else None,
    }
    (workdir / "flight.json").write_text(json.dumps(flight, default=str) + "\n")
    return flight


def fc_clock_rate(workdir: Path, rows: list[dict[str, Any]]) -> float:
    """The FC's time per mission-clock time while armed: its blackbox log's span over the
    armed rows' span (1.00 when the FC keeps time with the physics)."""
    from bfsitl.blackbox import decode_blackbox, find_blackbox_files

    armed = [r["time_s"] for r in rows if r["armed"]]
    logs = [log for path in find_blackbox_files(workdir) for log in decode_blackbox(path)]
    if not logs or len(armed) < 2:
        return math.nan
    frames = max(logs, key=lambda log: len(log.frames)).frames
    return (frames[-1].time_s - frames[0].time_s) / (armed[-1] - armed[0])


def plot(flights: dict[str, dict[str, Any]], path: Path) -> None:
    """The step responses and the climb and descent of both flights, overlaid."""
    from bfsitl.headless_pyplot import load_pyplot

    plt = load_pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.5), constrained_layout=True)
    styles = {
        "gazebo": ("Gazebo Harmonic", "tab:blue", "-"),
        "embedded": ("embedded IRIS", "tab:orange", "--"),
    }
    for physics, flight in flights.items():
        label, colour, line = styles[physics]
        for ax, axis in zip(axes[0], ("roll", "pitch", "yaw"), strict=True):
            t, v = zip(*step_response(flight, axis), strict=True)
            ax.plot(t, v, line, color=colour, label=label)
            ax.set_title(f"{axis}: stick {STEP_US} us for {STEP_S:g} s")
            ax.set_xlabel("s from the step")
            ax.set_ylabel("true angle change (deg)")
            ax.axvspan(0, STEP_S, color="0.9")
        for ax, name in zip(axes[1][:2], ("climb", "descent"), strict=True):
            start, end = flight["marks"][name]
            t, v = zip(*_series(flight["rows"], "sim_alt_m", start, end + 1.0), strict=True)
            ax.plot(t, v, line, color=colour, label=label)
            ax.set_title(f"{name} (altitude hold to {'6' if name == 'climb' else '2'} m)")
            ax.set_xlabel("s from the command")
            ax.set_ylabel("true altitude (m)")
        start, end = flight["marks"]["roll"]
        motors = [
            (r["time_s"] - start, r["motor1"], r["motor3"])
            for r in flight["rows"]
            if start <= r["time_s"] <= start + STEP_WINDOW_S
        ]
        t, right, left = zip(*motors, strict=True)
        axes[1][2].plot(t, right, line, color=colour, label=f"{label}: M1 (rear right)")
        axes[1][2].plot(t, left, line, color=colour, alpha=0.5, label=f"{label}: M3 (rear left)")
    axes[1][2].set_title("roll step: motor commands")
    axes[1][2].set_xlabel("s from the step")
    axes[1][2].set_ylabel("command (0..1)")
    axes[1][2].legend(fontsize=7)
    axes[0][0].legend(fontsize=8)
    fig.savefig(path, dpi=90)
    plt.close(fig)


# ---- figures ------------------------------------------------------------------------------


def _series(
    rows: list[dict[str, Any]], key: str, start_s: float, end_s: float
) -> list[tuple[float, float]]:
    return [(r["time_s"] - start_s, r[key]) for r in rows if start_s <= r["time_s"] <= end_s]


def _at(series: list[tuple[float, float]], t_s: float) -> float:
    """Linear interpolation (the ends held)."""
    if t_s <= series[0][0]:
        return series[0][1]
    for (t0, v0), (t1, v1) in zip(series, series[1:], strict=False):
        if t0 <= t_s <= t1:
            return v0 if t1 == t0 else v0 + (v1 - v0) * (t_s - t0) / (t1 - t0)
    return series[-1][1]


def _unwrap(series: list[tuple[float, float]]) -> list[tuple[float, float]]:
    out: list[tuple[float, float]] = []
    offset = 0.0
    for index, (t, v) in enumerate(series):
        if index:
            jump = v + offset - out[-1][1]
            offset -= 360.0 * round(jump / 360.0)
        out.append((t, v + offset))
    return out


AXIS_KEY = {"roll": "sim_roll_deg", "pitch": "sim_pitch_deg", "yaw": "sim_yaw_deg"}


def step_response(flight: dict[str, Any], axis: str) -> list[tuple[float, float]]:
    """The truth's angle on ``axis`` from the step's start, relative to it (degrees)."""
    start_s = flight["marks"][axis][0]
    series = _unwrap(_series(flight["rows"], AXIS_KEY[axis], start_s, start_s + STEP_WINDOW_S))
    origin = series[0][1]
    return [(t, v - origin) for t, v in series]


def rms_difference(
    a: list[tuple[float, float]], b: list[tuple[float, float]], span_s: float
) -> float:
    grid = [i * 0.01 for i in range(int(span_s / 0.01) + 1)]
    return math.sqrt(sum((_at(a, t) - _at(b, t)) ** 2 for t in grid) / len(grid))


def figures(flight: dict[str, Any]) -> dict[str, float]:
    rows, marks = flight["rows"], flight["marks"]
    out: dict[str, float] = {}
    start, end = marks["hover"]
    hover = [r for r in rows if start <= r["time_s"] <= end]
    out["hover throttle (us)"] = sum(r["rc_throttle_us"] for r in hover) / len(hover)
    out["hover motor command"] = sum(
        (r["motor1"] + r["motor2"] + r["motor3"] + r["motor4"]) / 4 for r in hover
    ) / len(hover)
    for axis in ("roll", "pitch"):
        # A stick above centre is right wing down and nose down: positive in Betaflight's.
        response = step_response(flight, axis)
        held = [(t, v) for t, v in response if t <= STEP_S]
        peak = max(v for _, v in held)
        out[f"{axis}: peak in the step (deg)"] = peak
        out[f"{axis}: time to 90 % of it (s)"] = next(t for t, v in held if v >= 0.9 * peak)
        out[f"{axis}: swing back after it (deg)"] = min(v for t, v in response if t > STEP_S)
    response = step_response(flight, "yaw")
    out["yaw: turned in the step (deg)"] = _at(response, STEP_S)
    out[f"yaw: turned {STEP_WINDOW_S:g} s on (deg)"] = response[-1][1]
    for name, target in (("climb", 6.0), ("descent", 2.0)):
        start, end = marks[name]
        series = _series(rows, "sim_alt_m", start, end)
        first = series[0][1]
        ninety = first + 0.9 * (target - first)
        reached = next((t for t, v in series if (v - ninety) * (target - first) >= 0), math.nan)
        rates = [r["sim_climb_m_s"] for r in rows if start <= r["time_s"] <= end]
        out[f"{name}: time to 90 % (s)"] = reached
        out[f"{name}: peak rate (m/s)"] = max(rates, key=abs)
    start, end = marks["turn"]
    out["turn of 180 deg: time (s)"] = end - start
    return out


def trace_errors(a: dict[str, Any], b: dict[str, Any]) -> dict[str, float]:
    """The RMS difference of each manoeuvre's response between two flights."""
    out = {}
    for axis in ("roll", "pitch", "yaw"):
        out[f"{axis} step: angle RMS diff (deg)"] = rms_difference(
            step_response(a, axis), step_response(b, axis), STEP_WINDOW_S
        )
    for name in ("climb", "descent"):
        series = []
        for flight in (a, b):
            start, end = flight["marks"][name]
            series.append(_series(flight["rows"], "sim_alt_m", start, end))
        span = min(s[-1][0] for s in series)
        out[f"{name}: altitude RMS diff (m)"] = rms_difference(series[0], series[1], span)
    return out


# ---- recording ----------------------------------------------------------------------------


def _gazebo_poses(pose_log: Path) -> list[dict[str, Any]]:
    """(sim time, the model's and imu_link's poses) of each scene message, in order."""
    poses = []
    for line in pose_log.read_text().splitlines():
        try:
            message = json.loads(line)
        except json.JSONDecodeError:
            continue
        stamp = message.get("header", {}).get("stamp", {})
        sim_s = float(stamp.get("sec", 0)) + float(stamp.get("nsec", 0)) * 1e-9
        entities = {p.get("name"): p for p in message.get("pose", [])}
        keep = {
            name: {
                "position": [entities[name].get("position", {}).get(k, 0.0) for k in "xyz"],
                "orientation_wxyz": [
                    entities[name].get("orientation", {}).get(k, 0.0) for k in "wxyz"
                ],
            }
            for name in ("iris_with_Betaflight", "iris_with_standoffs", "base_link", "imu_link")
            if name in entities
        }
        if keep:
            poses.append({"sim_time_s": sim_s, "entities": keep})
    return poses


#: The flight log's columns kept beside the packets: the FC's view (MSP: attitude, altitude,
#: MSP_MOTOR as 0..1) and the sticks.
FC_COLUMNS = (
    "time_s",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "fc_alt_m",
    "rc_roll_us",
    "rc_pitch_us",
    "rc_throttle_us",
    "rc_yaw_us",
    "fc_motor1",
    "fc_motor2",
    "fc_motor3",
    "fc_motor4",
    "armed",
)
#: Every packet's arrival is kept for this long in the hover (the timing's sample).
TIMING_WINDOW_S = 5.0
#: One servo packet in this many is kept (about 50 Hz).
SERVO_EVERY = 20


def _rounded(value: Any, places: int = 7) -> Any:
    if isinstance(value, float):
        return round(value, places)
    if isinstance(value, list | tuple):
        return [_rounded(v, places) for v in value]
    if isinstance(value, dict):
        return {k: _rounded(v, places) for k, v in value.items()}
    return value


def compact_recording(full: dict[str, Any]) -> dict[str, Any]:
    """The test data from everything recorded: ``full`` has ``meta``, ``fdm`` and ``servo``
    (every packet as ``(wall_s, bytes)``), ``gazebo_poses`` and ``rows`` (the flight log's).

    Kept: the fdm packets stamped with the sim time of a kept Gazebo pose (so that each has
    Gazebo's own pose beside it), every ``SERVO_EVERY``-th servo packet, every packet's
    arrival in a few seconds of the hover, and the flight log's rows at 50 Hz."""
    start_s, _ = full["meta"]["marks"]["hover"]
    window = (start_s, start_s + TIMING_WINDOW_S)

    def intervals_us(packets: list[tuple[float, bytes]]) -> list[int]:
        inside = [t for t, _ in packets if window[0] <= t <= window[1]]
        return [round((b - a) * 1e6) for a, b in zip(inside, inside[1:], strict=False)]

    pose_times_ms = {round(pose["sim_time_s"] * 1000.0) for pose in full["gazebo_poses"]}
    fdm = [
        [round(t, 6), data.hex()]
        for t, data in full["fdm"]
        if len(data) == 144 and round(struct.unpack_from("<d", data)[0] * 1000.0) in pose_times_ms
    ]
    rows = full["rows"][::2]
    return {
        "meta": full["meta"] | {"timing_window_s": list(window), "servo_every": SERVO_EVERY},
        "fdm": fdm,
        "servo": [[round(t, 6), data.hex()] for t, data in full["servo"][::SERVO_EVERY]],
        "timing": {
            "fdm_intervals_us": intervals_us(full["fdm"]),
            "servo_intervals_us": intervals_us(full["servo"]),
        },
        "gazebo_poses": _rounded(full["gazebo_poses"]),
        "fc": {
            "columns": list(FC_COLUMNS),
            "rows": [[_rounded(row[k], 4) for k in FC_COLUMNS] for row in rows],
        },
    }


def write_recording(
    flight: dict[str, Any], packets: PacketLog, firmware: str, directory: Path
) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    poses = _gazebo_poses(Path(flight["pose_log"])) if flight["pose_log"] else []
    full = {
        "meta": {
            "firmware": firmware,
            "world": "bfsitl/gazebo/worlds/iris_betaflight.sdf",
            "marks": flight["marks"],
            "packets": flight["packets"],
        },
        "fdm": packets.packets["fdm"],
        "servo": packets.packets["servo"],
        # Gazebo's scene messages come at about 60 Hz; every 3rd is plenty.
        "gazebo_poses": poses[::3],
        "rows": flight["rows"],
    }
    (directory / "exchange.json.gz").write_bytes(
        gzip.compress(json.dumps(compact_recording(full), separators=(",", ":")).encode(), mtime=0)
    )


# ---- main ---------------------------------------------------------------------------------


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--firmware", default="4.6.0", help="a stock build (default 4.6.0)")
    parser.add_argument("--out", type=Path, help="the flights' run directories and blackbox logs")
    parser.add_argument("--record", type=Path, help="write Gazebo's flight as test data here")
    parser.add_argument(
        "--repeats", type=int, default=2, help="flights per physics (default 2: the noise floor)"
    )
    parser.add_argument(
        "--own-stamps",
        action="store_true",
        help="fly Gazebo a second time with the plugin's own timestamps, as the tutorial does",
    )
    parser.add_argument("--json", type=Path, help="write the flights' figures as JSON")
    parser.add_argument("--plot", type=Path, help="draw the responses side by side (PNG)")
    parser.add_argument(
        "--from", dest="again", type=Path, help="figures of flights flown before (their --out)"
    )
    args = parser.parse_args()
    if args.again:
        flights = {
            path.parent.name: json.loads(path.read_text())
            for path in sorted(args.again.glob("*/flight.json"))
        }
        return report(flights, args)

    from bfsitl.errors import GazeboNotFoundError
    from bfsitl.gazebo import check_gazebo

    try:
        check_gazebo(None)
    except GazeboNotFoundError as exc:
        print(f"gazebo_parity: {exc}")
        return 2
    out = args.out or Path(tempfile.mkdtemp(prefix="gazebo-parity-"))
    packets = PacketLog() if args.record else None
    progress = lambda line: print(f"  {line}", file=sys.stderr)  # noqa: E731
    kinds = ["gazebo", "embedded"] + (["gazebo-own-stamps"] if args.own_stamps else [])
    flights = {}
    for repeat in range(1, args.repeats + 1):
        for kind in kinds:
            name = f"{kind}-{repeat}"
            print(f"flying the programme: {name} ...", file=sys.stderr)
            recorder = packets if name == "gazebo-1" else None
            flights[name] = fly(name, args.firmware, out, recorder, progress)
    if args.record and packets is not None:
        write_recording(flights["gazebo-1"], packets, args.firmware, args.record)
    print(f"run directories and blackbox logs: {out}")
    return report(flights, args)


def report(flights: dict[str, dict[str, Any]], args: argparse.Namespace) -> int:
    """The median of each figure per kind of flight and its spread (largest - smallest), then
    the RMS difference of the responses: between repeats of one kind (the noise floor) and
    between the kinds."""
    kinds = [k for k in ("gazebo", "embedded", "gazebo-own-stamps") if f"{k}-1" in flights]
    for name, flight in flights.items():
        if flight.get("failed"):
            print(f"{name} failed (left out below): {flight['failed']}")
    of_kind = {
        k: [f for n, f in flights.items() if n.rsplit("-", 1)[0] == k and not f.get("failed")]
        for k in kinds
    }
    kinds = [k for k in kinds if of_kind[k]]
    table: dict[str, dict[str, tuple[float, float]]] = {}
    for kind in kinds:
        runs = [
            figures(flight) | {"FC clock / wall clock": flight["fc_clock_rate"]}
            for flight in of_kind[kind]
        ]
        table[kind] = {
            figure: (
                statistics.median(r[figure] for r in runs),
                max(r[figure] for r in runs) - min(r[figure] for r in runs),
            )
            for figure in runs[0]
        }
    counted = ", ".join(f"{len(of_kind[k])} {k}" for k in kinds)
    print(f"median (spread: largest - smallest) of the flights that landed: {counted}")
    print(f"{'figure':34}" + "".join(f" {k:>20}" for k in kinds))
    for figure in table["gazebo"]:
        cells = "".join(f" {table[k][figure][0]:11.3f} ({table[k][figure][1]:5.3f})" for k in kinds)
        print(f"{figure:34}{cells}")
    pairs = {
        "Gazebo vs Gazebo": ("gazebo", "gazebo"),
        "embedded vs embedded": ("embedded", "embedded"),
        "embedded vs Gazebo": ("embedded", "gazebo"),
    }
    if "gazebo-own-stamps" in kinds:
        pairs["embedded vs Gazebo's own stamps"] = ("embedded", "gazebo-own-stamps")
    errors: dict[str, dict[str, float]] = {}
    for label, (a, b) in pairs.items():
        compared = [
            trace_errors(x, y)
            for i, x in enumerate(of_kind[a])
            for j, y in enumerate(of_kind[b])
            if a != b or i < j
        ]
        if compared:
            errors[label] = {k: statistics.mean(e[k] for e in compared) for k in compared[0]}
    print("\nRMS difference of the responses (mean over the pairs of flights)")
    print(f"{'':34}" + "".join(f" {label:>22}" for label in errors))
    for figure in next(iter(errors.values())):
        print(f"{figure:34}" + "".join(f" {errors[label][figure]:22.3f}" for label in errors))
    rtf = [f["real_time_factor"] for f in of_kind["gazebo"]]
    print(f"\nGazebo's real-time factor while flown: {', '.join(f'{x:.3f}' for x in rtf)}")
    if args.plot:
        plot({"gazebo": of_kind["gazebo"][0], "embedded": of_kind["embedded"][0]}, args.plot)
    if args.json:
        args.json.write_text(json.dumps({"figures": table, "errors": errors, "rtf": rtf}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
