"""lock_clock: the boot-time calibration pair is ignored, steady pairs' errors are estimated
without compounding corrections (errors as measured on 4.6.0 SITL: boot pair 9-15 % fast,
later pairs within about 1.5 %)."""

from __future__ import annotations

from collections.abc import Iterator

from bfsitl.sim.health import lock_clock


class ScriptedBridge:
    """Each calibration pair lands with the next scripted rate error."""

    speed = 0.75
    timestamps = "frozen"

    def __init__(self, errors: list[float]) -> None:
        self._errors: Iterator[float] = iter(errors)
        self.error = next(self._errors)  # the pair sent while priming, during boot
        self.correction = 1.0
        self.pairs = 1

    def recalibrate(self, rate_correction: float = 1.0) -> None:
        self.correction = rate_correction
        self.error = next(self._errors)
        self.pairs += 1


class ScriptedMonitor:
    def __init__(self, bridge: ScriptedBridge) -> None:
        self.bridge = bridge

    def reset(self) -> None:
        pass

    def fc_clock_ratio(self) -> float:
        # The pair asked for speed / correction; the SITL got that times its error.
        return self.bridge.error / self.bridge.correction


def test_boot_pair_error_is_not_carried_into_later_pairs():
    bridge = ScriptedBridge([1.12, 0.985, 0.986, 0.984])
    ratio = lock_clock(ScriptedMonitor(bridge), sleep=lambda _s: None)  # type: ignore[arg-type]
    assert ratio is not None and abs(ratio - 1.0) <= 0.01
    # boot pair measured, a fresh uncorrected pair measured (-1.5 %), then one aimed pair
    assert bridge.pairs == 3
    assert abs(bridge.correction - 0.985) < 1e-9


def test_random_errors_do_not_compound():
    # Compounding the corrections would multiply these and drift away; the median does not.
    bridge = ScriptedBridge([1.15, 0.97, 1.03, 0.97, 1.03, 0.97, 1.03, 1.0])
    ratio = lock_clock(
        ScriptedMonitor(bridge),
        attempts=6,  # type: ignore[arg-type]
        sleep=lambda _s: None,
    )
    assert ratio is not None and abs(ratio - 1.0) <= 0.04


def test_speed_one_needs_no_lock():
    bridge = ScriptedBridge([1.0])
    bridge.speed = 1.0
    assert lock_clock(ScriptedMonitor(bridge)) is None  # type: ignore[arg-type]
    assert bridge.pairs == 1
