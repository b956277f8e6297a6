"""A Betaflight source from a git URL: the ref resolved to a commit, a shallow clone of that
commit, kept in the cache under the commit so that the same commit is never fetched twice.

This is how a user gets master (``bfsitl firmware build --git
https://github.com/betaflight/betaflight --ref master``): bfsitl ships no firmware source
beyond the ``betaflight`` package's 4.6.0 tree, and master is in no package registry.

Steps, each one clear line when it fails:

1. ``git ls-remote`` turns the ref (a branch, a tag, a full commit hash, or nothing for the
   remote's default branch) into a commit.  Offline, a wrong URL and an unknown ref fail here,
   before anything is written.
2. A commit already in the cache is used as it is (a finished clone carries a marker file).
3. Otherwise ``git fetch --depth 1`` of that ref into a fresh directory beside the cache entry,
   which is renamed into place only when the checkout is complete: Ctrl-C, a full disk or a
   dropped connection leave no half-made entry behind.

No submodule is fetched: ``make TARGET=SITL`` compiles none of them.  Master's Makefile would
fetch two by itself (``src/config``, the boards' configurations, and libcanard); the build
copy gets stand-in stamps for those instead (:mod:`bfsitl.build.submodules`), so the build
works offline and from any snapshot of the tree.

git runs with ``GIT_TERMINAL_PROMPT=0`` (a private or misspelt URL fails instead of waiting
for a password nobody will type) and its progress lines are relayed to the build's progress.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import FirmwareSourceError

#: A finished clone's marker, written last: an entry without it is not used.
COMPLETE_MARKER = ".bfsitl-clone-complete"
#: Submodules the SITL build needs (see the module docstring): none.
SITL_SUBMODULES: tuple[str, ...] = ()
#: ``git ls-remote`` against an unreachable host gives up by itself; this bounds a server that
#: accepts the connection and then says nothing.
LS_REMOTE_TIMEOUT_S = 120.0

_FULL_HASH = re.compile(r"^[0-9a-f]{40}$")
_SHORT_HASH = re.compile(r"^[0-9a-f]{7,39}$")
# git's progress: "Receiving objects:  45% (1234/2742), 3.1 MiB | 2.0 MiB/s"
_PROGRESS = re.compile(r"^(?P<stage>[A-Za-z ]+):\s+(?P<percent>\d+)%")

Note = Callable[[str], None]


@dataclass(frozen=True)
class GitSource:
    """A clone ready to build: the tree, and what it is."""

    url: str
    #: As asked for (None: the remote's default branch).
    ref: str | None
    commit: str
    tree: Path
    #: False when the commit came from the cache.
    fetched: bool


def is_git_url(text: str) -> bool:
    """Whether ``text`` names a git remote rather than a local directory or tarball."""
    return "://" in text or bool(re.match(r"^[\w.-]+@[\w.-]+:", text))


def fetch_git_source(
    url: str,
    ref: str | None,
    cache_root: Path,
    *,
    note: Note | None = None,
    environ: Mapping[str, str] | None = None,
) -> GitSource:
    """The tree of ``ref`` at ``url``, from ``cache_root`` or freshly cloned into it.

    Raises :class:`~bfsitl.errors.FirmwareSourceError` with one line saying what went wrong
    and what to do."""
    say = note or (lambda _line: None)
    git = _git_command()
    env = _git_environment(environ)
    say(f"resolving {ref or 'the default branch'} at {url}")
    commit, fetch_ref = resolve_ref(git, url, ref, env)
    entry = cache_root / commit
    if (entry / COMPLETE_MARKER).is_file():
        say(f"source {commit[:12]} is cached ({entry})")
        return GitSource(url, ref, commit, entry, fetched=False)
    say(f"fetching {commit[:12]} (a shallow clone, no submodules)")
    cache_root.mkdir(parents=True, exist_ok=True)
    partial = Path(tempfile.mkdtemp(prefix=f".partial-{commit[:12]}-", dir=cache_root))
    try:
        _clone_into(git, url, fetch_ref, commit, partial, env, say)
        (partial / COMPLETE_MARKER).write_text(f"{url}\n{ref or ''}\n{commit}\n")
        if entry.exists():  # another process finished the same commit meanwhile
            shutil.rmtree(partial, ignore_errors=True)
        else:
            partial.rename(entry)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    say(f"source {commit[:12]} ready")
    return GitSource(url, ref, commit, entry, fetched=True)


def resolve_ref(git: str, url: str, ref: str | None, env: Mapping[str, str]) -> tuple[str, str]:
    """(the commit, what to fetch for it).  A full hash is taken as given (servers may refuse
    to list it, but fetching it works); a short one cannot be fetched and is refused."""
    if ref is not None and _FULL_HASH.match(ref.lower()):
        return ref.lower(), ref.lower()
    # Only the refs that can match: a big repository lists thousands of others.
    # (``REF^{}`` asks for an annotated tag's commit, which a bare pattern leaves out.)
    pattern = ["--symref", url, "HEAD"] if ref is None else [url, ref, f"{ref}^{{}}"]
    listing = _run_git(
        [git, "ls-remote", *pattern], env, what=f"listing {url}", timeout_s=LS_REMOTE_TIMEOUT_S
    )
    refs = parse_ls_remote(listing)
    found = pick_ref(refs, ref)
    if found is None:
        if ref is not None and _SHORT_HASH.match(ref.lower()):
            raise FirmwareSourceError(
                f"--ref {ref}: a short commit hash cannot be fetched shallowly; give all 40 "
                f"digits (`git rev-parse {ref}` in a clone prints them)"
            )
        if ref is None:
            raise FirmwareSourceError(f"{url} has no default branch (HEAD): give --ref")
        raise FirmwareSourceError(
            f"{url} has no branch, tag or commit {ref!r} (`git ls-remote {url}` lists them)"
        )
    return found


def parse_ls_remote(text: str) -> dict[str, str]:
    """``git ls-remote`` output as {ref name: commit}; symref lines are skipped."""
    refs: dict[str, str] = {}
    for line in text.splitlines():
        parts = line.split("\t")
        if len(parts) != 2 or line.startswith("ref:"):
            continue
        commit, name = parts[0].strip().lower(), parts[1].strip()
        if _FULL_HASH.match(commit):
            refs[name] = commit
    return refs


def pick_ref(refs: Mapping[str, str], ref: str | None) -> tuple[str, str] | None:
    """(commit, ref to fetch) for ``ref`` among ``refs``: a branch before a tag of the same
    name, an annotated tag by the commit it points at (``^{}``), a full ref name as given."""
    if ref is None:
        return (refs["HEAD"], "HEAD") if "HEAD" in refs else None
    for name in (f"refs/heads/{ref}", f"refs/tags/{ref}", ref):
        if name in refs:
            return refs.get(f"{name}^{{}}", refs[name]), name
    return None


def _clone_into(
    git: str,
    url: str,
    fetch_ref: str,
    commit: str,
    directory: Path,
    env: Mapping[str, str],
    say: Note,
) -> None:
    _run_git([git, "init", "--quiet", str(directory)], env, what="git init")
    _run_git(
        [git, "-C", str(directory), "remote", "add", "origin", url], env, what="git remote add"
    )
    _run_git(
        [
            git,
            "-C",
            str(directory),
            "fetch",
            "--depth",
            "1",
            "--progress",
            "--no-tags",
            "origin",
            fetch_ref,
        ],
        env,
        what=f"fetching {fetch_ref} from {url}",
        on_progress=_progress_relay(say),
    )
    fetched = (
        _run_git(
            [git, "-C", str(directory), "rev-parse", "FETCH_HEAD^{commit}"],
            env,
            what="git rev-parse",
        )
        .strip()
        .lower()
    )
    if fetched != commit:
        # The branch moved between ls-remote and fetch: build what was fetched, and say so.
        say(f"{fetch_ref} moved to {fetched[:12]} while fetching; building that")
    _run_git(
        [git, "-C", str(directory), "checkout", "--quiet", "--detach", "FETCH_HEAD"],
        env,
        what="git checkout",
    )
    for path in SITL_SUBMODULES:
        _run_git(
            [
                git,
                "-C",
                str(directory),
                "submodule",
                "update",
                "--init",
                "--depth",
                "1",
                "--",
                path,
            ],
            env,
            what=f"submodule {path}",
            on_progress=_progress_relay(say),
        )


def _progress_relay(say: Note) -> Callable[[str], None]:
    """git's progress lines as one line per stage and 25 % (a log, not a live counter)."""
    shown: dict[str, int] = {}

    def relay(line: str) -> None:
        match = _PROGRESS.match(line.strip())
        if match is None:
            return
        stage, percent = match["stage"].strip(), int(match["percent"])
        step = percent // 25
        if shown.get(stage, -1) < step:
            shown[stage] = step
            say(f"git: {stage.lower()} {percent}%")

    return relay


