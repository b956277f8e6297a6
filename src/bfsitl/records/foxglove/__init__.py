"""A flight for Foxglove: MCAP files and a live WebSocket server (the `foxglove` extra)."""

from bfsitl.records.foxglove.recorder import FoxgloveRecorder

__all__ = ["FoxgloveRecorder"]
