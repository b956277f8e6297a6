"""The simulated truth a learning step sees (:class:`bfsitl.gym.snapshot.TrueView`), made
for the tasks' pure tests: level, still and at rest in the air unless told otherwise."""

from __future__ import annotations

from bfsitl.gym.snapshot import TrueView


def true_view(**changes: object) -> TrueView:
    """A quad level and still at 2 m over where it armed, with ``changes`` on top."""
    values: dict[str, object] = {
        "north_m": 0.0,
        "east_m": 0.0,
        "alt_m": 2.0,
        "v_north_m_s": 0.0,
        "v_east_m_s": 0.0,
        "v_up_m_s": 0.0,
        "roll_rad": 0.0,
        "pitch_rad": 0.0,
        "yaw_rad": 0.0,
        "rates_flu_rad_s": (0.0, 0.0, 0.0),
        "accel_flu_m_s2": (0.0, 0.0, 9.81),
        "motors": (0.5, 0.5, 0.5, 0.5),
        "tilt_deg": 0.0,
        "on_ground": False,
    }
    values.update(changes)
    return TrueView(**values)  # type: ignore[arg-type]
