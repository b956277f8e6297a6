"""``bfsitl firmware``: build SITL binaries from source, list them, inspect one, clean up.

``build`` prints progress on stderr and, last on stdout, the binary's absolute path, so that
``FW=$(bfsitl firmware build --gps | tail -1)`` works; the build's name then works wherever a
firmware is asked for (``--firmware 4.6.0-gps``, ``BFSITL_FIRMWARE=4.6.0-gps``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from typing import Any

from bfsitl.build.binary_scan import binary_traits
from bfsitl.build.cache import FirmwareCache
from bfsitl.build.metadata import BuildMetadata, metadata_for_binary
from bfsitl.build.source_tree import package_source_dir, read_version
from bfsitl.cli.target import progress
from bfsitl.errors import BfsitlError, FirmwareBuildError, MspErrorReply
from bfsitl.sitl.firmware import FirmwareBinary, find_firmware

EXIT_OK = 0
#: Clones made by ``--git``, one directory per commit, inside the firmware cache.
GIT_SOURCES_DIR = "git-sources"


def add_firmware_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    firmware = sub.add_parser(
        "firmware",
        help="build SITL binaries from source; list and inspect them",
        description="Build Betaflight SITL binaries from source (out of tree, cached), list "
        "the cached builds, inspect a binary. A cached build's name works "
        "wherever --firmware or BFSITL_FIRMWARE takes a path.",
        epilog="Examples:\n"
        "  bfsitl firmware build --gps          4.6.0 with GPS, GPS Rescue, altitude "
        "and position hold\n"
        "  bfsitl firmware build --git https://github.com/betaflight/betaflight --ref "
        "master\n"
        "  bfsitl firmware build --source ~/src/betaflight --lockstep\n"
        "  FW=$(bfsitl firmware build --gps | tail -1)\n"
        "  bfsitl firmware list\n"
        "  bfsitl firmware build --lockstep     4.6.0 in lockstep (bfsitl fly runs "
        "it faster than real time, repeatably)\n"
        "  bfsitl firmware info 4.6.0-gps\n"
        "  bfsitl status --start --firmware 4.6.0-gps",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    actions = firmware.add_subparsers(dest="firmware_action", metavar="ACTION", required=True)

    build = actions.add_parser(
        "build",
        help="compile a SITL from a source tree or tarball (cached)",
        description="Compile a SITL (make TARGET=SITL) in a copy of the source, keep the binary "
        "and its build.json in the cache and print its path (the last line on "
        "stdout). The same source and options again: instant, from the cache.",
    )
    origin = build.add_mutually_exclusive_group()
    origin.add_argument(
        "--source",
        default=None,
        metavar="DIR_OR_TARBALL",
        help="a Betaflight tree (checkout, extracted tarball) or a "
        ".tar.xz/.tar.gz (default: the 4.6.0 tree of the installed "
        "betaflight package)",
    )
    origin.add_argument(
        "--git",
        default=None,
        metavar="URL",
        help="clone this git repository (shallow, no submodules; cached by "
        "commit) and build it, e.g. "
        "https://github.com/betaflight/betaflight",
    )
    build.add_argument(
        "--ref",
        default=None,
        metavar="REF",
        help="with --git: a branch, tag or full commit hash (default: the "
        "repository's default branch)",
    )
    build.add_argument(
        "--gps",
        action="store_true",
        help="with GPS (virtual), GPS Rescue, altitude and position hold, "
        "wherever the tree has the code (master's SITL has them anyway)",
    )
    build.add_argument(
        "--lockstep",
        action="store_true",
        help="apply bfsitl's lockstep patch (SIMULATOR platform only): the FC's "
        "clock follows the fdm packets, so `bfsitl fly` runs deterministic "
        "and as fast as the machine allows",
    )
    build.add_argument(
        "--define",
        action="append",
        default=[],
        metavar="NAME[=VALUE]",
        help="an extra -D for the compiler (repeatable)",
    )
    build.add_argument(
        "--jobs",
        "-j",
        type=_positive_int,
        default=None,
        metavar="N",
        help="parallel compile jobs (default: the CPUs available)",
    )
    build.add_argument(
        "--name",
        default=None,
        help="the build's name (default from version, revision and options, "
        "e.g. 4.6.0-gps); a name taken by another build moves to this one",
    )
    build.add_argument("--force", action="store_true", help="build again even if the cache has it")
    build.set_defaults(func=cmd_build)

    listing = actions.add_parser(
        "list",
        help="cached builds and the betaflight package's binary",
        description="The cached builds and the installed betaflight "
        "package's binary: name, version, MSP API, "
        "options, GPS, path.",
    )
    listing.add_argument("--json", action="store_true", help="a JSON list")
    listing.set_defaults(func=cmd_list)

    info = actions.add_parser(
        "info",
        help="what a binary is: build record, command-line form, live probe",
        description="Show a binary's build record (when bfsitl built it), what its bytes say "
        "(command-line form, compiled-in features) and, unless --no-probe, what it "
        "says about itself when started in an isolated namespace.",
    )
    info.add_argument(
        "firmware",
        nargs="?",
        default=None,
        metavar="BINARY_OR_NAME",
        help="a path or a cached build's name (default: the firmware bfsitl would use)",
    )
    info.add_argument("--json", action="store_true", help="one JSON object")
    info.add_argument("--no-probe", action="store_true", help="do not start the binary")
    info.set_defaults(func=cmd_info)

    clean = actions.add_parser(
        "clean",
        help="remove cached builds",
        description="Remove the named cached builds, or with --all the whole firmware cache.",
    )
    clean.add_argument("names", nargs="*", metavar="NAME", help="builds to remove")
    clean.add_argument("--all", action="store_true", help="remove the whole cache")
    clean.set_defaults(func=cmd_clean)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value


# --- build -----------------------------------------------------------------------------------


def cmd_build(args: argparse.Namespace) -> int:
    from bfsitl.build.builder import build_firmware  # the heavy part, for this command only
    from bfsitl.build.options import FirmwareBuildOptions
    from bfsitl.build.progress import BuildProgress

    if args.ref is not None and args.git is None:
        raise FirmwareBuildError(
            "--ref goes with --git URL (a local tree is built as it is checked out)"
        )
    options = FirmwareBuildOptions(defines=tuple(args.define), gps=args.gps, lockstep=args.lockstep)
    report = BuildProgress()
    cache = FirmwareCache()
    names_before = cache.name_map()
    # SIGTERM stops a build like Ctrl-C (bfsitl.cli.main): make's process group killed, the
    # copy deleted.
    source, url = args.source, None
    if args.git is not None:
        from bfsitl.build.git_source import fetch_git_source

        cloned = fetch_git_source(
            args.git, args.ref, cache.root / GIT_SOURCES_DIR, note=report.note
        )
        source, url = cloned.tree, cloned.url
    result = build_firmware(
        source,
        options,
        name=args.name,
        jobs=args.jobs,
        force=args.force,
        progress=report,
        source_url=url,
    )
    metadata = result.metadata
    if result.cached:
        progress(f"cached: {result.name} (built {metadata.built_at}, key {result.entry.key})")
    else:
        progress(
            f"built {result.name} in {metadata.build_duration_s:.1f} s "
            f"({metadata.compiled_files} files compiled)"
        )
    if result.cached and names_before.get(result.name) != result.entry.key:
        progress(f"named it {result.name}: --firmware {result.name} now runs this build")
    others = [name for name in result.entry.names if name != result.name]
    if others:
        progress(f"its other names: {', '.join(others)}")
    if result.displaced_key:
        short = result.displaced_key[:12]
        progress(
            f"the name {result.name} now means this build; the build it meant before "
            f"stays in the cache as {short}"
        )
    print(result.binary_path, flush=True)
    return EXIT_OK


# --- list ------------------------------------------------------------------------------------


def cmd_list(args: argparse.Namespace) -> int:
    cache = FirmwareCache()
    rows: list[dict[str, Any]] = []
    for entry in cache.entries():
        meta = entry.metadata
        rows.append(
            {
                "name": entry.label,
                "names": list(entry.names),
                "key": entry.key,
                "firmware_version": meta.firmware_version,
                "msp_api_version": meta.msp_api_version,
                "git_revision": meta.git_revision,
                "options": meta.options_text,
                "gps": meta.gps,
                "takes_ip_flag": meta.takes_ip_flag,
                "built_at": meta.built_at,
                "source": "cache",
                "source_url": meta.source_url,
                "path": str(entry.binary_path),
            }
        )
    package_row = _package_row()
    if package_row is not None:
        rows.append(package_row)
    if args.json:
        print(json.dumps(rows, indent=2))
        return EXIT_OK
    if not rows:
        progress(
            f"no cached builds in {cache.root}, and no betaflight package; build one: "
            f"bfsitl firmware build"
        )
        return EXIT_OK
    # Every name a build answers to: a build named with --name keeps its default name too,
    # and either works as --firmware.
    header = ("NAMES", "VERSION", "API", "OPTIONS", "GPS", "PATH")
    table = [header] + [
        (
            ", ".join(r["names"]) or r["name"],
            r["firmware_version"],
            r["msp_api_version"],
            r["options"],
            "yes" if r["gps"] else "no",
            r["path"],
        )
        for r in rows
    ]
    widths = [max(len(str(row[i])) for row in table) for i in range(len(header) - 1)]
    for row in table:
        cells = [str(cell).ljust(width) for cell, width in zip(row[:-1], widths, strict=True)]
        print("  ".join([*cells, str(row[-1])]))
    return EXIT_OK


def _package_row() -> dict[str, Any] | None:
    """The installed betaflight package's binary, as a row (version from its source tree)."""
    tree = package_source_dir()
    if tree is None:
        return None
    try:
        binary = find_firmware(environ={"PATH": ""})
    except BfsitlError:
        return None
    if binary.path.parent != tree / "obj":
        return None
    try:
        version = read_version(tree)
        traits = binary_traits(binary.path)
    except (BfsitlError, OSError):
        return None
    return {
        "name": "(package)",
        "names": [],
        "key": None,
        "firmware_version": version.firmware,
        "msp_api_version": version.msp_api,
        "git_revision": None,
        "options": "default",
        "gps": traits.has_gps,
        "takes_ip_flag": traits.takes_ip_flag,
        "built_at": None,
        "source": "betaflight package",
        "path": str(binary.path),
    }


