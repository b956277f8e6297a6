"""`bfsitl vehicle list|show`, and `--vehicle` read when the command line is: a wrong name is an
argparse error naming the vehicles, before anything starts."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bfsitl.cli.main import main
from bfsitl.vehicles import profile_text, shipped_profiles


def test_list_shows_every_vehicle_with_its_figures(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["vehicle", "list"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:5] == ["NAME", "MASS", "T/W", "HOVER", "MOTOR"]
    names = [line.split()[0] for line in out[1:]]
    assert names == ["iris", "3inch-cinewhoop", "5inch-freestyle", "7inch-longrange"]
    assert "1545 us" in out[1]  # IRIS's measured hover throttle
    assert main(["vehicle", "list", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    five = next(row for row in rows if row["name"] == "5inch-freestyle")
    assert five["mass_g"] == 650.0 and five["thrust_to_weight"] == pytest.approx(12.25, abs=0.01)


def test_show_prints_the_profile_and_what_the_physics_makes_of_it(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main(["vehicle", "show", "7inch-longrange"]) == 0
    out = capsys.readouterr().out
    assert 'name = "7inch-longrange"' in out and "# hover_throttle_us = " in out
    mine = tmp_path / "mine.toml"
    mine.write_text(profile_text(shipped_profiles()["5inch-freestyle"]).replace("650.0", "700.0"))
    assert main(["vehicle", "show", str(mine), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["figures"]["mass_g"] == 700.0 and "[sources]" in shown["profile"]


@pytest.mark.parametrize(
    "command", [["fly"], ["sim"], ["scenario", "run"], ["scenario", "compare", "--firmware", "x"]]
)
def test_a_wrong_vehicle_is_a_usage_error_naming_the_vehicles(
    command: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exited:
        main([*command, "--vehicle", "x500"])
    assert exited.value.code == 2
    err = capsys.readouterr().err
    assert "argument --vehicle: unknown vehicle 'x500': give one of iris, 3inch-cinewhoop" in err
