"""The session's and the gym environments' options, grouped by what they configure: every
option the flat forms had has one place in the groups, no group field is left without an old
option or a reason, and the groups travel to workers and actors (pickled)."""

from __future__ import annotations

import dataclasses
import inspect
import pickle
from typing import Any

import pytest

from bfsitl.backend.options import Timing, World
from bfsitl.errors import BfsitlError
from bfsitl.mission.session import (
    ConfiguratorBridge,
    FcSetup,
    FlightSession,
    SessionConfig,
    SitlLaunch,
)

#: SessionConfig's flat fields before the groups -> where each went.
SESSION_FIELDS = {
    "firmware": "sitl.firmware",
    "workdir": "sitl.workdir",
    "isolate": "sitl.isolate",
    "speed": "timing.speed",
    "lockstep": "timing.lockstep",
    "lockstep_spin": "timing.lockstep_spin",
    "lockstep_exchange": "timing.lockstep_exchange",
    "profile": "fc.profile",
    "angle_mode": "fc.angle_mode",
    "arm_timeout_s": "fc.arm_timeout_s",
    "rc_link": "fc.rc_link",
    "physics": "world.physics",
    "gz_plugin_dir": "world.gz_plugin_dir",
    "quad": "world.quad",
    "wind": "world.wind",
    "sensors": "world.sensors",
    "seed": "world.seed",
    "initial_heading_deg": "world.initial_heading_deg",
    "configurator_port": "configurator.port",
    "allow_origins": "configurator.allow_origins",
}
#: Group fields that came after the groups, with no flat field before them.
NEW_TO_THE_SESSION = {"sitl.env", "fc.attachable", "world.gz_world", "fc.rc_rate_hz"}
#: The gym environment's flat options before the groups -> where each went (the wind's speed,
#: direction and gusts are one Wind now, as the session's are).
ENV_OPTIONS = {
    "firmware": "sitl.firmware",
    "workdir": "sitl.workdir",
    "wind": "world.wind",
    "wind_from_deg": "world.wind",
    "gusts": "world.wind",
    "spin": "timing.lockstep_spin",
    "lockstep_exchange": "timing.lockstep_exchange",
    **{
        name: name
        for name in (
            "control_hz",
            "mode",
            "observation",
            "disturbances",
            "max_episode_steps",
            "start",
            "start_alt_m",
            "pin_core",
            "warm_resets",
            "render_mode",
        )
    },
}
#: The environment's own options that came after the groups (none of a group's meaning).
ADDED_TO_THE_ENV = {"latency", "rc_frame_per_step", "rc_rate_hz", "random_wind", "random_vehicle"}
#: Group fields the environment had no option for before: the session's meaning, new to it.
NEW_TO_THE_ENV = {
    "sitl.isolate",
    "sitl.env",
    "timing.speed",
    "timing.lockstep",
    "world.physics",
    "world.gz_plugin_dir",
    "world.gz_world",
    "world.quad",
    "world.sensors",
    "world.seed",
    "world.initial_heading_deg",
}

GROUPS: dict[str, type] = {
    "sitl": SitlLaunch,
    "timing": Timing,
    "fc": FcSetup,
    "world": World,
    "configurator": ConfiguratorBridge,
}


def leaves(groups: dict[str, type]) -> list[str]:
    return [
        f"{name}.{field.name}"
        for name, group in groups.items()
        for field in dataclasses.fields(group)
    ]


def test_every_session_field_has_one_place_in_the_groups() -> None:
    assert {field.name: field.type for field in dataclasses.fields(SessionConfig)} == {
        "sitl": "SitlLaunch",
        "timing": "Timing",
        "fc": "FcSetup",
        "world": "World",
        "configurator": "ConfiguratorBridge | None",
    }
    places = leaves(GROUPS)
    assert len(places) == len(set(places))
    # Each old field went to one place, and each place holds one old field: none lost, none
    # doubled, none invented.
    assert sorted([*SESSION_FIELDS.values(), *NEW_TO_THE_SESSION]) == sorted(places)


