"""Where bfsitl keeps what it makes: the firmware cache, the compiled kernel, firmware
received from another machine.

One function that reads the environment and nothing else, so the packages that only need the
place (the kernel's compiler, a SITL's received firmware) do not import the builder's cache.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

CACHE_ENV_VAR = "BFSITL_CACHE_DIR"
"""Where the cache is; wins over ``$XDG_CACHE_HOME`` and ``~/.cache``."""


def cache_root(environ: Mapping[str, str] | None = None) -> Path:
    env = os.environ if environ is None else environ
    if env.get(CACHE_ENV_VAR):
        return Path(os.path.expanduser(env[CACHE_ENV_VAR])).absolute()
    if env.get("XDG_CACHE_HOME"):
        return Path(env["XDG_CACHE_HOME"]).absolute() / "bfsitl" / "firmware"
    home = env.get("HOME") or str(Path.home())
    return Path(home) / ".cache" / "bfsitl" / "firmware"