# --- info ------------------------------------------------------------------------------------


def cmd_info(args: argparse.Namespace) -> int:
    binary = find_firmware(args.firmware)
    metadata = metadata_for_binary(binary.path)
    try:
        traits = binary_traits(binary.path)
    except OSError as exc:
        raise FirmwareBuildError(f"cannot read {binary.path}: {exc}") from None
    probe = None if args.no_probe else _probe(binary)
    report: dict[str, Any] = {
        "path": str(binary.path),
        "source": binary.source,
        "build": metadata.as_dict() if metadata is not None else None,
        "binary": {"takes_ip_flag": traits.takes_ip_flag, "features": list(traits.features)},
        "probe": probe,
    }
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(_info_text(binary, metadata, report))
    return EXIT_OK


def _probe(binary: FirmwareBinary) -> dict[str, Any]:
    """Start it isolated; read who it is and whether MSP_RAW_GPS answers (GPS compiled in)."""
    from bfsitl.fc.identity import read_identity
    from bfsitl.protocol.msp_codes import MspCommand
    from bfsitl.sitl.process import SitlProcess

    with SitlProcess(binary, isolate=True, progress=progress) as sitl:
        assert sitl.client is not None
        identity = read_identity(sitl.client)
        try:
            sitl.client.request(MspCommand.RAW_GPS)
            gps = True
        except MspErrorReply:
            gps = False
    return {"identity": identity.as_dict(), "describe": identity.describe(), "gps": gps}


