"""``bfsitl firmware build --lockstep``: the SITL patch that makes fdm packets the FC's clock."""

from bfsitl.build.lockstep.patch import MARKER, LockstepPatch, patch_sitl_source

__all__ = ["MARKER", "LockstepPatch", "patch_sitl_source"]
