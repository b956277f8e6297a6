"""``bfsitl firmware build``: a SITL binary from a source tree, made out of tree and cached.

The steps, in order:

1. classify the source and read its facts (fingerprint, version, what its SITL has): fast
   when known before (:mod:`bfsitl.build.source_facts`);
2. plan the build: defines, make arguments, tree hooks, key, name (:mod:`bfsitl.build.plan`);
3. under the key's lock: a finished entry is the answer ("cached"); else
4. copy the tree (without ``obj/``, ``.git``, ``docs/``) into ``tmp/`` of the cache, or unpack
   the tarball there: the source and its ``obj/`` are never written to;
5. run the plan's tree hooks on the copy, then make (:mod:`bfsitl.build.make_runner`);
6. keep the binary and its ``build.json``, rename them into ``builds/<key>`` in one step,
   delete the copy, point the name at the new entry.

Any failure, Ctrl-C included, stops make's process group and deletes the copy: the cache
never holds a partial entry.
"""

from __future__ import annotations

import datetime
import os
import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from bfsitl.build.binary_scan import binary_traits
from bfsitl.build.cache import CacheEntry, FirmwareCache, check_name
from bfsitl.build.make_runner import (
    build_environment,
    check_build_tools,
    run_make,
)
from bfsitl.build.metadata import BuildMetadata
from bfsitl.build.options import FirmwareBuildOptions
from bfsitl.build.plan import RECIPE_VERSION, BuildPlan, plan_build
from bfsitl.build.progress import BuildProgress
from bfsitl.build.source_facts import SKIPPED_WHEN_COPYING, identify_source, unpack
from bfsitl.build.source_tree import SourceSpec, remove_tree, resolve_source
from bfsitl.build.submodules import stamp_missing_submodules
from bfsitl.errors import FirmwareBuildError
from bfsitl.version import __version__

BINARY_GLOB = "betaflight_*_SITL"
"""What ``make TARGET=SITL`` leaves in ``obj/`` (the versioned copy of the ELF)."""
ELF_FALLBACK = "main/betaflight_SITL.elf"


@dataclass(frozen=True)
class BuildResult:
    """What :func:`build_firmware` produced or found."""

    entry: CacheEntry
    #: True when the build was already in the cache (nothing was compiled).
    cached: bool
    #: The name now pointing at the build, and the key of the build it was taken from.
    name: str
    displaced_key: str | None
    plan: BuildPlan

    @property
    def binary_path(self) -> Path:
        return self.entry.binary_path

    @property
    def metadata(self) -> BuildMetadata:
        return self.entry.metadata


def default_jobs() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def build_firmware(
    source: str | os.PathLike[str] | None = None,
    options: FirmwareBuildOptions | None = None,
    *,
    name: str | None = None,
    jobs: int | None = None,
    force: bool = False,
    cache: FirmwareCache | None = None,
    progress: BuildProgress | None = None,
    environ: Mapping[str, str] | None = None,
    source_url: str | None = None,
) -> BuildResult:
    """Build (or find in the cache) a SITL binary; see the module docstring for the steps.

    ``source``: None for the installed ``betaflight`` package's 4.6.0 tree, else a directory
    or a ``.tar.xz``/``.tar.gz``.  ``name`` overrides the default (``4.6.0-gps``, ...).
    ``source_url``: where the tree was cloned from (``--git``), kept in the build record.
    Raises :class:`~bfsitl.errors.FirmwareBuildError` (or a subclass) on failure.
    """
    env = dict(os.environ if environ is None else environ)
    cache = cache if cache is not None else FirmwareCache(environ=env)
    options = options if options is not None else FirmwareBuildOptions()
    report = progress if progress is not None else BuildProgress(stream=None)
    if name is not None:
        check_name(name)
    if jobs is not None and jobs < 1:
        raise FirmwareBuildError(f"--jobs must be at least 1, got {jobs}")
    spec = resolve_source(source)
    scratch: list[Path] = []

    def new_scratch() -> Path:
        scratch.append(cache.scratch_dir("unpack-"))
        return scratch[-1]

    try:
        source_info = identify_source(spec, cache.memo_dir, new_scratch, on_unpack=report.note)
        plan = plan_build(source_info, options)
        chosen = name or plan.default_name
        with cache.lock(plan.key, on_wait=report.note):
            entry = cache.entry(plan.key)
            if entry is not None and not force:
                displaced = cache.set_name(chosen, plan.key)
                return BuildResult(_with_name(cache, plan.key), True, chosen, displaced, plan)
            _explain_plan(plan, chosen, report)
            check_build_tools(env)
            work = cache.work_dir(plan.key)
            try:
                staging = _build_into(
                    plan, chosen, work, jobs or default_jobs(), env, report, cache.root, source_url
                )
                cache.commit(staging, plan.key)
            finally:
                remove_tree(work)
            displaced = cache.set_name(chosen, plan.key)
            return BuildResult(_with_name(cache, plan.key), False, chosen, displaced, plan)
    finally:
        for directory in scratch:
            remove_tree(directory)


