"""Each axis' control effectiveness and the motor time constant, from how the body rates
follow the motors.

Per axis, over every half-second training window (:mod:`bfsitl.fit.windows`), the rate's
change from the window's start is the integral of the angular acceleration the model gives:

    d_omega(t) = k dU(t) + c dS(t) - d dW(t) + b (t - t0) + e dC(t)   [+ s dX(t) on yaw]

``U`` is the integral of the rotors' thrust shares with the axis' signs (the torque the
mixer makes), ``S`` of their sum (a centre of mass off the thrust's centre turns all thrust
into torque), ``W`` of the logged rate (damping by the rotors' inflow), ``b`` a constant trim,
``C`` of the product of the other two axes' rates (the rigid body's own coupling, ``(I_yy -
I_zz) / I_xx`` on roll) and, on yaw, ``X`` the rotors' speed shares with the yaw signs (the
spin-up reaction).

The equation is linear in the coefficients, so numpy's least squares solves it exactly for a
given motor model.  The motor time constant is the one (5-150 ms) that leaves the least roll
and pitch error, found by scipy's bounded scalar search, for each delay of 0 to
:data:`MAX_DELAY_MS` by which the logged gyro may trail the motors (the FC's own gyro filters:
that delay is the log's, not the quad's, so the profile does not carry it).  Integrated sums
average the motors' noise out where a derivative of the gyro amplifies it: regressing the
differentiated rates came out 35-60 % low on a SITL log of a known quad.

Uncertainties come from resampling the windows (a bootstrap, with the lag and the delay held
at their fitted values): neighbouring frames are not independent samples, windows nearly are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfsitl.errors import FitError
from bfsitl.fit.log_data import FlightData
from bfsitl.fit.motor_model import PITCH_SIGNS, ROLL_SIGNS, YAW_SIGNS, delayed, rotor_speeds
from bfsitl.fit.windows import Windows

TIME_CONSTANT_RANGE_S = (0.005, 0.150)
#: An effectiveness counts as measured this many standard errors clear of zero.
IDENTIFIED_STDS = 3.0
#: The gyro's filtering delays what it reads by a few milliseconds (a PT1 at 100 Hz by
#: 1.6 ms); delays of 0 to this many milliseconds are tried, in whole frames.
MAX_DELAY_MS = 5
BOOTSTRAP_DRAWS = 40
AXES = ("roll", "pitch", "yaw")


@dataclass(frozen=True, slots=True)
class Estimate:
    """A fitted value and its standard error."""

    value: float
    std: float

    def as_dict(self) -> dict[str, float]:
        return {"value": self.value, "std": self.std}


@dataclass(frozen=True, slots=True)
class AxisFit:
    """One axis: angular acceleration per unit of rotor thrust share (rad/s^2; one rotor at
    full thrust is 1), the centre-of-mass term, the rate damping (1/s), the trim (rad/s^2),
    the rigid-body coupling (a ratio of inertias) and, on yaw, the spin-up term (rad/s per
    unit of speed share)."""

    effectiveness: Estimate
    offset_per_thrust: float
    damping_per_s: float
    trim_rad_s2: float
    coupling: float = 0.0
    spin_up: float = 0.0


@dataclass(frozen=True, slots=True)
class RotationFit:
    """The motors' lag, how late the gyro sees them (its filtering), and each axis."""

    time_constant_s: float
    delay_frames: int
    delay_s: float
    roll: AxisFit
    pitch: AxisFit
    yaw: AxisFit
    train_error: tuple[float, float, float]  # per axis: RMS error over RMS rate

    @property
    def yaw_identified(self) -> bool:
        """The yaw's effectiveness stands :data:`IDENTIFIED_STDS` standard errors clear of
        zero: the log's yaw follows the motors."""
        return _identified(self.yaw.effectiveness)

    @property
    def props_out(self) -> bool:
        """The yaw follows the motors the other way round: the props spin outwards."""
        return self.yaw_identified and self.yaw.effectiveness.value < 0

    @property
    def at_bounds(self) -> list[str]:
        """The searched figures that ended at the edge of their range (then not measured)."""
        edges = []
        low, high = TIME_CONSTANT_RANGE_S
        if not low + 1e-3 < self.time_constant_s < high - 1e-3:
            edges.append(
                f"the motor time constant ({self.time_constant_s * 1000:.0f} ms) is at the edge "
                f"of the {low * 1000:.0f}-{high * 1000:.0f} ms searched"
            )
        if self.delay_s >= MAX_DELAY_MS / 1000.0 - 1e-9:
            edges.append(
                f"the gyro delay ({self.delay_s * 1000:.0f} ms) is at the edge of the "
                f"0-{MAX_DELAY_MS} ms searched"
            )
        return edges

    def axis(self, index: int) -> AxisFit:
        return (self.roll, self.pitch, self.yaw)[index]


def _identified(estimate: Estimate) -> bool:
    return abs(estimate.value) >= IDENTIFIED_STDS * estimate.std


def _integral(values: np.ndarray, dt_s: float) -> np.ndarray:
    """The running integral along the last axis (rectangles: the physics holds a command for
    a step), zero at the first frame."""
    total = np.cumsum(values, axis=-1) * dt_s
    return np.concatenate([np.zeros(values.shape[:-1] + (1,)), total[..., :-1]], axis=-1)


