"""The frames of ``render_mode="rgb_array"``, without a SITL: what the picture says (the
quad's attitude, its place, its height, the target's place) read back from the pixels, the
option refused or honoured by the environment and the vector environment, and Gymnasium's
own render checks and RecordVideo on the frames."""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

pytest.importorskip("gymnasium")

import gymnasium  # noqa: E402
from support.fake_builds import fake_lockstep_build  # noqa: E402
from support.fake_flight_env import FakeFlightEnv  # noqa: E402
from test_gym_parts import snapshot  # noqa: E402

from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.gym.env import FlightEnv, HoverEnv  # noqa: E402
from bfsitl.gym.render import (  # noqa: E402
    _FRONT_ARM,
    _GAUGE_BAR,
    _PAD,
    _ROTOR_FULL,
    _ROTOR_IDLE,
    _SHADOW,
    _TARGET,
    Camera,
    _mix,
    render_frame,
)
from bfsitl.gym.vector import FlightVectorEnv  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402

WIDTH, HEIGHT = 320, 240
#: The frame's middle, where the camera keeps the quad.
CX, CY = (WIDTH - 1) / 2, (HEIGHT - 1) / 2
#: Left of the height gauge at the right edge (its target tick is the target's colour too).
SCENE_RIGHT = WIDTH - 24


@dataclass(frozen=True)
class Pose:
    north_m: float = 0.0
    east_m: float = 0.0
    alt_m: float = 1.5
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0
    # Each rotor lit differently, so that each one's disc is found by its colour.
    motors: tuple[float, ...] = (0.0, 1 / 3, 2 / 3, 1.0)