def _info_text(
    binary: FirmwareBinary, metadata: BuildMetadata | None, report: dict[str, Any]
) -> str:
    lines = [f"binary        {binary.path}", f"found         {binary.source}"]
    if metadata is not None:
        revision = f", git {metadata.git_revision}" if metadata.git_revision else ""
        lines += [
            f"build         {metadata.name} (key {metadata.key}), built {metadata.built_at} "
            f"in {metadata.build_duration_s:.1f} s",
            f"version       {metadata.firmware_version} (MSP API {metadata.msp_api_version})"
            f"{revision}",
            f"options       {metadata.options_text}"
            + (f"; make -D: {' '.join(metadata.make_defines)}" if metadata.make_defines else ""),
            f"source        {metadata.source_path} ({metadata.source_kind}, fingerprint "
            f"{metadata.source_fingerprint[:12]})",
        ]
        if metadata.source_url:
            lines.append(f"cloned from   {metadata.source_url}")
    else:
        lines.append("build         not built by bfsitl (no build.json beside it)")
    features = ", ".join(report["binary"]["features"]) or "no GPS, altitude or position hold"
    lines.append(f"features      {features} (from the binary's settings)")
    form = (
        "--ip ADDR (master form)"
        if report["binary"]["takes_ip_flag"]
        else "bare address as argv[1] (4.6 form)"
    )
    lines.append(f"command line  {form}")
    probe = report["probe"]
    if probe is not None:
        gps = "answers MSP_RAW_GPS" if probe["gps"] else "not compiled in (MSP_RAW_GPS refused)"
        lines.append(f"running       {probe['describe']}")
        lines.append(f"GPS           {gps}")
    return "\n".join(lines)


# --- clean -----------------------------------------------------------------------------------


def cmd_clean(args: argparse.Namespace) -> int:
    from bfsitl.scenario.prepared_fc import forget_prepared  # only here: the scenario layer

    cache = FirmwareCache()
    if args.all:
        cache.clear()
        progress(f"removed the firmware cache {cache.root}")
        return EXIT_OK
    if not args.names:
        print("bfsitl firmware clean: name builds to remove, or pass --all", file=sys.stderr)
        return 2
    entries = []
    for name in args.names:
        entry = cache.resolve(name)
        if entry is None:
            labels = ", ".join(cache.labels()) or "none"
            raise FirmwareBuildError(f"no cached build named {name!r} (cached: {labels})")
        entries.append(entry)
    for entry in entries:
        with contextlib.suppress(OSError):  # a build without its binary has no states
            forget_prepared(entry.binary_path, cache=cache.root)
        names = cache.remove(entry.key)
        progress(f"removed {', '.join(names) or entry.key[:12]} ({entry.binary_path.parent})")
    return EXIT_OK
