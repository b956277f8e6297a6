"""A frame of the simulated flight: what ``render_mode="rgb_array"`` returns, and so what
Gymnasium's ``RecordVideo`` writes.

**The view.**  The camera sits behind and above the quad (south of it), looking north and
down, so north runs up the frame and east to the right, as on the flight plot's ground track.
It follows the quad, which stays in the middle of the frame; what moves is the world: a ground
grid of 1 m squares about the quad (fading out towards its edge), the pad where the quad armed
(the origin of the truth's frame) and the targets.  The ground is lighter far away and the grid
shrinks as the camera climbs with the quad, so height shows even in one frame.

**The quad** is an X of arms in 3D, turned by its roll, pitch and yaw, so its attitude shows:
the front arms red with a dot at the nose, the rear arms dark, each rotor's disc brighter the
harder its motor runs.  It is drawn larger than life (arms of ``ARM_M``) so that a tilt of a
few degrees reads at 320 pixels.  A dashed line drops from it to the ground, where its shadow
lies (straight below, as at noon): against the grid they say where it is over the ground.

**The targets.**  The current one is a cyan ball with its own dashed line and cross on the
ground; a waypoint task's points still to come are paler, the reached ones grey.  A gauge at
the right edge shows the quad's height (the white bar, 0 to ``Camera.gauge_top_m``) and the
current target's (the cyan tick).

**Why numpy, not matplotlib.**  A frame is a few hundred short segments and a few small fills
written into one array.  The same scene as a matplotlib 3D figure on the Agg backend
(:mod:`bfsitl.headless_pyplot`), tried when this was written, drew some thirty times fewer
frames a second, many times the cost of the step it shows; and pyplot keeps its figures in
global state that every environment (in threads, forked workers, Ray actors) would have to
make, keep and close.  Here there is no state at all: the same pose and targets give the
same pixels, whoever asks and in whatever order.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Literal, Protocol, get_args

import numpy as np

from bfsitl.errors import EnvironmentConfigError
from bfsitl.gym.snapshot import Vec3

#: What ``render()`` can return: an RGB frame (Gymnasium's name for it).
RenderMode = Literal["rgb_array"]
RENDER_MODES: tuple[RenderMode, ...] = get_args(RenderMode)

#: The quad as drawn: centre to motor, rotor disc radius (metres, larger than life).
ARM_M = 0.4
ROTOR_M = 0.16
#: The targets' balls and the grid about the quad.
TARGET_BALL_M = 0.13
GRID_STEP_M = 1.0
GRID_RADIUS_M = 10.0
PAD_HALF_M = 0.4
#: Nothing nearer the camera than this is drawn (what crosses it is cut there).
_NEAR_M = 0.2

Colour = tuple[int, int, int]
_PIXEL = np.dtype("V3")
_SKY: Colour = (178, 204, 230)
_GROUND_NEAR: Colour = (92, 122, 78)
_GROUND_FAR: Colour = (146, 166, 128)
_GRID: Colour = (196, 212, 184)
_PAD: Colour = (214, 210, 196)
_SHADOW: Colour = (52, 68, 46)
_DROP_LINE: Colour = (36, 36, 40)
_FRONT_ARM: Colour = (222, 38, 38)
_REAR_ARM: Colour = (34, 34, 44)
_ROTOR_IDLE: Colour = (92, 92, 104)
_ROTOR_FULL: Colour = (255, 214, 64)
_TARGET: Colour = (28, 214, 255)
_TARGET_EDGE: Colour = (10, 90, 120)
_TARGET_LATER: Colour = (150, 196, 214)
_TARGET_REACHED: Colour = (128, 128, 128)
_GAUGE_BACK: Colour = (36, 36, 40)
_GAUGE_BAR: Colour = (236, 236, 236)

#: Betaflight's quad X, motors M1..M4 (rear right, front right, rear left, front left) as
#: (forward, right) signs in the body's FRD axes.
_MOTOR_SIGNS = ((-1.0, 1.0), (1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))
_FRONT_MOTORS = (1, 3)
_DISC_POINTS = 12
#: A rotor's disc about its motor, in the body's plane.
_RING = (
    np.stack(
        [
            np.cos(np.linspace(0.0, 2 * math.pi, _DISC_POINTS, endpoint=False)),
            np.sin(np.linspace(0.0, 2 * math.pi, _DISC_POINTS, endpoint=False)),
            np.zeros(_DISC_POINTS),
        ],
        axis=1,
    )
    * ROTOR_M
)


class Pose(Protocol):
    """Where the quad is and how it is turned: the environment's truth
    (:class:`~bfsitl.gym.snapshot.TrueView`) is one, the FC's view another."""

    @property
    def north_m(self) -> float: ...
    @property
    def east_m(self) -> float: ...
    @property
    def alt_m(self) -> float: ...
    @property
    def roll_rad(self) -> float: ...  # right wing down +
    @property
    def pitch_rad(self) -> float: ...  # nose down +, as Betaflight reports it
    @property
    def yaw_rad(self) -> float: ...  # heading, clockwise from north
    @property
    def motors(self) -> tuple[float, ...]: ...  # M1..M4, 0..1


