"""The public surface: every name in bfsitl.__all__ resolves, lazily, to its defining object."""

from __future__ import annotations

import subprocess
import sys

import pytest

import bfsitl


@pytest.mark.parametrize("name", bfsitl.__all__)
def test_every_public_name_resolves(name):
    assert getattr(bfsitl, name) is not None


def test_all_lists_exactly_the_lazy_exports():
    assert set(bfsitl.__all__) == {"BfsitlError", "__version__", *bfsitl._EXPORTS}


def test_the_names_are_the_defining_modules_objects():
    from bfsitl.mission.session import FlightSession
    from bfsitl.sitl.process import SitlProcess

    assert bfsitl.FlightSession is FlightSession and bfsitl.SitlProcess is SitlProcess


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'NoSuchThing'"):
        bfsitl.NoSuchThing  # noqa: B018


def test_import_bfsitl_loads_no_flight_machinery():
    code = "import sys, bfsitl; print(sorted(m for m in sys.modules if m.startswith('bfsitl.')))"
    loaded = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert "bfsitl.mission" not in loaded and "bfsitl.sim" not in loaded, loaded
