"""A flight for Foxglove: MCAP files and a live WebSocket server (the `foxglove` extra)."""

from bfsitl.flight_record.recorder import FoxgloveRecorder

__all__ = ["FoxgloveRecorder"]
