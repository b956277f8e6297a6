"""Each analyser on a made-up track that must trigger it and on one that must not; the
thresholds' edges; what a track without the data says."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from bfsitl.analysis import (
    ANALYSERS,
    Finding,
    Limits,
    Severity,
    Track,
    TrackPoint,
    analyse,
    combine,
    finding_from_dict,
)
from bfsitl.analysis.analysers import Analysis

RATE_HZ = 50.0


def hover(
    seconds: float, *, alt_m: float = 3.0, start_s: float = 0.0, **fields: object
) -> list[TrackPoint]:
    """A steady hover: airborne, level, motors at 0.55, holding its target."""
    count = round(seconds * RATE_HZ)
    base = TrackPoint(
        time_s=0.0,
        armed=True,
        airborne=True,
        alt_m=alt_m,
        climb_m_s=0.0,
        north_m=0.0,
        east_m=0.0,
        tilt_deg=1.0,
        roll_deg=0.5,
        pitch_deg=-0.5,
        phase="hold",
        target_alt_m=alt_m,
        target_north_m=0.0,
        target_east_m=0.0,
        motors=(0.55,) * 4,
        fc_alt_m=alt_m,
        fc_north_m=0.0,
        fc_east_m=0.0,
        modes=("ANGLE",),
    )
    base = replace(base, **fields)  # type: ignore[arg-type]
    return [replace(base, time_s=round(start_s + i / RATE_HZ, 4)) for i in range(count)]


def fall(
    points: list[TrackPoint], *, speed_m_s: float, rest_tilt_deg: float = 2.0
) -> list[TrackPoint]:
    """``points`` then a descent at ``speed_m_s`` to the ground and 2 s at rest there."""
    last = points[-1]
    out = list(points)
    t, alt = last.time_s, last.alt_m
    while alt > 0:
        t += 1 / RATE_HZ
        alt -= speed_m_s / RATE_HZ
        out.append(
            replace(
                last, time_s=round(t, 4), alt_m=max(alt, 0.0), climb_m_s=-speed_m_s, phase="watch"
            )
        )
    for i in range(100):
        out.append(
            replace(
                last,
                time_s=round(t + (i + 1) / RATE_HZ, 4),
                alt_m=0.0,
                climb_m_s=0.0,
                airborne=False,
                tilt_deg=rest_tilt_deg,
                phase="watch",
                armed=i < 10,
            )
        )
    return out


def found(points: list[TrackPoint], name: str, **limits: object) -> Finding | None:
    analysis = analyse(Track("flight", points), Limits(**limits))  # type: ignore[arg-type]
    assert name in analysis.watched, analysis.skipped
    return next((f for f in analysis.findings if f.analyser == name), None)


def test_a_steady_hover_gives_no_finding_at_all() -> None:
    analysis = analyse(Track("flight", hover(20.0)))
    assert analysis.findings == []
    assert set(analysis.watched) == {a.name for a in ANALYSERS}


# -- ground contact ----------------------------------------------------------------------------
def test_a_fall_at_crash_speed_is_a_crash_with_its_evidence() -> None:
    finding = found(fall(hover(5.0), speed_m_s=6.0), "crash")
    assert finding is not None and finding.severity is Severity.FAILURE
    assert finding.value == pytest.approx(6.0)
    assert finding.evidence["fell_from_m"] == pytest.approx(3.0)
    assert "6.0 m/s" in finding.summary and finding.time_s > 5.0


def test_a_slow_contact_that_ends_upside_down_is_a_crash() -> None:
    finding = found(fall(hover(5.0), speed_m_s=0.5, rest_tilt_deg=170.0), "crash")
    assert finding is not None and "upside down" in finding.summary


@pytest.mark.parametrize(
    ("speed", "crash", "hard"),
    [
        (0.5, False, False),
        (1.49, False, False),
        (1.5, False, True),
        (2.9, False, True),
        (3.0, True, False),
    ],
)
def test_contact_speeds_grade_from_landing_to_hard_landing_to_crash(
    speed: float, crash: bool, hard: bool
) -> None:
    points = fall(hover(5.0), speed_m_s=speed)
    assert (found(points, "crash") is not None) is crash
    assert (found(points, "hard_landing") is not None) is hard


def test_the_take_off_is_no_touchdown() -> None:
    ground = [replace(p, airborne=False, alt_m=0.0) for p in hover(2.0)]
    climb = hover(3.0, start_s=2.0, climb_m_s=2.0)
    assert found(ground + climb, "crash") is None


# -- where it went -------------------------------------------------------------------------------
def drift(points: list[TrackPoint], speed_m_s: float, seconds: float) -> list[TrackPoint]:
    last = points[-1]
    return [
        *points,
        *(
            replace(
                last,
                time_s=round(last.time_s + (i + 1) / RATE_HZ, 4),
                north_m=speed_m_s * (i + 1) / RATE_HZ,
                phase="watch",
                target_north_m=math.nan,
                target_east_m=math.nan,
            )
            for i in range(round(seconds * RATE_HZ))
        ),
    ]


def test_a_vehicle_still_leaving_beyond_its_targets_is_flying_away() -> None:
    finding = found(drift(hover(5.0), 2.0, 20.0), "fly_away")
    assert finding is not None and finding.severity is Severity.FAILURE
    assert finding.evidence["still_leaving"] is True
    assert finding.value == pytest.approx(40.0, abs=0.1)


def test_out_and_back_is_a_warning_and_within_the_margin_nothing() -> None:
    out = drift(hover(5.0), 2.0, 15.0)
    back = [
        replace(
            p,
            time_s=round(out[-1].time_s + (i + 1) / RATE_HZ, 4),
            north_m=30.0 - 2.0 * (i + 1) / RATE_HZ,
        )
        for i, p in enumerate(out[-1:] * 700)
    ]
    finding = found(out + back, "fly_away")
    assert finding is not None and finding.severity is Severity.WARNING
    assert found(drift(hover(5.0), 2.0, 12.0), "fly_away") is None  # 24 m < 0 + 25 m
    # A mission that goes 100 m out sets the bound: 110 m is no fly-away.
    far = hover(5.0, target_north_m=100.0, north_m=110.0)
    assert found(far, "fly_away") is None


# -- attitude ----------------------------------------------------------------------------------
def test_upside_down_in_the_air_is_a_loss_of_control_and_on_the_ground_is_not() -> None:
    flipped = hover(3.0) + hover(1.0, start_s=3.0, tilt_deg=150.0)
    finding = found(flipped, "loss_of_control")
    assert finding is not None and finding.severity is Severity.FAILURE
    assert finding.time_s == pytest.approx(3.0)
    on_ground = hover(3.0) + hover(1.0, start_s=3.0, tilt_deg=150.0, airborne=False)
    assert found(on_ground, "loss_of_control") is None


def test_a_flip_in_acro_is_no_loss_of_control_unless_the_gyro_leaves_its_setpoint() -> None:
    """A freestyle pilot rolls the quad upside down on purpose; the FC flies rates, not
    angles, so only its gyro against its setpoint says whether it kept control."""
    flip = hover(3.0, self_levelling=False) + hover(
        1.0, start_s=3.0, tilt_deg=170.0, self_levelling=False
    )
    assert found(flip, "loss_of_control") is None
    steep = hover(3.0, self_levelling=False) + hover(
        0.5, start_s=3.0, tilt_deg=80.0, self_levelling=False
    )
    assert found(steep, "loss_of_control") is None
    # The same flip in ANGLE (or with the mode unknown) is one.
    for levelling in (True, None):
        levelled = [replace(p, self_levelling=levelling) for p in flip]
        finding = found(levelled, "loss_of_control")
        assert finding is not None and finding.severity is Severity.FAILURE
    # In acro, a gyro that leaves its setpoint is still lost control.
    points = [
        replace(p, self_levelling=False, motors=(0.5,) * 4, accel_g=1.0)
        for p in rates(2.0, lambda t: 400.0 if t > 1.0 else 0.0)
    ]
    lost = analyse(Track("blackbox", points, disarm_reason="SWITCH"))
    assert any(f.analyser == "loss_of_control" for f in lost.findings)


def test_tilt_past_what_angle_mode_commands_is_a_warning() -> None:
    steep = hover(3.0) + hover(0.5, start_s=3.0, tilt_deg=80.0)
    finding = found(steep, "loss_of_control")
    assert finding is not None and finding.severity is Severity.WARNING
    assert found(hover(3.0) + hover(0.5, start_s=3.0, tilt_deg=70.0), "loss_of_control") is None


def rates(seconds: float, error: object, *, rate_hz: float = 500.0) -> list[TrackPoint]:
    """A log's points: gyro = setpoint + error(t) on every axis."""
    points = []
    for i in range(round(seconds * rate_hz)):
        t = i / rate_hz
        e = error(t)  # type: ignore[operator]
        points.append(
            TrackPoint(
                time_s=t,
                armed=True,
                motors=(0.5,) * 4,
                gyro_deg_s=(10.0 + e, -5.0 + e, e),
                setpoint_deg_s=(10.0, -5.0, 0.0),
                accel_g=1.0,
            )
        )
    return points


