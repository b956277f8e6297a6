"""What both scenario commands (``run``, ``compare``) start from: the files or the shipped
library, and the builds they fly, checked before anything starts."""

from __future__ import annotations

from pathlib import Path


def paths_or_library(paths: list[str]) -> list[str | Path]:
    """The paths given, or the scenario library that ships inside the package."""
    if paths:
        return list(paths)
    from bfsitl.library import scenarios_dir

    return [scenarios_dir()]


def check_builds(runs: list, *, given: bool) -> None:  # type: ignore[type-arg]
    """A missing build stops everything before any run, saying how to make it."""
    from bfsitl.errors import FirmwareNotFoundError
    from bfsitl.sitl.firmware import find_firmware

    for run in {run.firmware: run for run in runs}.values():
        try:
            find_firmware(run.firmware)
        except FirmwareNotFoundError as exc:
            origin = "--firmware" if given else f"named by {run.scenario.where}"
            raise FirmwareNotFoundError(
                f"the build {run.firmware!r} ({origin}) is not there: "
                f"`bfsitl firmware list` shows the builds, `bfsitl "
                f"firmware build --lockstep [--gps]` makes one. "
                f"{exc}"
            ) from exc
