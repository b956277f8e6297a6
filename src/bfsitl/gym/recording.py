"""An episode as ``bfsitl fly`` records a flight: one :class:`~bfsitl.mission.flight_row.
FlightRow` per step, written by the record sink its file's suffix picks (CSV, MCAP), and the
flight plot with the targets on the ground track.  For evaluating a policy: what it did can
be read, plotted and compared with any other flight."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from bfsitl.fc.rc_link import RC_MIN_US, RcCommand
from bfsitl.gym.env import FlightEnv
from bfsitl.gym.snapshot import Snapshot
from bfsitl.mission.flight_row import FlightRow
from bfsitl.records.sinks import RowSink, open_sink

#: The phase written in every row: the policy flies.
POLICY_PHASE = "policy"


def snapshot_row(
    snapshot: Snapshot,
    target: tuple[float, float, float],
    env: FlightEnv,
    wall_s: float,
    waypoint: int,
) -> FlightRow:
    fc, truth = snapshot.fc, snapshot.truth
    rc = env.rc_command or RcCommand()
    aux = (*rc.aux_us, RC_MIN_US, RC_MIN_US)  # AUX1 and AUX2, the switches off if absent
    return FlightRow(
        time_s=snapshot.time_s,
        phase=POLICY_PHASE,
        target_alt_m=target[2],
        sim_alt_m=truth.alt_m,
        fc_alt_m=fc.alt_m,
        climb_m_s=fc.climb_m_s,
        sim_climb_m_s=truth.v_up_m_s,
        fc_accel_up_m_s2=fc.accel_up_m_s2,
        roll_deg=math.degrees(fc.roll_rad),
        pitch_deg=math.degrees(fc.pitch_rad),
        yaw_deg=math.degrees(fc.yaw_rad) % 360.0,
        sim_tilt_deg=truth.tilt_deg,
        sim_roll_deg=math.degrees(truth.roll_rad),
        sim_pitch_deg=math.degrees(truth.pitch_rad),
        sim_yaw_deg=math.degrees(truth.yaw_rad) % 360.0,
        rc_roll_us=round(rc.roll_us),
        rc_pitch_us=round(rc.pitch_us),
        rc_throttle_us=round(rc.throttle_us),
        rc_yaw_us=round(rc.yaw_us),
        rc_aux1_us=round(aux[0]),
        rc_aux2_us=round(aux[1]),
        motor1=truth.motors[0],
        motor2=truth.motors[1],
        motor3=truth.motors[2],
        motor4=truth.motors[3],
        armed=fc.armed,
        wall_s=wall_s,
        sim_north_m=truth.north_m,
        sim_east_m=truth.east_m,
        fc_north_m=fc.north_m if fc.has_gps else math.nan,
        fc_east_m=fc.east_m if fc.has_gps else math.nan,
        target_north_m=target[0],
        target_east_m=target[1],
        waypoint=waypoint + 1,
    )


class EpisodeRecorder:
    """Rows of the steps it is shown, to ``path`` (its suffix picks the format) and kept for
    :meth:`plot`."""

    def __init__(self, path: str | Path) -> None:
        self.sink: RowSink = open_sink(path)
        self.rows: list[FlightRow] = []
        self.targets: list[tuple[float, float]] = []
        self._started = time.monotonic()

    def record(self, env: FlightEnv, action: np.ndarray | None = None) -> FlightRow:
        """The row of ``env``'s last step."""
        snapshot = env.snapshot
        if snapshot is None:
            raise ValueError("nothing to record: reset the environment first")
        target = env.task.target
        if (target[0], target[1]) not in self.targets:
            self.targets.append((target[0], target[1]))
        row = snapshot_row(snapshot, target, env, time.monotonic() - self._started, env.task.index)
        self.sink.write(row)
        self.rows.append(row)
        return row

    def plot(self, path: str | Path, *, title: str) -> None:
        """Altitude, throttle, attitude and the ground track with the targets."""
        if not self.rows:
            return
        from bfsitl.records.plot import write_flight_plot

        write_flight_plot(self.rows, Path(path), title=title, waypoints=self.targets)

    def close(self) -> None:
        self.sink.close()