def test_the_gyro_far_from_its_setpoint_is_a_loss_of_control() -> None:
    track = Track(
        "blackbox", rates(2.0, lambda t: 400.0 if t > 1.0 else 0.0), disarm_reason="SWITCH"
    )
    analysis = analyse(track)
    finding = next(f for f in analysis.findings if f.analyser == "loss_of_control")
    assert finding.severity is Severity.FAILURE and finding.source == "blackbox"
    assert finding.time_s == pytest.approx(1.25, abs=0.01)  # 0.25 s of error at 400 deg/s
    calm = Track("blackbox", rates(2.0, lambda t: 20.0 * math.sin(40 * t)), disarm_reason="SWITCH")
    assert not any(f.analyser == "loss_of_control" for f in analyse(calm).findings)


def test_a_sustained_swing_is_an_oscillation_and_noise_or_a_single_kick_is_not() -> None:
    def swing(t: float) -> float:
        return 80.0 * math.sin(2 * math.pi * 12.0 * t)

    finding = next(
        f
        for f in analyse(Track("blackbox", rates(3.0, swing), disarm_reason="SWITCH")).findings
        if f.analyser == "oscillation"
    )
    assert finding.evidence["frequency_hz"] == pytest.approx(12.0, abs=1.0)
    assert finding.value == pytest.approx(80.0 / math.sqrt(2), rel=0.05)
    small = Track("blackbox", rates(3.0, lambda t: 0.2 * swing(t)), disarm_reason="SWITCH")
    kick = Track(
        "blackbox", rates(3.0, lambda t: swing(t) if t < 0.4 else 0.0), disarm_reason="SWITCH"
    )
    for track in (small, kick):
        assert not any(f.analyser == "oscillation" for f in analyse(track).findings)


