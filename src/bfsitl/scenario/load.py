"""Reading scenario files: each one parsed (:mod:`bfsitl.scenario.spec`, its faults checked
as they are read) and its expectations checked, before anything flies."""

from __future__ import annotations

from pathlib import Path

from bfsitl.errors import ScenarioError
from bfsitl.scenario.expectations import check_expectations
from bfsitl.scenario.spec import SCENARIO_GLOB, Scenario, scenario_from_dict
from bfsitl.toml_file import read_toml_file


def load_scenario(path: str | Path) -> Scenario:
    """Read one scenario file, checked, faults and expectations included.

    Args:
        path: The scenario's TOML file.

    Returns:
        The scenario, named after the file's stem unless it names itself.

    Raises:
        ScenarioError: The file cannot be read, is no TOML, or holds something that cannot
            be run as written (the message names the file, the table and the key).
    """
    path = Path(path)
    data = read_toml_file(path, "scenario", ScenarioError)
    scenario = scenario_from_dict(data, name=path.stem, source=path)
    check_expectations(scenario)
    return scenario


def _library_file(name: str | Path) -> Path | None:
    """The shipped library's ``NAME.toml`` for a bare name, if there is one."""
    text = str(name)
    if "/" in text or text.endswith(SCENARIO_GLOB[1:]):
        return None
    from bfsitl.library import scenarios_dir

    candidate = scenarios_dir() / f"{text}{SCENARIO_GLOB[1:]}"
    return candidate if candidate.is_file() else None


def find_scenarios(paths: list[str | Path]) -> list[Scenario]:
    """Every scenario named: files as they are, directories by their ``*.toml`` files (sorted;
    not recursive), and a bare name that is no file (``rc-loss-hover-drop``) as the shipped
    library's file of that name.  Two scenarios with one name are refused (their reports would
    clash)."""
    scenarios: list[Scenario] = []
    for given in paths:
        path = Path(given)
        if path.is_dir():
            files = sorted(path.glob(SCENARIO_GLOB))
            if not files:
                raise ScenarioError(f"{path} holds no scenario files ({SCENARIO_GLOB})")
        elif path.is_file():
            files = [path]
        elif _library_file(given) is not None:
            files = [_library_file(given)]  # type: ignore[list-item]
        else:
            raise ScenarioError(
                f"{path}: no such scenario file or directory, nor a scenario "
                f"of the shipped library (`bfsitl scenario list` names them)"
            )
        scenarios.extend(load_scenario(f) for f in files)
    seen: dict[str, Scenario] = {}
    for scenario in scenarios:
        if scenario.name in seen:
            raise ScenarioError(
                f"two scenarios are named {scenario.name!r}: "
                f"{seen[scenario.name].where} and {scenario.where}"
            )
        seen[scenario.name] = scenario
    return scenarios
