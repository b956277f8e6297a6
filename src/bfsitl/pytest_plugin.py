"""bfsitl for pytest: scenario files as test items, a launched vehicle as a fixture.

Loaded with ``pytest -p bfsitl.pytest_plugin`` (or ``pytest_plugins = ["bfsitl.pytest_plugin"]``
in a conftest).  Options:

* ``--bfsitl-firmware NAME`` (repeat for several): the builds to fly; each scenario file and
  each test using ``bfsitl_firmware`` runs once per build;
* ``--bfsitl-out DIR``: where the runs' files go (default: pytest's temporary directory);
* ``--bfsitl-vehicle NAME|FILE``: the quad of ``bfsitl_vehicle`` and of the scenarios whose
  ``[vehicle]`` names none (default: IRIS, a replay's the 5-inch; ``bfsitl vehicle list``
  shows the names).

With at least one ``--bfsitl-firmware``, every ``*.toml`` file pytest is pointed at that is a
scenario (it has ``[flight]`` or ``[replay]``, and ``[expect]``) becomes one test per
firmware; a failed expectation fails it with the message that names it, the measured value
and the time; a fault the firmware cannot express skips it.

Fixtures:

* ``bfsitl_firmware``: the build's name (parametrised over the ``--bfsitl-firmware`` list);
* ``bfsitl_vehicle``: a started :class:`~bfsitl.mission.session.FlightSession` on it,
  provisioned for the autopilot, closed after the test
  (``Autopilot(bfsitl_vehicle).takeoff(2.0)``...);
* ``bfsitl_scenario``: ``run(path_or_scenario) -> ScenarioResult`` on that firmware, the
  result's files in the test's own directory.
"""

from __future__ import annotations

import tempfile
import tomllib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from bfsitl.errors import ScenarioFailedError
from bfsitl.scenario.load import load_scenario
from bfsitl.scenario.result import ScenarioResult, Verdict
from bfsitl.scenario.spec import Scenario, on_vehicle

FIRMWARE_OPTION = "--bfsitl-firmware"
VEHICLE_OPTION = "--bfsitl-vehicle"
_QUAD = pytest.StashKey[Any]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("bfsitl", "bfsitl: Betaflight SITL scenarios")
    group.addoption(
        FIRMWARE_OPTION,
        action="append",
        default=[],
        metavar="NAME",
        help="a SITL build (cached name or path) to fly scenarios and "
        "bfsitl_vehicle tests on; repeat for several",
    )
    group.addoption(
        VEHICLE_OPTION,
        default=None,
        metavar="NAME|FILE",
        help="the simulated quad: a shipped vehicle or a profile file (default: IRIS, a "
        "replay's the 5-inch, or the scenario's own [vehicle])",
    )
    group.addoption(
        "--bfsitl-out",
        default=None,
        metavar="DIR",
        help="where scenario runs write their files (default: pytest's tmp dir)",
    )


def _quad(config: pytest.Config) -> Any:
    """``--bfsitl-vehicle`` read (once per session), or None."""
    given = config.getoption(VEHICLE_OPTION)
    if given is None:
        return None
    if _QUAD not in config.stash:
        from bfsitl.vehicles import load_vehicle

        config.stash[_QUAD] = load_vehicle(given)
    return config.stash[_QUAD]


def _on_vehicle(config: pytest.Config, scenario: Scenario) -> Scenario:
    return on_vehicle([scenario], _quad(config))[0]


def _firmwares(config: pytest.Config) -> list[str]:
    return list(dict.fromkeys(config.getoption(FIRMWARE_OPTION) or []))


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "bfsitl_firmware" in metafunc.fixturenames:
        firmwares = _firmwares(metafunc.config)
        if not firmwares:
            firmwares = [None]  # type: ignore[list-item]  # skipped in the fixture
        metafunc.parametrize(
            "bfsitl_firmware", firmwares, scope="function", ids=[str(f) for f in firmwares]
        )


@pytest.fixture
def bfsitl_firmware(request: pytest.FixtureRequest) -> str:
    firmware = request.param
    if firmware is None:
        pytest.skip(
            f"no firmware to fly: give {FIRMWARE_OPTION} NAME (`bfsitl firmware "
            f"list` shows the builds)"
        )
    return str(firmware)