@dataclass(frozen=True, slots=True)
class Camera:
    """The frame's size and the camera's place: ``distance_m`` back along its line of sight
    from the quad, looking down ``elevation_deg`` below the horizon, ``fov_deg`` across."""

    width_px: int = 320
    height_px: int = 240
    distance_m: float = 5.0
    elevation_deg: float = 30.0
    fov_deg: float = 60.0
    gauge_top_m: float = 5.0

    def __post_init__(self) -> None:
        checks = (
            ("width_px", self.width_px, 64, 4096),
            ("height_px", self.height_px, 48, 4096),
            ("distance_m", self.distance_m, 1.0, 100.0),
            ("elevation_deg", self.elevation_deg, 5.0, 85.0),
            ("fov_deg", self.fov_deg, 20.0, 120.0),
            ("gauge_top_m", self.gauge_top_m, 1.0, 1000.0),
        )
        for name, value, low, high in checks:
            if not low <= value <= high:
                raise EnvironmentConfigError(f"Camera.{name} {value} is outside {low:g}..{high:g}")


DEFAULT_CAMERA = Camera()


def check_render_mode(render_mode: str | None) -> None:
    """Raise EnvironmentConfigError, in one line, unless ``render_mode`` is one this module
    draws or None (no frames)."""
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise EnvironmentConfigError(
            f"render_mode {render_mode!r} is not one the environment draws: "
            f"{', '.join(repr(m) for m in RENDER_MODES)} (a frame from above and behind) or None"
        )


def render_frame(
    pose: Pose,
    targets: Sequence[Vec3] = (),
    *,
    current: int = 0,
    camera: Camera = DEFAULT_CAMERA,
) -> np.ndarray:
    """The frame of ``pose`` (north, east, up from the arming point; Betaflight's attitude)
    with ``targets`` (north, east, up; ``current`` is the one flown to): uint8, (height,
    width, 3).  See the module docstring for what it shows."""
    view = _View(camera, (pose.north_m, pose.east_m, pose.alt_m))
    image = np.empty((camera.height_px, camera.width_px, 3), dtype=np.uint8)
    view.paint_background(image)
    _draw_grid(image, view)
    quad = _quad_points(pose)
    points = [np.asarray(t, dtype=float) for t in targets]
    colours = [_target_colour(index, current) for index in range(len(points))]
    # What lies on the ground or reaches down to it goes below every object, as it is seen.
    _draw_ground(image, view, quad, points, colours)
    # The objects from the farthest to the nearest, so a near one covers a far one.
    painters: list[tuple[float, Callable[[], None]]] = [
        (view.depth(quad.centre), partial(_draw_quad, image, view, quad, pose.motors))
    ]
    for index, (point, colour) in enumerate(zip(points, colours, strict=True)):
        scale = 1.0 if index == current else 0.7
        painters.append(
            (view.depth(point), partial(_draw_target, image, view, point, colour, scale))
        )
    for _, draw in sorted(painters, key=lambda item: -item[0]):
        draw()
    target_alt_m = float(points[current][2]) if 0 <= current < len(points) else None
    _draw_gauge(image, camera, pose.alt_m, target_alt_m)
    return image


