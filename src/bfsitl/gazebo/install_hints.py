"""What the Gazebo backend's errors tell the user to install or build: the hints their
messages end with.  The error classes themselves are in :mod:`bfsitl.errors` (the one tree):

    BfsitlError
    └── GazeboError                    the Gazebo backend
        ├── GazeboNotFoundError        ``gz`` (Gazebo Harmonic) is not installed / not on PATH
        │   └── GazeboPluginNotFoundError  libBetaflightPlugin.so was not found
        └── GazeboStartError           ``gz sim`` ended or never loaded the plugin
"""

from __future__ import annotations

#: Where the long instructions are; every message points there.
DOCS = "docs/gazebo.md"

INSTALL_HINT = (
    "Install Gazebo Harmonic (gz-sim 8): on Ubuntu 22.04/24.04 add the OSRF apt repository "
    "and `apt-get install gz-harmonic` (https://gazebosim.org/docs/harmonic/install), then "
    f"check with `gz sim --versions`. Details: {DOCS}."
)

BUILD_HINT = (
    "Build the BetaflightPlugin for Harmonic (CMake against gz-cmake3, gz-sim8, gz-plugin2, "
    f"gz-math7, gz-transport13, gz-msgs10; steps in {DOCS}), then pass its build folder "
    "with --gz-plugin-dir DIR or add DIR to GZ_SIM_SYSTEM_PLUGIN_PATH."
)