def _git_command() -> str:
    git = shutil.which("git")
    if git is None:
        raise FirmwareSourceError(
            "git is not installed (apt-get install git); it is needed for --git"
        )
    return git


def _git_environment(environ: Mapping[str, str] | None) -> dict[str, str]:
    env = dict(os.environ if environ is None else environ)
    env["GIT_TERMINAL_PROMPT"] = "0"  # fail on a password prompt rather than hang
    env.setdefault("GIT_ASKPASS", "true")
    env["LC_ALL"] = "C"  # messages in English: the last line is shown to the user
    return env


def _run_git(
    args: Sequence[str],
    env: Mapping[str, str],
    *,
    what: str,
    timeout_s: float | None = None,
    on_progress: Callable[[str], None] | None = None,
) -> str:
    """Run git; its stdout.  A failure is one line: what was being done and git's last word."""
    try:
        process = subprocess.Popen(
            list(args),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=dict(env),
            stdin=subprocess.DEVNULL,
        )
    except OSError as exc:
        raise FirmwareSourceError(f"{what}: cannot run git: {exc}") from None
    try:
        stdout, stderr = _communicate(process, timeout_s, on_progress)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
        raise FirmwareSourceError(
            f"{what}: no answer in {timeout_s:.0f} s (offline, or the server is not answering)"
        ) from None
    except BaseException:  # Ctrl-C: git goes too
        process.kill()
        process.wait()
        raise
    if process.returncode != 0:
        raise FirmwareSourceError(f"{what} failed: {_last_word(stderr)}")
    return stdout


def _communicate(
    process: subprocess.Popen[bytes],
    timeout_s: float | None,
    on_progress: Callable[[str], None] | None,
) -> tuple[str, str]:
    if on_progress is None:
        out, err = process.communicate(timeout=timeout_s)
        return out.decode(errors="replace"), err.decode(errors="replace")
    # Progress comes on stderr as \r-separated updates; read it as it comes.
    assert process.stderr is not None and process.stdout is not None
    kept: list[str] = []
    pending = b""
    while chunk := process.stderr.read1(4096):  # type: ignore[attr-defined]
        pending += chunk
        *lines, pending = re.split(rb"[\r\n]", pending)
        for raw in lines:
            line = raw.decode(errors="replace")
            if line.strip():
                kept.append(line)
                on_progress(line)
    if pending.strip():
        kept.append(pending.decode(errors="replace"))
    text = process.stdout.read().decode(errors="replace")
    process.wait(timeout=timeout_s)
    return text, "\n".join(kept[-20:])


def _last_word(stderr: str) -> str:
    """git's reason: its last ``fatal:``/``error:`` line, else its last line."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    for line in reversed(lines):
        if line.startswith(("fatal:", "error:")):
            return line
    return lines[-1] if lines else "no reason given"