# -- the camera ----------------------------------------------------------------------------------
class _View:
    """A pinhole camera behind and above ``look_at`` (north, east, up), looking north."""

    def __init__(self, camera: Camera, look_at: Vec3) -> None:
        self.camera = camera
        elevation = math.radians(camera.elevation_deg)
        sin_e, cos_e = math.sin(elevation), math.cos(elevation)
        self.look_at = np.asarray(look_at, dtype=float)
        # Forward (into the picture) is north and down; the camera stands back along it.
        self.position = self.look_at - camera.distance_m * np.array([cos_e, 0.0, -sin_e])
        # North, east, up offsets times this are right, up and depth in the camera's axes.
        self.axes = np.array([[0.0, sin_e, cos_e], [1.0, 0.0, 0.0], [0.0, cos_e, -sin_e]])
        self.focal_px = (camera.width_px / 2) / math.tan(math.radians(camera.fov_deg) / 2)
        self.centre_px = np.array([(camera.width_px - 1) / 2, (camera.height_px - 1) / 2])
        #: Lines and shapes scale with the frame (their widths are for 320 pixels across).
        self.scale = camera.width_px / 320

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) north, east, up -> (N, 3) right, up, depth."""
        return (np.atleast_2d(points) - self.position) @ self.axes

    def depth(self, point: np.ndarray) -> float:
        return float((point - self.position) @ self.axes[:, 2])

    def project(self, camera_points: np.ndarray) -> np.ndarray:
        """(N, 3) camera axes (depth > 0) -> (N, 2) pixel x, y."""
        flipped = camera_points[:, :2] * np.array([1.0, -1.0])
        return self.centre_px + self.focal_px * flipped / camera_points[:, 2:3]

    def pixels_per_m(self, point: np.ndarray) -> float | None:
        """How many pixels a metre spans at ``point``; None behind the near plane."""
        depth = self.depth(point)
        return self.focal_px / depth if depth > _NEAR_M else None

    def ground_colours(self, north_m: np.ndarray) -> np.ndarray:
        """(N, 3) the ground's colour that far north of the camera: lighter far away."""
        far = np.clip((north_m - self.position[0]) / 40.0, 0.0, 1.0)[:, None]
        return (1 - far) * np.array(_GROUND_NEAR) + far * np.array(_GROUND_FAR)

    def paint_background(self, image: np.ndarray) -> None:
        """Sky above the horizon; below it the ground, lighter with distance (how far the
        camera sees depends on its height, so the climb shows here too)."""
        rows = np.arange(image.shape[0], dtype=float)
        # Each row's angle below the horizon, and how far north the ground it sees is.
        below = math.radians(self.camera.elevation_deg) - np.arctan(
            (self.centre_px[1] - rows) / self.focal_px
        )
        camera_alt_m = max(float(self.position[2]), 0.05)
        ahead_m = camera_alt_m / np.tan(np.maximum(below, 1e-6))
        ground = self.ground_colours(self.position[0] + ahead_m)
        colours = np.where((below > 0)[:, None], ground, np.array(_SKY, dtype=float))
        image[:, 0] = np.rint(colours).astype(np.uint8)
        # Every row is one colour: copy the filled columns onto the next as many, doubling
        # (a broadcast of 3-byte pixels is several times slower).
        filled = 1
        while filled < image.shape[1]:
            count = min(filled, image.shape[1] - filled)
            image[:, filled : filled + count] = image[:, :count]
            filled += count


# -- the scene -----------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class _QuadPoints:
    """The quad in the world (north, east, up): its centre, nose and motors, and each
    rotor's disc as a ring of points."""

    centre: np.ndarray  # (3,)
    nose: np.ndarray  # (3,)
    motors: np.ndarray  # (4, 3)
    discs: np.ndarray  # (4, _DISC_POINTS, 3)