def test_the_groups_have_defaults_and_are_frozen_and_picklable() -> None:
    config = SessionConfig()
    assert config.configurator is None and config.world.seed == 0
    assert config.fc.profile is not None and config.timing.lockstep_spin is None
    seeded = SessionConfig(world=World(seed=3))
    assert seeded.world.seed == 3 and seeded.sitl == SitlLaunch()
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.world.seed = 1  # type: ignore[misc]
    full = SessionConfig(configurator=ConfiguratorBridge(port=0, allow_origins=("x",)))
    # Vector environments' workers and Ray actors get their options pickled.
    assert pickle.loads(pickle.dumps(full)) == full


def test_the_old_flat_fields_are_gone() -> None:
    with pytest.raises(TypeError, match="speed"):
        SessionConfig(speed=2.0)  # type: ignore[call-arg]
    assert not hasattr(SessionConfig(), "seed")


def test_for_autopilot_sets_the_serial_rate_on_the_profile_it_is_given() -> None:
    fast = SessionConfig.for_autopilot(control_rate_hz=200.0, world=World(seed=4))
    assert fast.world.seed == 4 and fast.fc.profile is not None
    assert "set serial_update_rate_hz = 1000" in fast.fc.profile.cli_lines
    slow = SessionConfig.for_autopilot(control_rate_hz=25.0)
    assert slow.fc == FcSetup()
    assert SessionConfig.for_autopilot(fc=FcSetup(profile=None)).fc.profile is None
    with pytest.raises(TypeError, match="seed"):
        SessionConfig.for_autopilot(seed=4)


@pytest.mark.parametrize(
    ("config", "fix"),
    [
        (SessionConfig(timing=Timing(speed=-1.0)), "speed -1.0 must be a positive number"),
        (
            SessionConfig(configurator=ConfiguratorBridge(), fc=FcSetup(profile=None)),
            "the Configurator bridge needs provisioning",
        ),
        (
            SessionConfig(fc=FcSetup(profile=None, attachable=True)),
            "an attachable flight needs provisioning",
        ),
    ],
)
def test_a_wrong_value_in_a_group_is_refused_when_the_session_is_made(
    config: SessionConfig, fix: str
) -> None:
    with pytest.raises(BfsitlError, match=fix):
        FlightSession(config)


def test_every_environment_option_has_one_place_in_the_groups_or_its_own() -> None:
    pytest.importorskip("gymnasium")
    from bfsitl.gym.env import FlightEnv

    keywords = [
        name
        for name, parameter in inspect.signature(FlightEnv).parameters.items()
        if parameter.kind is inspect.Parameter.KEYWORD_ONLY
    ]
    env_groups = {"sitl": SitlLaunch, "timing": Timing, "world": World}
    # The session's groups where they mean the same, then the environment's own options.
    assert keywords[:3] == list(env_groups)
    own = keywords[3:]
    places = set(ENV_OPTIONS.values())
    assert places <= set(leaves(env_groups)) | set(own)
    # No option of its own that did not exist before, but those said to be new.
    assert set(own) <= places | ADDED_TO_THE_ENV
    assert not ADDED_TO_THE_ENV & set(leaves(env_groups))
    assert places | ADDED_TO_THE_ENV | NEW_TO_THE_ENV == set(leaves(env_groups)) | set(own)
    assert not places & NEW_TO_THE_ENV


@pytest.mark.parametrize(
    ("options", "fix"),
    [
        (
            {"timing": Timing(lockstep_exchange="pigeon")},  # type: ignore[arg-type]
            "timing.lockstep_exchange must be one of auto, shm, udp, not 'pigeon'",
        ),
        ({"timing": "udp"}, "timing must be a Timing"),
        ({"world": {"seed": 3}}, "world must be a World"),
        ({"sitl": None}, "sitl must be a SitlLaunch"),
    ],
)
def test_a_wrong_type_in_an_environment_group_is_said_with_what_it_takes(
    options: dict[str, Any], fix: str
) -> None:
    pytest.importorskip("gymnasium")
    from bfsitl.errors import EnvironmentConfigError
    from bfsitl.gym.env import HoverEnv

    with pytest.raises(EnvironmentConfigError, match=fix):
        HoverEnv(**options)