def _with_name(cache: FirmwareCache, key: str) -> CacheEntry:
    entry = cache.entry(key)
    if entry is None:  # deleted between our commit and now (a concurrent `clean`)
        raise FirmwareBuildError(f"the build {key} vanished from the cache {cache.root}")
    return entry


def _explain_plan(plan: BuildPlan, name: str, report: BuildProgress) -> None:
    report.note(f"building {name}: {plan.describe()}")
    gps = plan.gps
    if gps is None:
        return
    if not gps.add:
        report.note(
            "--gps: this tree's SITL has GPS, altitude and position hold already; nothing to add"
        )
    if gps.unavailable:
        report.note(f"--gps: this tree has no code for {', '.join(gps.unavailable)}; built without")


def _build_into(
    plan: BuildPlan,
    name: str,
    work: Path,
    jobs: int,
    environ: Mapping[str, str],
    report: BuildProgress,
    cache_root: Path,
    source_url: str | None = None,
) -> Path:
    """Copy, prepare, make; returns ``work/entry`` holding the binary and build.json."""
    started_s = time.monotonic()
    tree = _tree_copy(plan, work, report, cache_root)
    stamp_missing_submodules(tree, report.note)
    for hook in plan.tree_hooks:
        report.note(hook.description)
        hook(tree)
    env = build_environment(environ, work)
    args = plan.make_arguments(jobs)
    report.note(f"compiling with {jobs} job{'s' if jobs != 1 else ''}")
    result = run_make(
        args,
        cwd=tree,
        env=env,
        progress=report,
        dry_run_args=plan.make_arguments(jobs, dry_run=True),
    )
    built = _find_binary(tree)
    staging = work / "entry"
    staging.mkdir()
    binary = staging / built.name
    shutil.copy2(built, binary)
    traits = binary_traits(binary)
    if plan.expects_gps and not traits.has_gps:
        raise FirmwareBuildError(
            f"the build finished, but {built.name} has no GPS (no gps_provider setting): "
            f"this tree's SITL target disables it in a way bfsitl does not know"
        )
    facts = plan.source.facts
    metadata = BuildMetadata(
        name=name,
        key=plan.key,
        firmware_version=facts.firmware_version,
        msp_api_version=facts.msp_api_version,
        git_revision=plan.source.revision,
        defines=plan.options.defines,
        make_defines=plan.make_defines,
        gps_requested=plan.gps_changes_build,
        gps=traits.has_gps,
        features=traits.features,
        options=plan.options.key_fields(),
        source_kind=plan.source.spec.kind,
        source_path=str(plan.source.spec.path),
        source_fingerprint=facts.fingerprint,
        recipe_version=RECIPE_VERSION,
        built_at=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        build_duration_s=round(time.monotonic() - started_s, 1),
        compiled_files=result.compiled_files,
        jobs=jobs,
        make_command=tuple(args),
        binary_name=built.name,
        takes_ip_flag=traits.takes_ip_flag,
        bfsitl_version=__version__,
        source_url=source_url,
    )
    metadata.write(staging)
    return staging


def _tree_copy(plan: BuildPlan, work: Path, report: BuildProgress, cache_root: Path) -> Path:
    """A private, writable tree to build in: a copy of the directory, or the unpacked tarball."""
    spec: SourceSpec = plan.source.spec
    if spec.is_tarball:
        if plan.source.tree is not None:
            # Unpacked already while reading its facts: it is ours, move it in.
            target = work / "tree"
            shutil.move(str(plan.source.tree), target)
            return target
        report.note(f"unpacking {spec.path.name}")
        return unpack(spec.path, work / "src")
    started_s = time.monotonic()
    target = work / "tree"
    shutil.copytree(spec.path, target, symlinks=True, ignore=_copy_filter(spec.path, cache_root))
    report.note(f"copied the source tree in {time.monotonic() - started_s:.1f} s")
    return target


def _copy_filter(root: Path, cache_root: Path) -> Callable[[str, list[str]], set[str]]:
    """Leave out top-level obj/, .git, docs/, and the cache itself if it lies in the tree."""
    root_text = os.path.abspath(root)
    cache_text = os.path.abspath(cache_root)

    def ignore(directory: str, names: list[str]) -> set[str]:
        skipped = set()
        if os.path.abspath(directory) == root_text:
            skipped |= {n for n in names if n in SKIPPED_WHEN_COPYING}
        here = os.path.abspath(directory)
        skipped |= {n for n in names if os.path.join(here, n) == cache_text}
        return skipped

    return ignore


def _find_binary(tree: Path) -> Path:
    obj = tree / "obj"
    candidates = sorted(
        (p for p in obj.glob(BINARY_GLOB) if p.is_file()),
        key=lambda p: p.stat().st_mtime_ns,
        reverse=True,
    )
    if not candidates and (obj / ELF_FALLBACK).is_file():
        candidates = [obj / ELF_FALLBACK]
    if not candidates:
        raise FirmwareBuildError(
            f"make finished, but left no SITL binary in obj/ (looked for {BINARY_GLOB} and "
            f"{ELF_FALLBACK})"
        )
    return candidates[0]
