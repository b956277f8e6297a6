"""What every expectation judge shares: a bound over a window (:class:`Limit`), how an
expectation is written back in messages, and a judged check."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bfsitl.scenario.result import CheckResult


@dataclass(frozen=True, slots=True)
class Limit:
    """A bound over a window of the run (None: the key's default window); a distance bound
    may measure from a point (``north_m``, ``east_m``) instead of the take-off point."""

    value: float
    from_s: float | None = None
    until_s: float | None = None
    north_m: float | None = None
    east_m: float | None = None


def shown(key: str, value: Any) -> str:
    """The expectation as the file wrote it, for messages."""
    if isinstance(value, Limit):
        window = ""
        if value.from_s is not None or value.until_s is not None:
            window = (
                f" over {value.from_s if value.from_s is not None else 0:g}.."
                f"{value.until_s if value.until_s is not None else 'end'} s"
            )
        point = ""
        if value.north_m is not None or value.east_m is not None:
            point = f" from ({value.north_m or 0:g} N, {value.east_m or 0:g} E)"
        return f"{key} = {value.value:g}{point}{window}"
    if isinstance(value, bool):
        return f"{key} = {str(value).lower()}"
    if isinstance(value, (list, tuple)):
        return f"{key} = [{', '.join(repr(v) for v in value)}]"
    if isinstance(value, dict):
        return f"{key} = {{ {', '.join(f'{k} = {v!r}' for k, v in value.items())} }}"
    return f"{key} = {value!r}" if isinstance(value, str) else f"{key} = {value:g}"


def check(
    key: str,
    value: Any,
    passed: bool,
    message: str,
    measured: float | str | None,
    at_s: float | None,
) -> CheckResult:
    """One judged expectation: its message names it, what was measured and when."""
    when = f" at t={at_s:.2f} s" if at_s is not None else ""
    return CheckResult(
        shown(key, value), passed, f"{shown(key, value)}: {message}{when}", measured, at_s
    )


def name_list(value: str | list[str]) -> list[str]:
    """A key's value that is one name or a list of them, as a list."""
    return [value] if isinstance(value, str) else list(value)
