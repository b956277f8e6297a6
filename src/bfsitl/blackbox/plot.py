"""The FC's own view of a flight, from its blackbox: rate setpoint against the gyro on each
axis, the motor outputs, and the receiver and failsafe state, on the log's time axis.

The gyro against its setpoint is where a wrong motor order, a wrong sign or a sick motor
shows first; the receiver lines show when the FC itself considered the link lost.
"""

from __future__ import annotations

from pathlib import Path

from bfsitl.blackbox.decode import BlackboxLog
from bfsitl.headless_pyplot import load_pyplot
from bfsitl.protocol.failsafe_phase import FailsafePhase

AXES = ("roll", "pitch", "yaw")


def write_blackbox_plot(log: BlackboxLog, path: str | Path, *, title: str = "") -> Path:
    plt = load_pyplot()
    frames = log.frames
    start = frames[0].time_s if frames else 0.0
    t = [f.time_s - start for f in frames]
    figure, axes = plt.subplots(5, 1, figsize=(9, 9), sharex=True)
    for index, axis in enumerate(axes[:3]):
        axis.plot(
            t,
            [f.setpoint[index] if len(f.setpoint) > index else float("nan") for f in frames],
            linewidth=1.0,
            label="setpoint",
        )
        axis.plot(
            t,
            [f.gyro_adc[index] if len(f.gyro_adc) > index else float("nan") for f in frames],
            linewidth=0.8,
            label="gyro",
        )
        axis.set_ylabel(f"{AXES[index]} (deg/s)")
        axis.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    for motor in range(4):
        axes[3].plot(
            t,
            [f.motors[motor] if len(f.motors) > motor else float("nan") for f in frames],
            linewidth=0.8,
            label=f"M{motor + 1}",
        )
    axes[3].set_ylabel("motor (as logged)")
    axes[3].legend(loc="upper right", fontsize=8, ncol=4)
    axes[3].grid(alpha=0.3)
    phase = [f.failsafe_phase if f.failsafe_phase is not None else float("nan") for f in frames]
    axes[4].step(t, phase, where="post", color="tab:red", label="failsafe phase")
    axes[4].step(
        t,
        [
            0.5
            if f.rx_flight_channels_valid
            else -0.5
            if f.rx_flight_channels_valid is not None
            else float("nan")
            for f in frames
        ],
        where="post",
        color="tab:blue",
        label="flight channels valid (+) / invalid (-)",
    )
    axes[4].set_yticks([-0.5, *range(len(FailsafePhase))])
    axes[4].set_yticklabels(["invalid", *[p.name for p in FailsafePhase]], fontsize=7)
    axes[4].legend(loc="upper right", fontsize=7)
    # The FC starts its log when it arms, so this is the scenario plot's clock (from arming)
    # to within a frame.
    axes[4].set_xlabel("seconds from the log's first frame: the FC arming (FC time)")
    axes[4].grid(alpha=0.3)
    reason = f", disarmed: {log.disarm_reason_name}" if log.disarm_reason_name else ""
    # Two lines: a long scenario name and firmware string cut the disarm reason off.
    axes[0].set_title(
        (title + "\n" if title else "") + f"blackbox: {log.firmware_revision}" + reason,
        fontsize=10,
    )
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return path