def test_the_motors_split_swinging_in_a_flight_record_is_an_oscillation() -> None:
    points = hover(4.0)
    shaken = [
        replace(p, motors=(0.55 - s, 0.55 - s, 0.55 + s, 0.55 + s))
        for p in points
        for s in [0.3 * math.copysign(1.0, math.sin(2 * math.pi * 6.0 * p.time_s))]
    ]
    finding = found(shaken, "oscillation")
    assert finding is not None and "roll" in finding.summary
    gentle = [
        replace(p, motors=(0.55 - s, 0.55 - s, 0.55 + s, 0.55 + s))
        for p in points
        for s in [0.05 * math.sin(2 * math.pi * 6.0 * p.time_s)]
    ]
    assert found(gentle, "oscillation") is None


# -- motors ------------------------------------------------------------------------------------
def test_a_motor_at_full_for_a_while_is_saturation_and_a_blip_is_not() -> None:
    points = (
        hover(2.0) + hover(0.5, start_s=2.0, motors=(1.0, 0.6, 0.6, 0.6)) + hover(2.0, start_s=2.5)
    )
    finding = found(points, "motor_saturation")
    assert finding is not None and finding.evidence["motors"] == [1]
    assert finding.value == pytest.approx(0.5, abs=0.03)
    blip = (
        hover(2.0) + hover(0.1, start_s=2.0, motors=(1.0, 0.6, 0.6, 0.6)) + hover(2.0, start_s=2.1)
    )
    assert found(blip, "motor_saturation") is None


def test_saturation_on_the_ground_is_not_counted() -> None:
    points = hover(2.0, airborne=False, motors=(1.0,) * 4)
    assert found(points + hover(2.0, start_s=2.0), "motor_saturation") is None


# -- failsafe, GPS, excursions -----------------------------------------------------------------
def test_the_failsafe_phases_are_timed_from_when_it_was_entered() -> None:
    points = (
        hover(2.0, failsafe_phase=0)
        + hover(1.0, start_s=2.0, failsafe_phase=2)
        + hover(1.0, start_s=3.0, failsafe_phase=3)
    )
    finding = found(points, "failsafe")
    assert finding is not None and finding.severity is Severity.INFO
    assert finding.evidence["to_landed_s"] == pytest.approx(1.0)
    assert "LANDING at 2.00 s -> LANDED at 3.00 s" in finding.summary
    assert found(hover(3.0, failsafe_phase=0), "failsafe") is None


def test_a_failsafe_that_comes_and_goes_names_a_few_changes_and_keeps_them_all() -> None:
    # LANDING and IDLE alternate when a flight channel is invalid then valid again: the line
    # names the first changes, how many more, and the last; the evidence has every one.
    points = hover(1.0, failsafe_phase=0)
    for index in range(200):
        points += hover(0.02, start_s=1.0 + 0.02 * index, failsafe_phase=2 * (index % 2 == 0))
    finding = found(points, "failsafe")
    assert finding is not None
    assert len(finding.evidence["phases"]) == 201  # the first IDLE, then each change
    assert finding.summary.startswith("failsafe: LANDING at 1.00 s -> IDLE at 1.02 s -> ")
    assert "(194 more changes) -> IDLE at 4.98 s" in finding.summary  # 5 + 194 + 1
    assert finding.summary.count(" at ") == 6 and len(finding.summary) < 200