def body_to_world(roll_rad: float, pitch_rad: float, yaw_rad: float) -> np.ndarray:
    """The rotation of body FRD vectors into north, east, up, from Betaflight's angles
    (its pitch is nose down positive: the aerospace pitch negated)."""
    pitch = -pitch_rad
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    ned = np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
    return ned * np.array([[1.0], [1.0], [-1.0]])  # down -> up


def _quad_points(pose: Pose) -> _QuadPoints:
    rotation = body_to_world(pose.roll_rad, pose.pitch_rad, pose.yaw_rad)
    centre = np.array([pose.north_m, pose.east_m, pose.alt_m], dtype=float)
    half = ARM_M / math.sqrt(2)
    motors_frd = np.array([[f * half, r * half, 0.0] for f, r in _MOTOR_SIGNS])
    # The discs a little above the arms (FRD: up is -z), as the propellers are.
    discs_frd = motors_frd[:, None, :] + _RING + np.array([0.0, 0.0, -0.02])
    return _QuadPoints(
        centre=centre,
        nose=centre + rotation @ np.array([ARM_M * 0.95, 0.0, 0.0]),
        motors=centre + motors_frd @ rotation.T,
        discs=centre + discs_frd @ rotation.T,
    )


def _draw_grid(image: np.ndarray, view: _View) -> None:
    """1 m squares about the quad, cut into 1 m pieces so each fades with its own distance
    from it."""
    north, east, _ = view.look_at
    count = round(GRID_RADIUS_M / GRID_STEP_M)
    steps = np.arange(-count, count + 1) * GRID_STEP_M
    origin = np.floor(np.array([north, east, 0.0]) / GRID_STEP_M) * GRID_STEP_M
    lines, pieces = (a.ravel() for a in np.meshgrid(steps, steps[:-1], indexing="ij"))
    zeros = np.zeros_like(lines)
    # Pieces along the east axis (constant north), then along the north axis (constant east).
    starts = origin + np.concatenate(
        [np.stack([lines, pieces, zeros], axis=1), np.stack([pieces, lines, zeros], axis=1)]
    )
    ends = starts.copy()
    ends[: len(lines), 1] += GRID_STEP_M
    ends[len(lines) :, 0] += GRID_STEP_M
    middles = (starts + ends) / 2
    off_m = np.hypot(middles[:, 0] - north, middles[:, 1] - east)
    # Each piece is as much grid as it is near the quad, the rest the ground beneath it.
    alpha = (np.clip(1.0 - off_m / GRID_RADIUS_M, 0.0, 1.0) ** 1.5 * 0.9)[:, None]
    colours = (1 - alpha) * view.ground_colours(middles[:, 0]) + alpha * np.array(_GRID)
    _segments_3d(image, view, starts, ends, colours, 1)


def _draw_ground(
    image: np.ndarray,
    view: _View,
    quad: _QuadPoints,
    targets: list[np.ndarray],
    colours: list[Colour],
) -> None:
    """The pad where the quad armed (with an arrow pointing north), the quad's shadow, a
    cross below each target, and dashed lines from the quad and the targets to the ground:
    one batch of segments."""
    h = PAD_HALF_M
    _polygon_3d(
        image, view, np.array([[-h, -h, 0.0], [-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0]]), _PAD
    )
    flat = np.array([1.0, 1.0, 0.0])
    for disc in quad.discs:
        _polygon_3d(image, view, disc * flat, _SHADOW)
    s = max(1, round(view.scale))
    segments: list[tuple[np.ndarray, np.ndarray, Colour, int]] = [
        (np.array([[-0.6 * h, 0, 0]]), np.array([[0.8 * h, 0, 0]]), _SHADOW, s),
        (np.tile(quad.centre * flat, (4, 1)), quad.motors * flat, _SHADOW, 3 * s),
        _dashes(quad.centre, _DROP_LINE, s),
    ]
    cross = np.array([[0.25, 0.0, 0.0], [0.0, 0.25, 0.0]])
    for target, colour in zip(targets, colours, strict=True):
        segments.append((target * flat - cross, target * flat + cross, colour, 2 * s))
        segments.append(_dashes(target, colour, s))
    starts = np.concatenate([a for a, _, _, _ in segments])
    ends = np.concatenate([b for _, b, _, _ in segments])
    counts = [len(a) for a, _, _, _ in segments]
    each_colour = np.repeat(np.array([c for _, _, c, _ in segments], dtype=float), counts, axis=0)
    widths = np.repeat([w for _, _, _, w in segments], counts)
    _segments_3d(image, view, starts, ends, each_colour, widths)