@pytest.fixture
def bfsitl_vehicle(
    bfsitl_firmware: str, tmp_path: Path, request: pytest.FixtureRequest
) -> Iterator[Any]:
    from bfsitl.autopilot import launch_sitl

    quad = _quad(request.config)
    with launch_sitl(
        bfsitl_firmware, workdir=tmp_path / "sitl", vehicle=quad if quad is not None else "iris"
    ) as vehicle:
        yield vehicle


_OUT_ROOT = pytest.StashKey[Path]()


def _out_dir(config: pytest.Config, name: str) -> Path:
    """``--bfsitl-out``, or one fresh temporary directory per pytest session."""
    if _OUT_ROOT not in config.stash:
        base = config.getoption("--bfsitl-out")
        config.stash[_OUT_ROOT] = (
            Path(base) if base else Path(tempfile.mkdtemp(prefix="bfsitl-scenarios-"))
        )
    return config.stash[_OUT_ROOT] / name


@pytest.fixture
def bfsitl_scenario(
    bfsitl_firmware: str, tmp_path: Path, request: pytest.FixtureRequest
) -> Callable[[str | Path | Scenario], ScenarioResult]:
    from bfsitl.scenario.run import RunOptions, run_scenario

    def run(scenario: str | Path | Scenario) -> ScenarioResult:
        if not isinstance(scenario, Scenario):
            scenario = _on_vehicle(request.config, load_scenario(scenario))
        return run_scenario(
            scenario, bfsitl_firmware, RunOptions(tmp_path / scenario.name, plot="failed")
        )

    return run


# -- scenario files as test items -------------------------------------------------------------
def _looks_like_scenario(path: Path) -> bool:
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return ("flight" in data or "replay" in data) and "expect" in data


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    if file_path.suffix != ".toml" or not _firmwares(parent.config):
        return None
    if not _looks_like_scenario(file_path):
        return None
    return ScenarioFile.from_parent(parent, path=file_path)


class ScenarioFile(pytest.File):
    """A scenario file: one item per firmware."""

    def collect(self) -> Iterator[pytest.Item]:
        # A broken file (or a bad --bfsitl-vehicle) is a collection error.
        scenario = _on_vehicle(self.config, load_scenario(self.path))
        for firmware in _firmwares(self.config):
            yield ScenarioItem.from_parent(
                self, name=f"{scenario.name}[{firmware}]", scenario=scenario, firmware=firmware
            )


class ScenarioItem(pytest.Item):
    def __init__(self, *, scenario: Scenario, firmware: str, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.scenario = scenario
        self.firmware = firmware
        self.result: ScenarioResult | None = None

    def runtest(self) -> None:
        from bfsitl.scenario.run import RunOptions, run_scenario

        out = _out_dir(self.config, f"{self.firmware}/{self.scenario.name}".replace("/", "_"))
        # Plots only for a run that failed: the one someone will look at.
        options = RunOptions(out, plot="failed")
        self.result = result = run_scenario(self.scenario, self.firmware, options)
        for kind, path in result.artifacts.items():
            self.user_properties.append((kind, str(path)))
        if result.verdict is Verdict.SKIPPED:
            pytest.skip(result.reason)
        if result.verdict is Verdict.KNOWN:
            pytest.xfail(result.reason)  # a firmware defect the scenario declares
        if result.verdict is not Verdict.PASSED:
            raise ScenarioFailedError(result.reason)

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException], style: Any = None) -> str:
        if isinstance(excinfo.value, ScenarioFailedError) and self.result is not None:
            result = self.result
            lines = [f"{result.verdict.value}: {result.reason}"]
            lines += [f"  {'PASS' if c.passed else 'FAIL'} {c.message}" for c in result.checks]
            lines += [f"  t={e.time_s:7.2f} s  {e.text}" for e in result.events]
            lines += [f"  {kind}: {path}" for kind, path in result.artifacts.items()]
            return "\n".join(lines)
        return str(super().repr_failure(excinfo))

    def reportinfo(self) -> tuple[Path, int, str]:
        return self.path, 0, f"scenario {self.name}"
