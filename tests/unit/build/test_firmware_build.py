"""`bfsitl firmware build` with fakes: a tiny source tree and a fake `make` on PATH.

The fake make behaves like Betaflight's where it matters: it prints a `%% (optimised) file.c`
line per file (and `echo "%% ..."` lines for `make -n`), then writes
`obj/betaflight_<version>_SITL` whose bytes hold the CLI setting names of the features its
EXTRA_FLAGS turned on.  Environment variables steer it: FAKE_MAKE_FAIL, FAKE_MAKE_SLEEP,
FAKE_MAKE_IP (write master's usage text), FAKE_MAKE_GPS=yes (GPS without -DUSE_GPS, as
master's SITL), FAKE_MAKE_LOG (append each invocation).
"""

from __future__ import annotations

import io
import os
import tarfile
import threading
import time
from pathlib import Path

import pytest

from bfsitl.build import (
    BuildProgress,
    FirmwareBuildOptions,
    FirmwareCache,
    binary_traits,
    build_firmware,
    metadata_for_binary,
)
from bfsitl.build.binary_scan import clear_cache
from bfsitl.build.features import header_defines
from bfsitl.build.fingerprint import fingerprint_tree
from bfsitl.build.source_tree import read_version, revision_from_name
from bfsitl.cli.main import main
from bfsitl.errors import (
    BuildToolMissingError,
    FirmwareBuildError,
    FirmwareNotFoundError,
    FirmwareSourceError,
)
from bfsitl.sitl.firmware import FirmwareBinary, find_firmware

FAKE_MAKE = r"""#!/bin/sh
dry=0; flags=""
for arg in "$@"; do
  case "$arg" in
    -n) dry=1 ;;
    EXTRA_FLAGS=*) flags="${arg#EXTRA_FLAGS=}" ;;
  esac
done
[ -n "$FAKE_MAKE_LOG" ] && echo "$*" >> "$FAKE_MAKE_LOG"
if [ "$dry" = 1 ]; then
  for i in 0 1 2 3 4 5 6 7 8 9; do echo "echo \"%% (optimised) src/f$i.c\" && gcc -c f$i.c"; done
  exit 2
fi
echo "%% (optimised) src/f0.c"
if [ -n "$FAKE_MAKE_SLEEP" ]; then
  # Written whole or not at all: the test reads it as soon as it exists.
  echo $$ > "$FAKE_MAKE_PIDFILE.part" && mv "$FAKE_MAKE_PIDFILE.part" "$FAKE_MAKE_PIDFILE"
  sleep "$FAKE_MAKE_SLEEP"
fi
if [ -n "$FAKE_MAKE_FAIL" ]; then
  for i in 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25; do
    echo "noise line $i"
  done
  echo "src/main/fc/core.c:12:5: error: 'bogus' undeclared (first use in this function)"
  echo "make: *** [Makefile:1: core.o] Error 1"
  exit 2
fi
for i in 1 2 3 4 5 6 7 8 9; do echo "%% (optimised) src/f$i.c"; done
mkdir -p obj/main
out=obj/betaflight_9.9.0_SITL
printf 'ELF fake sitl\000settings\000' > "$out"
case "$flags$FAKE_MAKE_GPS" in
  *-DUSE_GPS*|*yes) printf 'gps_provider\000gps_rescue_x\000' >> "$out" ;;
esac
case "$flags" in *-DUSE_ALTITUDE_HOLD*) printf 'alt_hold_x\000' >> "$out" ;; esac
[ -n "$FAKE_MAKE_IP" ] && printf -- '  --ip <address>  Simulator IP\000' >> "$out"
chmod +x "$out"
exit 0
"""

