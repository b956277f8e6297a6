"""bfsitl: fly a real Betaflight flight controller in software-in-the-loop, from Python."""

from bfsitl.errors import BfsitlError

__version__ = "0.1.0"

__all__ = ["BfsitlError", "__version__"]