def axis_terms(
    data: FlightData, beta: float, time_constant_s: float, delay_frames: int = 0
) -> list[np.ndarray]:
    """Each axis' integrated regressors (terms, N) in the order of the module doc, with the
    motors seen ``delay_frames`` late (the gyro's filtering delay)."""
    motors = delayed(data.motors, delay_frames)
    speeds = rotor_speeds(motors, beta, time_constant_s, data.dt_s)
    thrust = speeds**2
    total = _integral(thrust.sum(axis=0), data.dt_s)
    ramp = data.time_s - data.time_s[0]
    rates = data.gyro_frd_rad_s
    terms = []
    for index, signs in enumerate((ROLL_SIGNS, PITCH_SIGNS, YAW_SIGNS)):
        # The rigid body's own coupling: (I_yy - I_zz) / I_xx * q * r on roll, and so on.
        other, third = [axis for axis in range(3) if axis != index]
        coupling = _integral(rates[other] * rates[third], data.dt_s)
        rate = _integral(rates[index], data.dt_s)
        columns = [_integral(signs @ thrust, data.dt_s), total, -rate, ramp, coupling]
        if index == 2:
            # The rate at frame n has felt the rotors' spin-up up to the end of step n - 1.
            spin = YAW_SIGNS @ speeds
            columns.append(np.concatenate([spin[:1], spin[:-1]]))
        terms.append(np.vstack(columns))
    return terms


def _design(terms: np.ndarray, target: np.ndarray, windows: Windows) -> tuple[np.ndarray, ...]:
    design = windows.changes(terms)  # (terms, windows, length)
    change = windows.changes(target)  # (windows, length)
    return design, change


def _solve(design: np.ndarray, change: np.ndarray, rows: np.ndarray) -> np.ndarray:
    matrix = design[:, rows, :].reshape(design.shape[0], -1).T
    solution, *_ = np.linalg.lstsq(matrix, change[rows].ravel(), rcond=None)
    return np.asarray(solution)


def _relative_error(
    design: np.ndarray, change: np.ndarray, coefficients: np.ndarray, rate: np.ndarray
) -> float:
    predicted = np.tensordot(coefficients, design, axes=1)
    return float(np.sqrt(np.mean((predicted - change) ** 2)) / max(_rms(rate), 1e-9))


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2)))


def _axes_fit(
    data: FlightData, windows: Windows, beta: float, time_constant_s: float, delay_frames: int
) -> tuple[list[np.ndarray], list[float], list[tuple[np.ndarray, np.ndarray]]]:
    everything = np.arange(len(windows))
    solutions, errors, designs = [], [], []
    for index, terms in enumerate(axis_terms(data, beta, time_constant_s, delay_frames)):
        design, change = _design(terms, data.gyro_frd_rad_s[index], windows)
        solution = _solve(design, change, everything)
        rate = windows.spans(data.gyro_frd_rad_s[index])
        solutions.append(solution)
        errors.append(_relative_error(design, change, solution, rate))
        designs.append((design, change))
    return solutions, errors, designs


def fit_rotation(data: FlightData, windows: Windows, beta: float, *, seed: int = 0) -> RotationFit:
    """Each axis' terms and the motor time constant (see the module doc).

    Raises:
        FitError: Too few windows, or roll or pitch rates that do not follow the motors.
    """
    if len(windows) < 10:
        raise FitError(
            f"{data.label}: {len(windows)} half-second windows of usable flight; a fit needs "
            "at least 10"
        )

    def lag_for(delay_frames: int) -> tuple[float, float]:
        """The best time constant with this delay, and its roll and pitch error."""

        def roll_pitch_error(time_constant_s: float) -> float:
            _, errors, _ = _axes_fit(data, windows, beta, time_constant_s, delay_frames)
            return errors[0] + errors[1]

        from scipy import optimize  # imported when used, as in motor_model

        search = optimize.minimize_scalar(
            roll_pitch_error,
            bounds=TIME_CONSTANT_RANGE_S,
            method="bounded",
            options={"xatol": 1e-3},
        )
        return float(search.x), float(search.fun)

    delays = sorted({round(ms / 1000.0 / data.dt_s) for ms in range(MAX_DELAY_MS + 1)})
    lags = {delay: lag_for(delay) for delay in delays}
    delay_frames = min(lags, key=lambda delay: lags[delay][1])
    time_constant_s = lags[delay_frames][0]
    solutions, errors, designs = _axes_fit(data, windows, beta, time_constant_s, delay_frames)
    rng = np.random.default_rng(seed)
    draws = [
        [_solve(design, change, rng.integers(0, len(windows), len(windows)))[0]]
        for _ in range(BOOTSTRAP_DRAWS)
        for design, change in designs
    ]
    spread = np.array(draws).reshape(BOOTSTRAP_DRAWS, 3).std(axis=0)
    axes = []
    for index, solution in enumerate(solutions):
        axes.append(
            AxisFit(
                effectiveness=Estimate(float(solution[0]), float(spread[index])),
                offset_per_thrust=float(solution[1]),
                damping_per_s=float(solution[2]),
                trim_rad_s2=float(solution[3]),
                coupling=float(solution[4]),
                spin_up=float(solution[5]) if len(solution) > 5 else 0.0,
            )
        )
    for name, axis in zip(AXES[:2], axes[:2], strict=True):
        estimate = axis.effectiveness
        if estimate.value <= 0:
            raise FitError(
                f"{data.label}: the {name} rates do not follow the motors (effectiveness "
                f"{estimate.value:.3g}): is this a quad-X in Betaflight's motor order?"
            )
        if not _identified(estimate):
            raise FitError(
                f"{data.label}: the {name} rates hardly follow the motors (effectiveness "
                f"{estimate.value:.3g} +- {estimate.std:.2g}, under {IDENTIFIED_STDS:g} standard "
                "errors): fit a calmer flight with sharp stick moves"
            )
    return RotationFit(
        time_constant_s,
        delay_frames=delay_frames,
        delay_s=delay_frames * data.dt_s,
        roll=axes[0],
        pitch=axes[1],
        yaw=axes[2],
        train_error=(errors[0], errors[1], errors[2]),
    )