def test_a_gps_glitch_ridden_out_is_info_and_followed_is_a_warning() -> None:
    glitch = hover(2.0) + hover(3.0, start_s=2.0, fc_north_m=20.0) + hover(1.0, start_s=5.0)
    finding = found(glitch, "gps_glitch")
    assert finding is not None and finding.severity is Severity.INFO
    followed = hover(2.0) + [
        replace(p, north_m=-min(8.0, 4.0 * (p.time_s - 2.0)))
        for p in hover(3.0, start_s=2.0, fc_north_m=20.0)
    ]
    finding = found(followed, "gps_glitch")
    assert finding is not None and finding.severity is Severity.WARNING
    assert finding.value == pytest.approx(8.0)
    assert found(hover(3.0, fc_north_m=2.0), "gps_glitch") is None  # GPS noise is no glitch


@pytest.mark.parametrize(
    ("name", "field", "value", "severity"),
    [
        ("altitude_excursion", "alt_m", 4.9, None),  # 1.9 m off
        ("altitude_excursion", "alt_m", 5.5, Severity.WARNING),
        ("altitude_excursion", "alt_m", 8.5, Severity.FAILURE),
        ("position_excursion", "north_m", 2.5, None),
        ("position_excursion", "north_m", 4.0, Severity.WARNING),
        ("position_excursion", "north_m", 12.0, Severity.FAILURE),
        ("altitude_estimate", "fc_alt_m", 4.5, None),
        ("altitude_estimate", "fc_alt_m", 6.0, Severity.WARNING),
        ("altitude_estimate", "fc_alt_m", 9.0, Severity.FAILURE),
    ],
)
def test_excursions_grade_by_how_far_off(
    name: str, field: str, value: float, severity: Severity | None
) -> None:
    off = [replace(p, **{field: value}) for p in hover(2.0, start_s=5.0)]  # type: ignore[arg-type]
    finding = found(hover(5.0) + off, name)
    assert (finding.severity if finding else None) is severity


def test_a_holds_first_seconds_settle_and_are_not_excursions() -> None:
    points = hover(2.0, alt_m=8.0, target_alt_m=3.0) + hover(5.0, start_s=2.0)
    assert found(points, "altitude_excursion") is None


# -- what runs, and results as data -------------------------------------------------------------
def test_a_track_without_the_data_lists_the_analyser_as_skipped_with_why() -> None:
    bare = [TrackPoint(time_s=i / 50, armed=True, motors=(0.5,) * 4) for i in range(100)]
    analysis = analyse(Track("blackbox", bare))
    assert "motor_saturation" in analysis.watched
    assert "fly_away" in analysis.skipped and "north_m" in analysis.skipped["fly_away"]
    assert "crash" in analysis.skipped  # no disarm reason: the log was cut
    empty = analyse(Track("flight", []))
    assert empty.watched == [] and len(empty.skipped) == len(ANALYSERS)


def test_combining_sources_keeps_each_analysers_worst() -> None:
    warning = Finding("crash", Severity.WARNING, "a", 1.0, 1.0, "m/s")
    failure = Finding("crash", Severity.FAILURE, "b", 2.0, 5.0, "m/s", source="blackbox")
    info = Finding("failsafe", Severity.INFO, "c", 0.5, 1.0, "phases")
    merged = combine(
        Analysis([warning, info], ["crash", "failsafe"], {"fly_away": "no"}),
        Analysis([failure], ["crash", "fly_away"], {}),
    )
    assert merged.findings == [failure, info]
    assert merged.skipped == {} and set(merged.watched) == {"crash", "failsafe", "fly_away"}


def test_a_finding_survives_json() -> None:
    finding = found(fall(hover(5.0), speed_m_s=6.0), "crash")
    assert finding is not None
    again = finding_from_dict(finding.as_dict())
    assert again.analyser == "crash" and again.severity is Severity.FAILURE
    assert again.value == pytest.approx(finding.value, abs=1e-4)
    assert again.evidence["fell_from_m"] == pytest.approx(3.0)
    with pytest.raises(ValueError, match="unknown severity"):
        Severity.parse("catastrophic")


def test_evidence_reads_as_text_not_python() -> None:
    from bfsitl.analysis.findings import evidence_text
    from bfsitl.mission.phase import Phase

    evidence = {
        "touchdown_speed_m_s": 7.412345,
        "sample": {"phase": Phase.WATCH, "alt_m": math.nan, "motors": (0.5, 0.25)},
    }
    text = evidence_text(evidence)
    assert text == "touchdown_speed_m_s=7.4123, sample=(phase=watch, alt_m=n/a, motors=[0.5, 0.25])"
    assert "<Phase" not in text
    # And in JSON: the enum's value, not its repr.
    finding = Finding("crash", Severity.FAILURE, "x", 1.0, 7.4, "m/s", evidence)
    assert finding.as_dict()["evidence"]["sample"]["phase"] == "watch"
