"""What an analyser found: a severity, one line a person reads, and the evidence behind it.

Findings are plain records, JSON-ready through :meth:`Finding.as_dict` (``result.json``, the
fly summary, ``bfsitl log check --json``) and back through :func:`finding_from_dict` (an A/B
comparison reads them from two runs' files).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any


class Severity(enum.IntEnum):
    """How bad it is; ordered, so ``max()`` of several is the worst."""

    #: Worth knowing, nothing wrong in itself (a failsafe entered, a GPS glitch ridden out).
    INFO = 1
    #: Something a pilot would want to look at (a hard landing, saturated motors).
    WARNING = 2
    #: The flight went wrong (a crash, a fly-away, lost control).
    FAILURE = 3

    @property
    def label(self) -> str:
        return self.name.lower()

    @classmethod
    def parse(cls, text: str) -> Severity:
        try:
            return cls[text.strip().upper()]
        except KeyError:
            raise ValueError(
                f"unknown severity {text!r}; one of {', '.join(s.label for s in cls)}"
            ) from None


@dataclass(frozen=True, slots=True)
class Finding:
    """One analyser's verdict on one flight (the worst instance of what it looks for)."""

    #: The analyser's name: ``crash``, ``hard_landing``, ``motor_saturation``, ...
    analyser: str
    severity: Severity
    #: One line: what happened, when, how much.
    summary: str
    #: When it happened (the worst instance), seconds on the flight's clock.
    time_s: float
    #: The measured value the severity was judged on, in ``unit``.
    value: float
    unit: str
    #: What the track said around it: named values (the touchdown speed, the attitude, the
    #: sample at that time, how often it happened).
    evidence: dict[str, Any] = field(default_factory=dict)
    #: Where it was seen: ``flight`` (bfsitl's record of the flight, with the simulated
    #: truth) or ``blackbox`` (the FC's own log).
    source: str = "flight"

    def as_dict(self) -> dict[str, Any]:
        return {
            "analyser": self.analyser,
            "severity": self.severity.label,
            "summary": self.summary,
            "time_s": _plain(self.time_s),
            "value": _plain(self.value),
            "unit": self.unit,
            "source": self.source,
            "evidence": {k: _plain(v) for k, v in self.evidence.items()},
        }

    def line(self) -> str:
        """``failure  crash  t=12.34 s  hit the ground at 6.1 m/s ...`` for a terminal."""
        return (
            f"{self.severity.label:<8} {self.analyser:<18} t={self.time_s:7.2f} s  {self.summary}"
        )


def finding_from_dict(data: dict[str, Any]) -> Finding:
    """A finding as :meth:`Finding.as_dict` wrote it."""
    value = data.get("value")
    return Finding(
        str(data["analyser"]),
        Severity.parse(str(data["severity"])),
        str(data.get("summary", "")),
        float(data.get("time_s") or 0.0),
        math.nan if value is None else float(value),
        str(data.get("unit", "")),
        dict(data.get("evidence") or {}),
        str(data.get("source", "flight")),
    )


def worst(findings: list[Finding]) -> Severity | None:
    """The worst severity among ``findings`` (None: there are none)."""
    return max((f.severity for f in findings), default=None)


def _plain(value: Any) -> Any:
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, float):
        return round(value, 4) if math.isfinite(value) else None
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def evidence_text(evidence: dict[str, Any]) -> str:
    """The evidence as a person reads it: ``key=value`` pairs, numbers rounded, names as
    they are spelled in the flight's record (``phase=watch``, not a Python repr), a nested
    sample in parentheses."""

    def shown(value: Any) -> str:
        value = _plain(value)
        if value is None:
            return "n/a"
        if isinstance(value, dict):
            return "(" + evidence_text(value) + ")"
        if isinstance(value, list):
            return "[" + ", ".join(shown(v) for v in value) + "]"
        return str(value)

    return ", ".join(f"{key}={shown(value)}" for key, value in evidence.items())
