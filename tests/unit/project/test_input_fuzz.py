"""Every file bfsitl reads, fed garbage: the only outcomes allowed are a valid result or the
project's own error naming the file.  Never a traceback of another kind.

The readers: missions and scenarios (TOML), profiles and ``bfsitl cli --file`` (CLI lines),
build records (``build.json`` in the firmware cache).  Inputs: arbitrary bytes, arbitrary text,
the shipped files with random damage, and TOML-shaped data with the right keys and wrong
values of every type.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bfsitl.build.cache import FirmwareCache
from bfsitl.build.metadata import METADATA_NAME, metadata_for_binary
from bfsitl.errors import MissionError, ProvisioningError, ScenarioError
from bfsitl.fc.provisioning import Profile
from bfsitl.library import mission_files, scenario_files
from bfsitl.mission.plan import load_mission, plan_from_dict
from bfsitl.scenario.load import load_scenario
from bfsitl.scenario.spec import scenario_from_dict

FUZZ = settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)

READERS = {
    "mission": (load_mission, MissionError),
    "scenario": (load_scenario, ScenarioError),
    "profile": (Profile.from_file, ProvisioningError),
}

# TOML's values: scalars of every type (the awkward floats too), arrays and tables.
toml_scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20),
    st.sampled_from([0, -1, 1e9, -1e-9, "", "auto", "switch", "master-lockstep"]),
)
toml_values = st.recursive(
    toml_scalars,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)

MISSION_KEYS = [
    "takeoff_alt_m",
    "speed_m_s",
    "land",
    "hold_position",
    "hold_s",
    "waypoint",
    "north_m",
    "east_m",
    "alt_m",
    "heading_deg",
]
SCENARIO_KEYS = [
    "description",
    "firmware",
    "requires_gps",
    "duration_s",
    "settle_s",
    "seed",
    "cli",
    "vehicle",
    "wind",
    "flight",
    "fault",
    "expect",
    "mass_kg",
    "north_m_s",
    "east_m_s",
    "gust_std_m_s",
    "at_s",
    "kind",
    "method",
]


def _tables(keys: list[str]) -> st.SearchStrategy[dict[str, Any]]:
    """Dicts with the reader's own keys (and a few others), values of any TOML type, nested
    the way the files nest them (a waypoint or fault list of tables, a wind table...)."""
    table = st.dictionaries(st.sampled_from(keys) | st.text(max_size=6), toml_values, max_size=6)
    nested = st.dictionaries(st.sampled_from(keys), table | st.lists(table, max_size=3), max_size=3)
    return st.builds(lambda a, b: {**a, **b}, table, nested)


def _check(read: Any, error: type[Exception], path: Path) -> None:
    try:
        read(path)
    except error as exc:
        assert str(path) in str(exc), f"the error does not name the file: {exc}"


@pytest.mark.parametrize("kind", sorted(READERS))
@FUZZ
@given(data=st.binary(max_size=300))
def test_any_bytes_give_a_result_or_an_error_naming_the_file(
    kind: str, data: bytes, tmp_path: Path
) -> None:
    read, error = READERS[kind]
    path = tmp_path / f"input-{kind}.toml"
    path.write_bytes(data)
    _check(read, error, path)


def _damaged(original: str, edits: list[tuple[int, int, str]]) -> str:
    text = original
    for position, length, insert in edits:
        at = position % (len(text) + 1)
        text = text[:at] + insert + text[at + length :]
    return text


edits = st.lists(
    st.tuples(
        st.integers(0, 10_000),
        st.integers(0, 8),
        st.sampled_from(
            [
                "",
                "=",
                "[",
                "]",
                '"',
                "\n",
                "-",
                "1e400",
                "nan",
                "[[fault]]",
                "\x00",
                "é",
                "true",
                "{",
            ]
        ),
    ),
    min_size=1,
    max_size=5,
)


@FUZZ
@given(edits=edits, which=st.integers(0, 100))
def test_damaged_shipped_scenarios_give_a_result_or_an_error_naming_the_file(
    edits: list[tuple[int, int, str]], which: int, tmp_path: Path
) -> None:
    files = scenario_files()
    source = files[which % len(files)]
    path = tmp_path / source.name
    path.write_text(_damaged(source.read_text(), edits))
    _check(load_scenario, ScenarioError, path)


@FUZZ
@given(edits=edits)
def test_damaged_shipped_missions_give_a_result_or_an_error_naming_the_file(
    edits: list[tuple[int, int, str]], tmp_path: Path
) -> None:
    source = mission_files()[0]
    path = tmp_path / source.name
    path.write_text(_damaged(source.read_text(), edits))
    _check(load_mission, MissionError, path)


@settings(max_examples=300, deadline=None)
@given(data=_tables(MISSION_KEYS))
def test_mission_tables_of_any_shape_give_a_plan_or_a_mission_error(data: dict[str, Any]) -> None:
    try:
        plan = plan_from_dict(data, source="fuzz.toml")
    except MissionError as exc:
        assert "fuzz.toml" in str(exc), exc
        return
    assert math.isfinite(plan.target_alt_m) and plan.target_alt_m > 0


@settings(max_examples=300, deadline=None)
@given(data=_tables(SCENARIO_KEYS))
def test_scenario_tables_of_any_shape_give_a_scenario_or_a_scenario_error(
    data: dict[str, Any],
) -> None:
    try:
        scenario = scenario_from_dict(data, name="fuzz", source=Path("fuzz.toml"))
    except ScenarioError as exc:
        assert "fuzz.toml" in str(exc), exc
        return
    assert scenario.duration_s > 0


@FUZZ
@given(lines=st.lists(st.text(max_size=40), max_size=8))
def test_profile_lines_of_any_text_give_a_profile_or_an_error_naming_the_file(
    lines: list[str], tmp_path: Path
) -> None:
    path = tmp_path / "profile.txt"
    path.write_text("\n".join(lines), encoding="utf-8", errors="surrogatepass") if not any(
        "\ud800" <= c <= "\udfff" for line in lines for c in line
    ) else path.write_bytes(b"\xed\xa0\x80")
    try:
        profile = Profile.from_file(path)
    except ProvisioningError as exc:
        assert str(path) in str(exc)
        return
    # What reaches the FC is printable: a control byte would switch its port's mode.
    assert all(c >= " " and c != "\x7f" for line in profile.cli_lines for c in line)


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=10),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3)
    ),
    max_leaves=10,
)


def _a_build_record(tmp_path: Path) -> dict[str, Any]:
    """A real-looking record to damage: every field of a build bfsitl makes."""
    return {
        "name": "fuzz",
        "key": "0123456789abcdef0123",
        "firmware_version": "4.6.0",
        "msp_api_version": "1.47",
        "git_revision": None,
        "defines": [],
        "make_defines": [],
        "gps_requested": False,
        "gps": False,
        "features": [],
        "options": {},
        "source_kind": "package",
        "source_path": str(tmp_path),
        "source_fingerprint": "f" * 20,
        "recipe_version": 1,
        "built_at": "2026-01-01T00:00:00+00:00",
        "build_duration_s": 1.0,
        "compiled_files": 1,
        "jobs": 1,
        "make_command": ["make"],
        "binary_name": "sitl",
        "takes_ip_flag": False,
        "bfsitl_version": "0",
        "schema": 1,
    }


@FUZZ
@given(
    change=st.dictionaries(
        st.sampled_from(sorted(_a_build_record(Path("/")))), json_values, min_size=1, max_size=4
    ),
    raw=st.one_of(st.none(), st.binary(max_size=60)),
)
def test_damaged_build_records_never_break_reading_the_cache(
    change: dict[str, Any], raw: bytes | None, tmp_path: Path
) -> None:
    cache = FirmwareCache(tmp_path / "cache")
    entry = cache.builds_dir / "0123456789abcdef0123"
    entry.mkdir(parents=True, exist_ok=True)
    (entry / "sitl").write_bytes(b"\x7fELF")
    record = entry / METADATA_NAME
    if raw is None:
        record.write_text(json.dumps({**_a_build_record(tmp_path), **change}))
    else:
        record.write_bytes(raw)
    found = metadata_for_binary(entry / "sitl")
    entries = cache.entries()
    for item in entries:  # what `firmware list` shows of each
        assert isinstance(item.metadata.name, str) and isinstance(item.label, str)
        assert isinstance(item.metadata.options_text, str)
    if found is not None:
        assert isinstance(found.binary_name, str)


def test_firmware_list_survives_a_corrupt_record(tmp_path: Path) -> None:
    cache = FirmwareCache(tmp_path / "cache")
    for key, content in (
        ("a" * 20, b"\xff\xfe garbage"),
        ("b" * 20, b'{"schema": 1}'),
        (
            "c" * 20,
            json.dumps(
                {**_a_build_record(tmp_path), "key": "c" * 20, "options": [1, 2], "defines": 7}
            ).encode(),
        ),
    ):
        entry = cache.builds_dir / key
        entry.mkdir(parents=True)
        (entry / "sitl").write_bytes(b"\x7fELF")
        (entry / METADATA_NAME).write_bytes(content)
    env = {**os.environ, "BFSITL_CACHE_DIR": str(cache.root)}
    for args in (["firmware", "list"], ["firmware", "list", "--json"]):
        run = subprocess.run(
            [sys.executable, "-m", "bfsitl.cli.main", *args],
            capture_output=True,
            text=True,
            env=env,
            timeout=60,
        )
        assert run.returncode == 0, run.stderr
        assert "Traceback" not in run.stderr


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["fly", "--mission"], "mission"),
        (["scenario", "list"], "scenario"),
        (["scenario", "run"], "scenario"),
        (["fly", "--profile"], "profile"),
        (["cli", "--file"], "command"),
    ],
)
def test_the_commands_say_a_binary_file_in_one_line(
    argv: list[str], names: str, tmp_path: Path
) -> None:
    garbage = tmp_path / "garbage.bin"
    garbage.write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff\xfe" + bytes(range(256)))
    env = {**os.environ, "BFSITL_FIRMWARE": str(tmp_path / "no-such-sitl")}
    run = subprocess.run(
        [sys.executable, "-m", "bfsitl.cli.main", *argv, str(garbage)],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
        cwd=tmp_path,
    )
    assert run.returncode == 1, run.stderr
    assert "Traceback" not in run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bfsitl: error: ")
    assert str(garbage) in lines[0] and f"a {names} file is" in lines[0]


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["fly", "--rate", "0"], "argument --rate: 0 is out of range: 1..200 Hz"),
        (["fly", "--wind", "-1"], "argument --wind: -1 is out of range"),
        (["fly", "--gusts", "21"], "argument --gusts: 21 is out of range: 0..20 m/s"),
        (["fly", "--target-alt", "nan"], "argument --target-alt: 'nan' must be a finite number"),
        (["fly", "--configurator-port", "70000"], "argument --configurator-port: 70000 is out"),
        (["sim", "--step-ms", "0"], "argument --step-ms: 0 is out of range"),
        (["scenario", "run", "--jobs", "0"], "argument --jobs: 0 is out of range: at least 1"),
        (["scenario", "run", "--speed", "-2"], "argument --speed: '-2' must be a positive"),
        (["status", "--start", "--timeout", "0"], "argument --timeout: 0 is out of range"),
        (["telemetry", "--start", "--duration", "-1"], "argument --duration: -1 is out of range"),
    ],
)
def test_options_are_checked_before_anything_starts(
    argv: list[str], says: str, tmp_path: Path
) -> None:
    """No firmware exists here: had anything started, the error would be about that."""
    env = {**os.environ, "BFSITL_FIRMWARE": str(tmp_path / "no-such-sitl")}
    run = subprocess.run(
        [sys.executable, "-m", "bfsitl.cli.main", *argv],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
        cwd=tmp_path,
    )
    assert run.returncode == 2 and says in run.stderr, run.stderr
    assert "no-such-sitl" not in run.stderr and "Traceback" not in run.stderr