def _draw_quad(image: np.ndarray, view: _View, quad: _QuadPoints, motors: Sequence[float]) -> None:
    """The arms, then the rotors' discs farthest first (a near rotor covers a far one), lit
    by their motors, outlined in their arm's colour; the nose's dot on top."""
    arm_colours = np.array(
        [_FRONT_ARM if m in _FRONT_MOTORS else _REAR_ARM for m in range(4)], dtype=float
    )
    width = max(1, round(3 * view.scale))
    _segments_3d(image, view, np.tile(quad.centre, (4, 1)), quad.motors, arm_colours, width)
    for motor in sorted(range(4), key=lambda m: -view.depth(quad.motors[m])):
        output = motors[motor] if motor < len(motors) else math.nan
        lit = min(1.0, max(0.0, output)) if math.isfinite(output) else 0.0
        _polygon_3d(image, view, quad.discs[motor], _mix(_ROTOR_IDLE, _ROTOR_FULL, lit))
    rings = quad.discs.reshape(-1, 3)
    ring_ends = np.roll(quad.discs, -1, axis=1).reshape(-1, 3)
    ring_colours = np.repeat(arm_colours, _DISC_POINTS, axis=0)
    _segments_3d(image, view, rings, ring_ends, ring_colours, 1)
    per_m = view.pixels_per_m(quad.nose)
    if per_m is not None:
        x, y = view.project(view.to_camera(quad.nose))[0]
        _disc(image, x, y, max(2.0, 0.09 * per_m), _FRONT_ARM)


def _draw_target(
    image: np.ndarray, view: _View, target: np.ndarray, colour: Colour, scale: float
) -> None:
    per_m = view.pixels_per_m(target)
    if per_m is None:
        return
    x, y = view.project(view.to_camera(target))[0]
    radius = max(2.0, scale * TARGET_BALL_M * per_m)
    _disc(image, x, y, radius + max(1.0, view.scale), _TARGET_EDGE)
    _disc(image, x, y, radius, colour)


def _draw_gauge(
    image: np.ndarray, camera: Camera, alt_m: float, target_alt_m: float | None
) -> None:
    scale = camera.width_px / 320
    height, width = image.shape[:2]
    top, bottom = round(12 * scale), height - 1 - round(12 * scale)
    left, right = width - round(14 * scale), width - round(7 * scale)
    image[top : bottom + 1, left : right + 1] = _GAUGE_BACK

    def row(value_m: float) -> int:
        fraction = min(1.0, max(0.0, value_m / camera.gauge_top_m))
        return round(bottom - fraction * (bottom - top))

    if math.isfinite(alt_m):
        image[row(alt_m) : bottom + 1, left + 1 : right] = _GAUGE_BAR
    if target_alt_m is not None and math.isfinite(target_alt_m):
        tick = row(target_alt_m)
        image[max(top, tick - 1) : tick + 1, left - round(4 * scale) : right + 1] = _TARGET


def _target_colour(index: int, current: int) -> Colour:
    if index == current:
        return _TARGET
    return _TARGET_REACHED if index < current else _TARGET_LATER