TARGET_46 = """
#define USE_ACC
#define USE_VIRTUAL_ACC
#ifdef USE_GPS
#define USE_VIRTUAL_GPS
#endif
#if 0
#define USE_POSITION_HOLD
#endif
"""
TARGET_MASTER = """
#define USE_ACC
#define USE_GPS
#define USE_VIRTUAL_GPS
#define USE_ALTITUDE_HOLD
#define USE_POSITION_HOLD
"""
COMMON_PRE = """
#if !defined(CLOUD_BUILD) && !defined(SITL)
#define USE_GPS
#define USE_ALTITUDE_HOLD
#endif
#ifdef USE_GPS
#define USE_GPS_RESCUE
#endif
"""
CODE = (
    "#ifdef USE_GPS\n#ifdef USE_VIRTUAL_GPS\n#endif\n#endif\n"
    "#ifdef USE_ALTITUDE_HOLD\n#endif\n#ifdef USE_POSITION_HOLD\n#endif\n"
    "#ifdef USE_GPS_RESCUE\n#endif\n"
)


def make_tree(root: Path, *, master: bool = False) -> Path:
    """A Betaflight-shaped tree: just what the build code reads."""
    files = {
        "Makefile": "all:\n",
        "mk/tools.mk": "CC := gcc\n",
        "lib/main/dyad/dyad.c": "int dyad;\n",
        "src/main/msp/msp_protocol.h": "#define API_VERSION_MAJOR 1\n#define API_VERSION_MINOR "
        + ("49\n" if master else "47\n"),
        "src/main/target/common_pre.h": COMMON_PRE,
        "src/main/target/common_post.h": "",
        "src/main/io/gps.c": CODE,
        "src/platform/SIMULATOR/target/SITL/target.h": TARGET_MASTER if master else TARGET_46,
        "docs/readme.md": "not source\n",
        "obj/old.o": "a stale object from an earlier in-tree build\n",
    }
    if master:
        files["src/main/build/version.h"] = (
            "#define FC_VERSION_YEAR 2026 // the year\n#define FC_VERSION_MONTH 12\n"
            '#define FC_VERSION_PATCH_LEVEL 0\n#define FC_VERSION_SUFFIX "alpha"\n'
        )
    else:
        files["src/main/build/version.h"] = (
            "#define FC_VERSION_MAJOR            4  // increment when ...\n"
            "#define FC_VERSION_MINOR 6\n#define FC_VERSION_PATCH_LEVEL 0\n"
        )
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


@pytest.fixture
def fake_bin(tmp_path: Path) -> Path:
    directory = tmp_path / "fakebin"
    directory.mkdir()
    (directory / "make").write_text(FAKE_MAKE)
    (directory / "make").chmod(0o755)
    (directory / "gcc").write_text("#!/bin/sh\nexit 0\n")
    (directory / "gcc").chmod(0o755)
    return directory


