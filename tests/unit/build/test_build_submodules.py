"""Submodules master's Makefile would fetch by itself: stamped in the build copy so that a
tree without them (a source archive, a shallow clone) builds the SITL offline."""

from __future__ import annotations

from pathlib import Path

from bfsitl.build.submodules import auto_hydrated_submodules, stamp_missing_submodules

# The shape of master's .gitmodules (2026.12): two fetched by every build, the SDKs opt-in.
GITMODULES = """\
[submodule "config"]
\tpath = src/config
\turl = https://example.invalid/config.git
\tbranch = master
[submodule "lib/modules/pico-sdk"]
\tpath = lib/modules/pico-sdk
\tupdate = none
[submodule "lib/modules/dronecan/libcanard"]
\tpath = lib/modules/dronecan/libcanard
\turl = https://example.invalid/libcanard.git
[submodule "escape"]
\tpath = ../outside
"""
HYDRATING_MAKEFILE = '$(STAMPS):\n\tgit submodule update --init -- "$(@:/.git=)"\n'


def tree_with(tmp_path: Path, makefile: str) -> Path:
    tree = tmp_path / "tree"
    tree.mkdir()
    (tree / "Makefile").write_text(makefile)
    (tree / ".gitmodules").write_text(GITMODULES)
    return tree


def test_the_submodules_make_would_fetch_are_those_not_marked_update_none() -> None:
    assert auto_hydrated_submodules(GITMODULES) == [
        "src/config",
        "lib/modules/dronecan/libcanard",
        "../outside",
    ]
    assert auto_hydrated_submodules("") == []
    assert auto_hydrated_submodules("garbage\n[submodule broken\npath = x\n") == []


def test_missing_ones_get_a_stamp_and_the_user_is_told(tmp_path: Path) -> None:
    tree = tree_with(tmp_path, HYDRATING_MAKEFILE)
    (tree / "src" / "config").mkdir(parents=True)
    notes: list[str] = []
    stamped = stamp_missing_submodules(tree, notes.append)
    assert stamped == ["src/config", "lib/modules/dronecan/libcanard"]
    assert (tree / "src/config/.git").is_file()
    assert (tree / "lib/modules/dronecan/libcanard/.git").is_file()
    assert not (tmp_path / "outside").exists()  # never outside the tree
    assert not (tree / "lib/modules/pico-sdk").exists()  # opt-in SDKs are left alone
    assert notes == [
        "not fetching submodules src/config, lib/modules/dronecan/libcanard: the "
        "SITL build does not compile them"
    ]


def test_a_checked_out_submodule_and_a_makefile_that_fetches_nothing_are_left_alone(
    tmp_path: Path,
) -> None:
    tree = tree_with(tmp_path, HYDRATING_MAKEFILE)
    (tree / "src/config").mkdir(parents=True)
    (tree / "src/config/.git").write_text("gitdir: ../../.git/modules/config\n")
    assert stamp_missing_submodules(tree, lambda _n: None) == ["lib/modules/dronecan/libcanard"]
    assert (tree / "src/config/.git").read_text().startswith("gitdir:")

    plain = tmp_path / "plain"
    plain.mkdir()
    (plain / "Makefile").write_text("all:\n\techo 4.6 hydrates nothing\n")
    (plain / ".gitmodules").write_text(GITMODULES)
    assert stamp_missing_submodules(plain, lambda _n: None) == []
    assert not (plain / "src").exists()