def _dashes(
    point: np.ndarray, colour: Colour, width: int
) -> tuple[np.ndarray, np.ndarray, Colour, int]:
    """A dashed vertical line from ``point`` down to the ground (dashes of 0.15 m)."""
    height_m = float(point[2]) if math.isfinite(point[2]) else 0.0
    dash_m = 0.15
    tops = np.arange(height_m, 0.0, -2 * dash_m)
    starts = np.tile(point, (len(tops), 1))
    starts[:, 2] = tops
    ends = starts.copy()
    ends[:, 2] = np.maximum(tops - dash_m, 0.0)
    return starts, ends, colour, width


def _mix(a: Colour, b: Colour, fraction: float) -> Colour:
    r, g, b_ = (round(x + (y - x) * fraction) for x, y in zip(a, b, strict=True))
    return (r, g, b_)


# -- rasterising ---------------------------------------------------------------------------------
def _segments_3d(
    image: np.ndarray,
    view: _View,
    starts: np.ndarray,
    ends: np.ndarray,
    colours: Colour | np.ndarray,
    widths: int | np.ndarray,
) -> None:
    """World segments (one colour and width, or one each), cut at the near plane,
    projected and drawn."""
    count = len(starts)
    colours = np.broadcast_to(np.asarray(colours, dtype=float), (count, 3))
    widths = np.broadcast_to(np.asarray(widths, dtype=np.int64), (count,))
    a, b = view.to_camera(starts), view.to_camera(ends)
    za, zb = a[:, 2], b[:, 2]
    keep = (np.maximum(za, zb) > _NEAR_M) & np.isfinite(za) & np.isfinite(zb)
    # A kept segment has at most one end behind the near plane: that end moves onto it.
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing = a + (b - a) * ((_NEAR_M - za) / (zb - za))[:, None]
    a = np.where((za < _NEAR_M)[:, None], crossing, a)[keep]
    b = np.where((zb < _NEAR_M)[:, None], crossing, b)[keep]
    _segments_2d(image, view.project(a), view.project(b), colours[keep], widths[keep])