@pytest.fixture
def env(tmp_path: Path, fake_bin: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    """os.environ with the fake tools first on PATH and a private cache."""
    monkeypatch.setenv("PATH", f"{fake_bin}{os.pathsep}/usr/bin{os.pathsep}/bin")
    monkeypatch.setenv("BFSITL_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("FAKE_MAKE_LOG", str(tmp_path / "make.log"))
    for name in (
        "FAKE_MAKE_FAIL",
        "FAKE_MAKE_SLEEP",
        "FAKE_MAKE_IP",
        "FAKE_MAKE_GPS",
        "BFSITL_FIRMWARE",
    ):
        monkeypatch.delenv(name, raising=False)
    return dict(os.environ)


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    return make_tree(tmp_path / "betaflight-4.6.0")


def make_runs(tmp_path: Path) -> list[str]:
    """The real (not dry-run) make invocations so far."""
    log = tmp_path / "make.log"
    lines = log.read_text().splitlines() if log.exists() else []
    return [line for line in lines if " -n " not in f" {line} "]


def cache_of(env: dict[str, str]) -> FirmwareCache:
    return FirmwareCache(environ=env)


# --- building and the cache -----------------------------------------------------------------


def test_build_then_cached(tree: Path, env: dict[str, str], tmp_path: Path) -> None:
    first = build_firmware(tree, environ=env)
    assert not first.cached
    assert first.name == "4.6.0"
    assert first.binary_path.is_file() and os.access(first.binary_path, os.X_OK)
    assert first.binary_path.parent.parent == Path(env["BFSITL_CACHE_DIR"]) / "builds"
    second = build_firmware(tree, environ=env)
    assert second.cached
    assert second.binary_path == first.binary_path
    assert len(make_runs(tmp_path)) == 1
    # Only the binary and its record are kept; the copy and tmp/ are gone.
    assert sorted(p.name for p in first.binary_path.parent.iterdir()) == [
        "betaflight_9.9.0_SITL",
        "build.json",
    ]
    assert list((Path(env["BFSITL_CACHE_DIR"]) / "tmp").iterdir()) == []


def test_source_tree_is_never_written(tree: Path, env: dict[str, str]) -> None:
    before = {p: p.stat().st_mtime_ns for p in tree.rglob("*")}
    build_firmware(tree, FirmwareBuildOptions(gps=True), environ=env)
    after = {p: p.stat().st_mtime_ns for p in tree.rglob("*")}
    assert after == before  # no obj/ output, nothing touched


def test_copy_leaves_out_obj_git_and_docs(
    tree: Path, env: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    (tree / ".git").mkdir()
    (tree / ".git" / "HEAD").write_text("0123456789abcdef0123456789abcdef01234567\n")
    seen: list[set[str]] = []
    import bfsitl.build.builder as builder

    real_run_make = builder.run_make

    def spy(args, *, cwd, **kwargs):  # type: ignore[no-untyped-def]
        seen.append({p.name for p in cwd.iterdir()})
        return real_run_make(args, cwd=cwd, **kwargs)

    monkeypatch.setattr(builder, "run_make", spy)
    result = build_firmware(tree, environ=env)
    assert seen and not ({"obj", ".git", "docs"} & seen[0])
    assert {"Makefile", "src", "lib", "mk"} <= seen[0]
    # The checkout's revision is known, passed to make and kept in the name and record.
    assert result.metadata.git_revision == "0123456"
    assert "REVISION=0123456" in result.metadata.make_command
    assert result.name == "4.6.0-0123456"


def test_metadata_beside_the_binary(tree: Path, env: dict[str, str]) -> None:
    result = build_firmware(tree, FirmwareBuildOptions(gps=True, defines=("FOO=2",)), environ=env)
    meta = metadata_for_binary(result.binary_path)
    assert meta is not None
    assert meta.name == "4.6.0-gps+FOO-2"
    assert (meta.firmware_version, meta.msp_api_version) == ("4.6.0", "1.47")
    assert meta.defines == ("FOO=2",)
    assert meta.make_defines == ("FOO=2", "USE_ALTITUDE_HOLD", "USE_GPS", "USE_POSITION_HOLD")
    assert meta.gps and meta.gps_requested
    assert meta.features == ("gps", "gps_rescue", "altitude_hold")
    assert meta.source_kind == "directory" and meta.source_path == str(tree)
    assert meta.takes_ip_flag is False
    assert meta.binary_path == result.binary_path
    assert meta.compiled_files == 10
    assert metadata_for_binary(tree / "Makefile") is None


def test_key_is_stable_and_sensitive(tree: Path, env: dict[str, str], tmp_path: Path) -> None:
    def key(options: FirmwareBuildOptions, source: Path = tree) -> str:
        return build_firmware(source, options, environ=env).entry.key

    base = key(FirmwareBuildOptions(defines=("A", "B=1")))
    assert key(FirmwareBuildOptions(defines=("-DB=1", "A"))) == base  # order, -D prefix
    assert key(FirmwareBuildOptions(defines=("A", "B=2"))) != base
    assert key(FirmwareBuildOptions(defines=("A", "B=1"), gps=True)) != base
    copy = make_tree(tmp_path / "elsewhere" / "betaflight-4.6.0")
    assert key(FirmwareBuildOptions(defines=("A", "B=1")), copy) == base  # content, not place
    (copy / "src" / "main" / "io" / "gps.c").write_text(CODE + "int changed;\n")
    assert key(FirmwareBuildOptions(defines=("A", "B=1")), copy) != base


def test_fingerprint_ignores_obj_git_docs_and_uses_its_memo(
    tree: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    memo = tmp_path / "memo"
    first = fingerprint_tree(tree, memo)
    (tree / "obj" / "new.o").write_text("x")
    (tree / "docs" / "more.md").write_text("x")
    import bfsitl.build.fingerprint as fingerprint

    reads: list[str] = []
    real = fingerprint._digest
    monkeypatch.setattr(fingerprint, "_digest", lambda p, i: reads.append(p) or real(p, i))
    # Files changed in the last seconds are never remembered (a change within the same
    # timestamp tick would not show); these were all written just now.
    assert fingerprint_tree(tree, memo) == first
    assert reads
    reads.clear()
    monkeypatch.setattr(fingerprint, "_RACY_WINDOW_S", -1.0)
    assert fingerprint_tree(tree, memo) == first
    reads.clear()
    assert fingerprint_tree(tree, memo) == first
    assert reads == []  # every file known by its stat
    (tree / "src" / "main" / "io" / "gps.c").write_text(CODE + "/* changed */\n")
    assert fingerprint_tree(tree, memo) != first
    assert [Path(p).name for p in reads] == ["gps.c"]


def test_failure_leaves_no_entry_and_explains(
    tree: Path, env: dict[str, str], tmp_path: Path
) -> None:
    env["FAKE_MAKE_FAIL"] = "1"
    with pytest.raises(FirmwareBuildError) as caught:
        build_firmware(tree, environ=env)
    message = str(caught.value)
    assert "exit code 2" in message
    assert "error: 'bogus' undeclared" in message.splitlines()[0]  # the cause comes first
    assert "noise line 8" in message and "noise line 7" not in message  # the last 20 lines
    cache = Path(env["BFSITL_CACHE_DIR"])
    assert not (cache / "builds").exists() or list((cache / "builds").iterdir()) == []
    assert list((cache / "tmp").iterdir()) == []
    assert cache_of(env).entries() == []


class InterruptingProgress(BuildProgress):
    """Ctrl-C arrives while make runs (after its first compiled file)."""

    def __init__(self, pidfile: Path) -> None:
        super().__init__(stream=None)
        self.pidfile = pidfile

    def compiled(self, count: int) -> None:
        deadline = time.monotonic() + 5
        while not self.pidfile.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        raise KeyboardInterrupt


def test_interrupt_kills_make_and_leaves_nothing(
    tree: Path, env: dict[str, str], tmp_path: Path
) -> None:
    pidfile = tmp_path / "make.pid"
    env.update(FAKE_MAKE_SLEEP="30", FAKE_MAKE_PIDFILE=str(pidfile))
    started = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        build_firmware(tree, environ=env, progress=InterruptingProgress(pidfile))
    assert time.monotonic() - started < 5
    pid = int(pidfile.read_text())
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # make (and its sleep) are gone, reaped
    cache = Path(env["BFSITL_CACHE_DIR"])
    assert list((cache / "tmp").iterdir()) == []
    assert cache_of(env).entries() == []


def test_concurrent_builds_of_one_key_build_once(
    tree: Path, env: dict[str, str], tmp_path: Path
) -> None:
    env["FAKE_MAKE_SLEEP"] = "0.3"
    env["FAKE_MAKE_PIDFILE"] = str(tmp_path / "pid")
    results = []
    notes: list[str] = []

    class Notes(BuildProgress):
        def note(self, message: str) -> None:
            notes.append(message)

    def run() -> None:
        results.append(build_firmware(tree, environ=env, progress=Notes(stream=None)))

    threads = [threading.Thread(target=run) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(10)
    assert sorted(r.cached for r in results) == [False, True]
    assert len(make_runs(tmp_path)) == 1
    assert any("is building the same firmware; waiting" in n for n in notes)


def test_missing_gcc_names_the_package(tree: Path, env: dict[str, str], fake_bin: Path) -> None:
    (fake_bin / "gcc").unlink()
    env["PATH"] = str(fake_bin)  # make only
    with pytest.raises(BuildToolMissingError) as caught:
        build_firmware(tree, environ=env)
    assert "gcc not found" in str(caught.value)
    assert "apt-get install gcc make" in str(caught.value)


def test_missing_compiler_seen_by_make_names_the_package(
    tree: Path, env: dict[str, str], fake_bin: Path
) -> None:
    (fake_bin / "make").write_text(
        "#!/bin/sh\necho 'make: gcc: No such file or directory'\n"
        "echo 'make: *** [x.o] Error 127'\nexit 2\n"
    )
    with pytest.raises(BuildToolMissingError, match="apt-get install gcc make"):
        build_firmware(tree, environ=env)


def test_name_moves_to_the_newer_build(tree: Path, env: dict[str, str]) -> None:
    old = build_firmware(tree, environ=env)
    (tree / "src" / "main" / "io" / "gps.c").write_text(CODE + "int v2;\n")
    new = build_firmware(tree, environ=env)
    assert new.name == old.name == "4.6.0"
    assert new.displaced_key == old.entry.key
    cache = cache_of(env)
    assert cache.resolve("4.6.0").key == new.entry.key  # type: ignore[union-attr]
    assert cache.resolve(old.entry.key[:8]).key == old.entry.key  # type: ignore[union-attr]
    assert sorted(e.label for e in cache.entries()) == sorted(["4.6.0", old.entry.key[:12]])


def test_explicit_name_and_bad_names(tree: Path, env: dict[str, str]) -> None:
    result = build_firmware(tree, name="mine", environ=env)
    assert cache_of(env).resolve("mine").binary_path == result.binary_path  # type: ignore
    with pytest.raises(FirmwareBuildError, match="bad build name"):
        build_firmware(tree, name="../escape", environ=env)


# --- what --gps means per tree --------------------------------------------------------------


def test_gps_on_a_46_tree_adds_the_defines(tree: Path, env: dict[str, str]) -> None:
    result = build_firmware(tree, FirmwareBuildOptions(gps=True), environ=env)
    assert result.name == "4.6.0-gps"
    plan = result.plan
    assert plan.gps is not None
    # USE_VIRTUAL_GPS and USE_GPS_RESCUE follow from USE_GPS in the headers: never added.
    assert plan.make_defines == ("USE_ALTITUDE_HOLD", "USE_GPS", "USE_POSITION_HOLD")
    assert set(plan.gps.present) == {"USE_VIRTUAL_GPS", "USE_GPS_RESCUE"}
    assert result.metadata.gps


def test_gps_on_a_master_tree_changes_nothing(tmp_path: Path, env: dict[str, str]) -> None:
    master = make_tree(tmp_path / "betaflight-2026.12.0-alpha-301d01a", master=True)
    env.update(FAKE_MAKE_IP="1", FAKE_MAKE_GPS="yes")
    plain = build_firmware(master, environ=env)
    with_gps = build_firmware(master, FirmwareBuildOptions(gps=True), environ=env)
    assert with_gps.cached and with_gps.entry.key == plain.entry.key
    assert plain.name == "2026.12.0-alpha-301d01a"
    assert with_gps.plan.make_defines == ()
    assert plain.metadata.takes_ip_flag is True
    assert plain.metadata.git_revision == "301d01a"


def test_a_gps_build_without_gps_in_the_binary_fails(
    tree: Path, env: dict[str, str], fake_bin: Path
) -> None:
    script = (fake_bin / "make").read_text().replace("*-DUSE_GPS*|*yes)", "*NEVER*)")
    (fake_bin / "make").write_text(script)
    with pytest.raises(FirmwareBuildError, match="has no GPS"):
        build_firmware(tree, FirmwareBuildOptions(gps=True), environ=env)
    assert cache_of(env).entries() == []


def test_header_defines_follow_guards_and_conditions() -> None:
    text = """
#define TOP
#ifdef USE_GPS
#define UNDER_GPS
#if !defined(UNDER_GPS_GUARDED) && defined(USE_ACC)
#define UNDER_GPS_GUARDED
#endif
#else
#define NO_GPS
#endif
#if defined(A) || defined(B)
#define UNKNOWN
#endif
/* #define COMMENTED */
"""
    found = header_defines(text, frozenset({"USE_ACC"}))
    assert found.unconditional == {"TOP"}
    assert found.under_gps == {"UNDER_GPS", "UNDER_GPS_GUARDED"}


def test_versions_of_both_schemes(tmp_path: Path) -> None:
    assert read_version(make_tree(tmp_path / "a")).firmware == "4.6.0"
    master = read_version(make_tree(tmp_path / "b", master=True))
    assert (master.firmware, master.msp_api) == ("2026.12.0-alpha", "1.49")
    assert revision_from_name("betaflight-2026.12.0-alpha-301d01a") == "301d01a"
    assert revision_from_name("betaflight-4.6.0") is None


def test_not_a_tree_is_refused(tmp_path: Path, env: dict[str, str]) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(FirmwareSourceError, match="not a Betaflight source tree"):
        build_firmware(tmp_path / "empty", environ=env)


# --- tarballs -------------------------------------------------------------------------------


def make_tarball(tree: Path, path: Path) -> Path:
    with tarfile.open(path, "w:gz") as archive:
        archive.add(tree, arcname=tree.name)
    return path


def test_tarball_builds_like_its_tree_and_is_not_unpacked_twice(
    tmp_path: Path, env: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    master = make_tree(tmp_path / "betaflight-2026.12.0-alpha-301d01a", master=True)
    tarball = make_tarball(master, tmp_path / "src.tar.gz")
    env["FAKE_MAKE_GPS"] = "yes"
    first = build_firmware(tarball, environ=env)
    assert first.name == "2026.12.0-alpha-301d01a"
    assert first.metadata.source_kind == "tarball"
    import bfsitl.build.source_facts as source_facts

    monkeypatch.setattr(source_facts, "unpack", lambda *a: pytest.fail("unpacked again"))
    assert build_firmware(tarball, environ=env).cached
    # Same content as the tree it came from (obj/ and docs/ left out): same build.
    monkeypatch.undo()
    assert build_firmware(master, environ=env).entry.key == first.entry.key


@pytest.mark.parametrize("member", ["../evil.c", "/etc/evil.c"])
def test_unsafe_tarball_is_refused(tmp_path: Path, env: dict[str, str], member: str) -> None:
    tarball = tmp_path / "bad.tar.gz"
    with tarfile.open(tarball, "w:gz") as archive:
        data = b"int x;\n"
        info = tarfile.TarInfo(member)
        info.size = len(data)
        archive.addfile(info, io.BytesIO(data))
    with pytest.raises(FirmwareSourceError, match="outside"):
        build_firmware(tarball, environ=env)
    assert not (tmp_path / "evil.c").exists()


# --- progress and the command line ----------------------------------------------------------


def test_plain_progress_without_a_total_ends_with_the_count() -> None:
    out = io.StringIO()
    progress = BuildProgress(stream=out, live=False)
    for count in range(1, 61):
        progress.compiled(count)
    progress.finish()
    assert out.getvalue().splitlines() == ["bfsitl: compiled 50 files", "bfsitl: compiled 60 files"]


def test_plain_progress_is_a_line_per_ten_percent() -> None:
    out = io.StringIO()
    progress = BuildProgress(stream=out, live=False)
    progress.set_total(40)
    for count in range(1, 41):
        progress.compiled(count)
    progress.finish()
    lines = out.getvalue().splitlines()
    assert lines[0] == "bfsitl: compiled 4/40 files (10 %)"
    assert lines[-1] == "bfsitl: compiled 40/40 files (100 %)"
    assert len(lines) == 10 and "\r" not in out.getvalue()


def test_live_progress_redraws_one_line() -> None:
    out = io.StringIO()
    progress = BuildProgress(stream=out, live=True)
    progress.compiled(1)
    progress.set_total(3)
    progress.compiled(3)
    progress.note("linking")
    text = out.getvalue()
    assert text.startswith("\rbfsitl: compiling 1 files")
    assert text.endswith("\nbfsitl: linking\n")


def test_cli_build_prints_the_path_last(
    tree: Path, env: dict[str, str], capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["firmware", "build", "--source", str(tree), "--gps", "-j", "2"]) == 0
    out, err = capsys.readouterr()
    path = Path(out.strip().splitlines()[-1])
    assert path.is_absolute() and path.is_file()
    # 10/10 when make's dry run counted first, else the plain final count.
    assert "bfsitl: compiled 10/10 files (100 %)" in err or "bfsitl: compiled 10 files" in err
    assert "built 4.6.0-gps" in err
    assert main(["firmware", "build", "--source", str(tree), "--gps"]) == 0
    out, err = capsys.readouterr()
    assert out.strip().splitlines()[-1] == str(path)
    assert "cached: 4.6.0-gps" in err


def test_cli_build_failure_is_exit_1_with_the_cause(
    tree: Path,
    env: dict[str, str],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("FAKE_MAKE_FAIL", "1")
    assert main(["firmware", "build", "--source", str(tree)]) == 1
    out, err = capsys.readouterr()
    assert out == ""
    assert "error: 'bogus' undeclared" in err


def test_cli_list_info_clean(
    tree: Path, env: dict[str, str], capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    build_firmware(tree, FirmwareBuildOptions(gps=True), environ=env)
    assert main(["firmware", "list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    mine = [r for r in rows if r["source"] == "cache"]
    assert [(r["name"], r["firmware_version"], r["options"], r["gps"]) for r in mine] == [
        ("4.6.0-gps", "4.6.0", "gps", True)
    ]
    assert main(["firmware", "info", "4.6.0-gps", "--no-probe", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["build"]["name"] == "4.6.0-gps" and info["probe"] is None
    assert info["binary"] == {
        "takes_ip_flag": False,
        "features": ["gps", "gps_rescue", "altitude_hold"],
    }
    # A configuration prepared for the build (a scenario run's) goes with it.
    from bfsitl.fc.provisioning import Profile
    from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE
    from bfsitl.scenario.prepared_fc import EEPROM_NAME, prepared_eeprom

    cache = cache_of(env)
    state = prepared_eeprom(
        cache.entries()[0].binary_path,
        DEFAULT_PROFILE,
        Profile(),
        lambda run_dir: (run_dir / EEPROM_NAME).write_bytes(b"configured"),
        cache=cache.root,
    )
    assert state is not None and state.is_file()
    assert main(["firmware", "clean", "4.6.0-gps"]) == 0
    assert cache.entries() == []
    assert not state.exists()


def test_a_second_name_is_said_when_given_and_listed_beside_the_first(
    tree: Path, env: dict[str, str], capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    assert main(["firmware", "build", "--source", str(tree), "--gps"]) == 0
    capsys.readouterr()
    # The same build again under a name of the user's: nothing compiles, the name is said.
    assert main(["firmware", "build", "--source", str(tree), "--gps", "--name", "mine-gps"]) == 0
    err = capsys.readouterr().err
    assert "named it mine-gps: --firmware mine-gps now runs this build" in err
    assert "its other names: 4.6.0-gps" in err
    # Once more: the name is already there, so nothing new is named.
    assert main(["firmware", "build", "--source", str(tree), "--gps", "--name", "mine-gps"]) == 0
    assert "named it" not in capsys.readouterr().err
    assert main(["firmware", "list"]) == 0
    table = capsys.readouterr().out.splitlines()
    assert table[0].startswith("NAMES ")
    assert any(line.startswith("4.6.0-gps, mine-gps ") for line in table), table
    assert main(["firmware", "list", "--json"]) == 0
    rows = [r for r in json.loads(capsys.readouterr().out) if r["source"] == "cache"]
    assert [r["names"] for r in rows] == [["4.6.0-gps", "mine-gps"]]


# --- find_firmware and the command-line form ------------------------------------------------


def test_find_firmware_resolves_a_cached_name(
    tree: Path, env: dict[str, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    result = build_firmware(tree, FirmwareBuildOptions(gps=True), environ=env)
    found = find_firmware("4.6.0-gps", environ=env)
    assert found.path == result.binary_path
    assert "4.6.0-gps" in found.source
    assert find_firmware(environ={**env, "BFSITL_FIRMWARE": "4.6.0-gps"}).path == result.binary_path
    # An existing path of the same name wins over the cached name.
    monkeypatch.chdir(tmp_path)
    local = tmp_path / "4.6.0-gps"
    local.write_text("#!/bin/sh\n")
    local.chmod(0o755)
    assert find_firmware("4.6.0-gps", environ=env).path == local


def test_bad_firmware_value_lists_the_cached_names(tree: Path, env: dict[str, str]) -> None:
    build_firmware(tree, FirmwareBuildOptions(gps=True), environ=env)
    with pytest.raises(FirmwareNotFoundError) as caught:
        find_firmware("4.7.0", environ=env)
    assert "not the name of a cached build" in str(caught.value)
    assert "4.6.0-gps" in str(caught.value)


@pytest.mark.parametrize("name", ["betaflight_4.6.0_SITL", "betaflight_SITL.elf", "sitl"])
def test_takes_ip_flag_comes_from_the_bytes(tmp_path: Path, name: str) -> None:
    clear_cache()
    with_text = tmp_path / "a" / name
    without = tmp_path / "b" / name
    for path, content in (
        (with_text, b"usage\0  --ip <address>     Simulator IP\0"),
        (without, b"\x7fELF 4.6 copies argv[1]\0"),
    ):
        path.parent.mkdir()
        path.write_bytes(content)
        path.chmod(0o755)
    assert FirmwareBinary(with_text, "x").command("10.0.0.2")[1:] == ["--ip", "10.0.0.2"]
    assert FirmwareBinary(without, "x").command("10.0.0.2")[1:] == ["10.0.0.2"]
    assert binary_traits(with_text).takes_ip_flag and not binary_traits(without).features


def test_takes_ip_flag_of_an_unreadable_file_says_so(tmp_path: Path) -> None:
    with pytest.raises(FirmwareNotFoundError, match="cannot read SITL firmware"):
        FirmwareBinary(tmp_path / "missing_SITL", "x").command("127.0.0.1")


def test_build_options_for_the_profile(tree: Path, env: dict[str, str]) -> None:
    profile = pytest.importorskip("bfsitl.protocol.firmware_profile")
    if not hasattr(profile, "BuildOptions"):
        pytest.skip("firmware_profile has no BuildOptions")
    from bfsitl.build import build_options_for_binary

    result = build_firmware(
        tree,
        FirmwareBuildOptions(gps=True, defines=("ENABLE_GAZEBO_BRIDGE=0", "SITL_ATTITUDE_DIRECT")),
        environ=env,
    )
    options = build_options_for_binary(result.binary_path)
    assert options == profile.BuildOptions(gps=True, gazebo_bridge=False, attitude_direct=True)
    assert build_options_for_binary(tree / "Makefile") is None


def test_the_package_exports_what_it_lists() -> None:
    import bfsitl.build as package

    for name in package.__all__:
        assert getattr(package, name) is not None


def test_names_a_binary_lacks_are_found_in_its_bytes(tmp_path: Path) -> None:
    from bfsitl.build.binary_scan import names_missing

    binary = tmp_path / "betaflight_SITL"
    binary.write_bytes(
        b"\x7fELF\x00p_roll\x00d_max_roll\x00AIRMODE\x00abs_control_gain_x\x00align_board_roll\x00"
    )
    wanted = frozenset({"p_roll", "d_max_roll", "AIRMODE", "abs_control_gain", "d_max", "d_roll"})
    # A name that starts a longer one is not there; one that ends another is (the linker keeps
    # 4.6.0's d_roll only as the tail of align_board_roll).
    assert names_missing(binary, wanted) == {"abs_control_gain", "d_max"}
    empty = tmp_path / "empty"
    empty.write_bytes(b"")
    assert names_missing(empty, wanted) == wanted