def where(frame: np.ndarray, colour: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The x and y of the scene's pixels of exactly ``colour`` (the gauge left out)."""
    ys, xs = np.nonzero((frame[:, :SCENE_RIGHT] == np.array(colour, dtype=np.uint8)).all(axis=2))
    return xs, ys


def centre_of(frame: np.ndarray, colour: tuple[int, int, int]) -> tuple[float, float]:
    xs, ys = where(frame, colour)
    assert len(xs) > 0, f"nothing of {colour} in the frame"
    return float(xs.mean()), float(ys.mean())


def rotor(frame: np.ndarray, motor: int) -> tuple[float, float]:
    """Where the disc of motor M1..M4 (0..3) is drawn."""
    return centre_of(frame, _mix(_ROTOR_IDLE, _ROTOR_FULL, Pose().motors[motor]))


# -- the frame -----------------------------------------------------------------------------------
def test_a_frame_is_rgb_bytes_of_the_cameras_size_and_the_same_pose_gives_the_same_pixels() -> None:
    frame = render_frame(Pose(), [(1.0, 1.0, 2.0)])
    assert frame.shape == (HEIGHT, WIDTH, 3) and frame.dtype == np.uint8
    assert np.array_equal(frame, render_frame(Pose(), [(1.0, 1.0, 2.0)]))
    large = render_frame(Pose(), camera=Camera(width_px=480, height_px=360))
    assert large.shape == (360, 480, 3) and large.dtype == np.uint8
    with pytest.raises(EnvironmentConfigError, match="Camera.width_px 10 is outside"):
        Camera(width_px=10)


def test_a_roll_right_puts_the_right_rotors_lower_and_a_pitch_down_the_front_ones() -> None:
    level = render_frame(Pose())
    # Level, seen from straight behind: left and right rotors side by side, front ones
    # farther up the frame.
    for right, left in ((0, 2), (1, 3)):
        assert rotor(level, right)[1] == pytest.approx(rotor(level, left)[1], abs=1.0)
        assert rotor(level, right)[0] > CX > rotor(level, left)[0]
    assert rotor(level, 1)[1] < rotor(level, 0)[1]
    rolled = render_frame(Pose(roll_rad=0.4))  # right wing down
    assert not np.array_equal(rolled, level)
    for right, left in ((0, 2), (1, 3)):
        assert rotor(rolled, right)[1] > rotor(rolled, left)[1] + 5
    pitched = render_frame(Pose(pitch_rad=0.3))  # nose down, as Betaflight counts it
    assert rotor(pitched, 1)[1] > rotor(level, 1)[1] + 3  # the front comes down
    assert rotor(pitched, 0)[1] < rotor(level, 0)[1] - 3  # the rear goes up


@pytest.mark.parametrize(
    ("yaw_deg", "side"),
    [(0.0, "up"), (90.0, "right"), (180.0, "down"), (270.0, "left")],
)
def test_the_red_nose_points_where_the_quad_heads(yaw_deg: float, side: str) -> None:
    # North is up the frame and east to the right, as on the flight plot's track.
    x, y = centre_of(render_frame(Pose(yaw_rad=math.radians(yaw_deg))), _FRONT_ARM)
    offset = {"up": CY - y, "down": y - CY, "right": x - CX, "left": CX - x}[side]
    assert offset > 4


def test_moving_over_the_ground_moves_the_world_under_the_quad() -> None:
    # The camera follows the quad: the pad where it armed moves the other way.
    home = centre_of(render_frame(Pose(alt_m=1.0)), _PAD)
    north = centre_of(render_frame(Pose(north_m=0.5, alt_m=1.0)), _PAD)
    east = centre_of(render_frame(Pose(east_m=0.5, alt_m=1.0)), _PAD)
    assert north[1] > home[1] + 3 and north[0] == pytest.approx(home[0], abs=1.0)
    assert east[0] < home[0] - 3
    assert not np.array_equal(
        render_frame(Pose(north_m=5.3, east_m=-7.1)), render_frame(Pose(north_m=5.0, east_m=-7.0))
    )  # far from the pad, the grid shows it


def test_climbing_lengthens_the_drop_to_the_shadow_and_fills_the_gauge() -> None:
    low, high = render_frame(Pose(alt_m=1.0)), render_frame(Pose(alt_m=3.0))
    assert centre_of(high, _SHADOW)[1] > centre_of(low, _SHADOW)[1] + 10

    def bar_px(frame: np.ndarray) -> int:
        return int(
            (frame[:, SCENE_RIGHT:] == np.array(_GAUGE_BAR, dtype=np.uint8)).all(axis=2).sum()
        )

    assert bar_px(high) > 2 * bar_px(low) > 0


@pytest.mark.parametrize(("north_m", "east_m"), [(2.0, 1.5), (2.0, -1.5), (0.0, 1.0)])
def test_the_target_is_drawn_where_it_is(north_m: float, east_m: float) -> None:
    frame = render_frame(Pose(), [(north_m, east_m, 2.5)])
    xs, ys = where(frame, _TARGET)  # its ball, its line and the cross below it
    assert len(xs) > 20
    assert ((xs > CX) if east_m > 0 else (xs < CX)).all()
    # Farther north is higher up the frame than a point nearer the camera.
    nearer = where(render_frame(Pose(), [(north_m - 0.5, east_m, 2.5)]), _TARGET)[1]
    assert ys.min() < nearer.min()
    assert len(where(render_frame(Pose()), _TARGET)[0]) == 0  # no target, no mark


def test_only_the_current_waypoint_has_the_targets_colour() -> None:
    points = [(2.0, 1.5, 2.5), (2.0, -1.5, 2.5)]
    xs, _ = where(render_frame(Pose(), points, current=1), _TARGET)
    assert len(xs) > 20 and (xs < CX).all()  # the second one, west


# -- the environment -----------------------------------------------------------------------------
def test_an_unknown_render_mode_is_refused_in_one_line_before_anything_starts() -> None:
    # No firmware is looked up: the option is said as such on any machine.
    with pytest.raises(EnvironmentConfigError, match=r"^render_mode 'human' is not one") as caught:
        HoverEnv(render_mode="human")
    assert "\n" not in str(caught.value) and "'rgb_array'" in str(caught.value)
    with pytest.raises(EnvironmentConfigError, match="render_mode 'rgb'"):
        FlightVectorEnv("support.fake_flight_env:FakeFlightEnv", 2, render_mode="rgb")


def test_render_is_none_without_a_mode_and_the_truth_with_the_targets_with_one(
    tmp_path: Path,
) -> None:
    sitl = SitlLaunch(firmware=fake_lockstep_build(tmp_path))
    plain = HoverEnv(sitl=sitl)
    drawing = HoverEnv(sitl=sitl, render_mode="rgb_array", control_hz=50)
    try:
        assert plain.render_mode is None and plain.render() is None
        with pytest.raises(EnvironmentConfigError, match=r"render\(\) before reset\(\)"):
            drawing.render()
        # One frame a step: a recording plays at the simulated time's pace.
        assert drawing.metadata == {"render_modes": ["rgb_array"], "render_fps": 50}
        assert FlightEnv.metadata["render_fps"] == 100  # the class keeps the default
        drawing.task.reset(np.random.default_rng(3))
        drawing._snapshot = snapshot(north_m=0.4, roll_rad=0.3)
        frame = drawing.render()
        assert frame is not None and frame.shape == (HEIGHT, WIDTH, 3)
        expected = render_frame(drawing._snapshot.truth, drawing.task.targets)
        assert np.array_equal(frame, expected)
        # Gymnasium's own checks of a render: the declared modes and fps, the frame.
        from gymnasium.utils.passive_env_checker import env_render_passive_checker

        assert np.array_equal(env_render_passive_checker(drawing), frame)
    finally:
        plain.close()
        drawing.close()


def test_gymnasium_make_takes_the_mode_and_gives_the_control_rate_as_fps(tmp_path: Path) -> None:
    import bfsitl.gym  # noqa: F401 - registers the ids

    sitl = SitlLaunch(firmware=fake_lockstep_build(tmp_path))
    env = gymnasium.make("bfsitl/Hover-v0", sitl=sitl, render_mode="rgb_array", control_hz=25)
    try:
        assert env.render_mode == "rgb_array" and env.metadata["render_fps"] == 25
    finally:
        env.close()


class ScriptedHover(HoverEnv):
    """HoverEnv whose flight is a script (no SITL): it climbs north and rolls with the
    first stick; its render() is the real one."""

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        gymnasium.Env.reset(self, seed=seed)
        self.task.reset(self.np_random)
        self._steps = 0
        self._snapshot = snapshot(north_m=0.0, east_m=0.0, alt_m=1.5, roll_rad=0.0)
        return self._observe(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self._steps += 1
        assert self._snapshot is not None
        truth = replace(
            self._snapshot.truth,
            north_m=0.1 * self._steps,
            alt_m=1.5 + 0.05 * self._steps,
            roll_rad=0.5 * float(action[0]),
        )
        self._snapshot = replace(self._snapshot, truth=truth)
        return self._observe(), 0.0, False, self._steps >= 5, {}


def scripted(tmp_path: Path) -> ScriptedHover:
    return ScriptedHover(
        sitl=SitlLaunch(firmware=fake_lockstep_build(tmp_path)),
        render_mode="rgb_array",
        control_hz=40,
    )


def test_gymnasiums_render_collection_gets_a_new_frame_every_step(tmp_path: Path) -> None:
    env = gymnasium.wrappers.RenderCollection(scripted(tmp_path))
    try:
        env.reset(seed=1)
        for _ in range(3):
            env.step(np.array([0.5, 0, 0, 0], dtype=np.float32))
        frames = env.render()
        assert len(frames) == 4 and all(f.shape == (HEIGHT, WIDTH, 3) for f in frames)
        assert all(not np.array_equal(a, b) for a, b in zip(frames, frames[1:], strict=False))
    finally:
        env.close()


def test_record_video_takes_every_frame_at_the_control_rate(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # MoviePy only encodes what RecordVideo hands it: a stand-in keeps the frames, so the
    # wrapper's own path (triggers, fps, capture, save at the episode's end) runs here
    # whether MoviePy is installed or not.
    clips: list[tuple[list[np.ndarray], float, str]] = []

    class Clip:
        def __init__(self, frames: list[np.ndarray], fps: float) -> None:
            self.frames, self.fps = list(frames), fps

        def write_videofile(self, path: str, logger: object = None) -> None:
            clips.append((self.frames, self.fps, path))

    names = ("moviepy", "moviepy.video", "moviepy.video.io", "moviepy.video.io.ImageSequenceClip")
    for name in names:
        monkeypatch.setitem(sys.modules, name, ModuleType(name))
    sys.modules[names[-1]].ImageSequenceClip = Clip  # type: ignore[attr-defined]
    env = gymnasium.wrappers.RecordVideo(scripted(tmp_path), str(tmp_path / "videos"))
    env.reset(seed=2)
    for _ in range(5):
        env.step(np.zeros(4, dtype=np.float32))
    env.close()
    [(frames, fps, path)] = clips
    assert fps == 40 and path.endswith("rl-video-episode-0.mp4")
    assert len(frames) == 6 and all(f.shape == (HEIGHT, WIDTH, 3) for f in frames)
    assert all(f.dtype == np.uint8 for f in frames)


def test_record_video_writes_an_mp4_with_moviepy(tmp_path: Path) -> None:
    pytest.importorskip("moviepy")
    env = gymnasium.wrappers.RecordVideo(scripted(tmp_path), str(tmp_path / "videos"))
    env.reset(seed=2)
    for _ in range(5):
        env.step(np.zeros(4, dtype=np.float32))
    env.close()
    video = tmp_path / "videos" / "rl-video-episode-0.mp4"
    assert video.stat().st_size > 1000


# -- the vector environment ----------------------------------------------------------------------
class DrawingFakeEnv(FakeFlightEnv):
    """The vector tests' stand-in, drawing its own seed into its frames."""

    def __init__(self, *, render_mode: str | None = None, **options: Any) -> None:
        super().__init__(**options)
        self.render_mode = render_mode

    def render(self) -> np.ndarray | None:  # type: ignore[override]
        if self.render_mode is None:
            return None
        return np.full((4, 6, 3), self.seed_seen or 0, dtype=np.uint8)


def test_the_vector_environment_returns_each_workers_frame() -> None:
    # The workers are forked: this module is importable there as it is here.
    envs = FlightVectorEnv(f"{__name__}:DrawingFakeEnv", 2, render_mode="rgb_array")
    plain = FlightVectorEnv(f"{__name__}:DrawingFakeEnv", 2)
    try:
        assert envs.render_mode == "rgb_array" and envs.metadata["render_modes"] == ["rgb_array"]
        assert envs.metadata["render_fps"] == 100
        # Before a reset: refused in the parent, and the environments stay open.
        with pytest.raises(EnvironmentConfigError, match="before reset"):
            envs.render()
        envs.reset(seed=[7, 9])
        frames = envs.render()
        assert frames is not None and [f[0, 0, 0] for f in frames] == [7, 9]
        observations, rewards, *_ = envs.step(np.full((2, 4), 0.25, dtype=np.float32))
        assert rewards.tolist() == [0.25, 0.25]  # a render leaves the steps' numbers alone
        assert observations[:, 0].tolist() == [1.0, 1.0]
        plain.reset()
        assert plain.render_mode is None and plain.render() is None
    finally:
        envs.close()
        plain.close()