def _segments_2d(
    image: np.ndarray, a: np.ndarray, b: np.ndarray, colours: np.ndarray, widths: np.ndarray
) -> None:
    """Pixel segments, cut to the frame first (so one that projects to thousands of pixels
    costs no more than one across the frame), one sample per pixel of length, each sample a
    square of its segment's width.  Coordinates travel as separate 1D arrays: numpy gathers
    those several times faster than rows of a 2D one."""
    height, frame_width = image.shape[:2]
    margin = float(widths.max()) if len(widths) else 0.0
    x0, y0, x1, y1, keep = _clip_to_box(
        a[:, 0],
        a[:, 1],
        b[:, 0],
        b[:, 1],
        (-margin, -margin),
        (frame_width + margin, height + margin),
    )
    if not keep.any():
        return
    x0, y0, x1, y1, widths = x0[keep], y0[keep], x1[keep], y1[keep], widths[keep]
    # Pixels as single 3-byte items: one scatter writes a whole pixel.
    pixels = image.reshape(-1, 3).view(_PIXEL).reshape(-1)
    paint = np.ascontiguousarray(np.rint(colours[keep]), dtype=np.uint8).view(_PIXEL).reshape(-1)
    dx, dy = x1 - x0, y1 - y0
    counts = np.ceil(np.maximum(np.abs(dx), np.abs(dy))).astype(np.int64) + 1
    segment = np.repeat(np.arange(len(counts)), counts)
    first = np.repeat(np.cumsum(counts) - counts, counts)
    step = (np.arange(len(segment)) - first) / np.repeat(np.maximum(counts - 1, 1), counts)
    xs = np.rint(x0[segment] + dx[segment] * step).astype(np.int64)
    ys = np.rint(y0[segment] + dy[segment] * step).astype(np.int64)
    for width in np.unique(widths).tolist():
        picked = np.repeat(widths == width, counts)
        x, y, owner = xs[picked], ys[picked], segment[picked]
        if width > 1:
            low = -((width - 1) // 2)
            offsets = np.arange(low, low + width)
            x = (x[:, None, None] + offsets[None, None, :]).repeat(width, axis=1).ravel()
            y = (y[:, None, None] + offsets[None, :, None]).repeat(width, axis=2).ravel()
            owner = owner.repeat(width * width)
        inside = (x >= 0) & (x < frame_width) & (y >= 0) & (y < height)
        pixels[y[inside] * frame_width + x[inside]] = paint[owner[inside]]


def _clip_to_box(
    x0: np.ndarray,
    y0: np.ndarray,
    x1: np.ndarray,
    y1: np.ndarray,
    low: tuple[float, float],
    high: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Liang-Barsky for many segments at once: the parts inside the box, and which have
    one."""
    dx, dy = x1 - x0, y1 - y0
    t0, t1 = np.zeros(len(x0)), np.ones(len(x0))
    keep = np.isfinite(x0) & np.isfinite(y0) & np.isfinite(x1) & np.isfinite(y1)
    # The four sides, each as (p, q): the segment is outside where p t < q fails.
    sides = ((-dx, x0 - low[0]), (dx, high[0] - x0), (-dy, y0 - low[1]), (dy, high[1] - y0))
    with np.errstate(divide="ignore", invalid="ignore"):
        for p, q in sides:
            keep &= (p != 0) | (q >= 0)
            ratio = q / p
            t0 = np.where(p < 0, np.maximum(t0, ratio), t0)
            t1 = np.where(p > 0, np.minimum(t1, ratio), t1)
    keep &= t0 <= t1
    return x0 + dx * t0, y0 + dy * t0, x0 + dx * t1, y0 + dy * t1, keep


def _polygon_3d(image: np.ndarray, view: _View, corners: np.ndarray, colour: Colour) -> None:
    """A convex world polygon, drawn only when all of it is in front of the camera (the
    pad, the shadows and the discs it is used for are small)."""
    points = view.to_camera(corners)
    if (points[:, 2] > _NEAR_M).all():
        _fill_convex(image, view.project(points), colour)


def _fill_convex(image: np.ndarray, corners: np.ndarray, colour: Colour) -> None:
    low, high = corners.min(axis=0), corners.max(axis=0)
    if not (np.isfinite(low).all() and np.isfinite(high).all()):
        return
    height, width = image.shape[:2]
    x0, y0 = max(0, math.floor(low[0])), max(0, math.floor(low[1]))
    x1, y1 = min(width - 1, math.ceil(high[0])), min(height - 1, math.ceil(high[1]))
    if x0 > x1 or y0 > y1:
        return
    cx, cy = corners[:, 0, None, None], corners[:, 1, None, None]
    ex = np.concatenate((corners[1:, 0], corners[:1, 0]))[:, None, None] - cx
    ey = np.concatenate((corners[1:, 1], corners[:1, 1]))[:, None, None] - cy
    xs = np.arange(x0, x1 + 1, dtype=float)[None, None, :]
    ys = np.arange(y0, y1 + 1, dtype=float)[None, :, None]
    # The side of every edge each pixel is on: inside is the same side of all of them,
    # whichever way round the corners go.
    cross = ex * (ys - cy) - ey * (xs - cx)
    inside = (cross >= 0).all(axis=0) | (cross <= 0).all(axis=0)
    image[y0 : y1 + 1, x0 : x1 + 1][inside] = colour


def _disc(image: np.ndarray, x: float, y: float, radius: float, colour: Colour) -> None:
    if not (math.isfinite(x) and math.isfinite(y)):
        return
    height, width = image.shape[:2]
    x0, x1 = max(0, math.floor(x - radius)), min(width - 1, math.ceil(x + radius))
    y0, y1 = max(0, math.floor(y - radius)), min(height - 1, math.ceil(y + radius))
    if x0 > x1 or y0 > y1:
        return
    xs = np.arange(x0, x1 + 1)[None, :]
    ys = np.arange(y0, y1 + 1)[:, None]
    inside = (xs - x) ** 2 + (ys - y) ** 2 <= radius * radius
    image[y0 : y1 + 1, x0 : x1 + 1][inside] = colour
