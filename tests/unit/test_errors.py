"""One exception tree in one file: every exception class bfsitl defines is in bfsitl.errors,
derives from BfsitlError, and is drawn in that module's tree."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import bfsitl
from bfsitl import errors


def bfsitl_exception_classes() -> set[type[BaseException]]:
    found: set[type[BaseException]] = set()
    for module_info in pkgutil.walk_packages(bfsitl.__path__, "bfsitl."):
        try:
            module = importlib.import_module(module_info.name)
        except errors.ExtraMissingError:
            # A module of an extra this installation lacks (bfsitl.gym.policy_export without
            # torch) says so on import, by design; it is walked where the extra is (CI
            # installs every extra).
            continue
        for _name, value in inspect.getmembers(module, inspect.isclass):
            if issubclass(value, BaseException) and value.__module__.startswith("bfsitl"):
                found.add(value)
    return found


def test_every_exception_class_is_defined_in_errors_py():
    classes = bfsitl_exception_classes()
    assert len(classes) > 30  # the walk found the package's modules
    elsewhere = sorted(
        f"{c.__module__}.{c.__qualname__}" for c in classes if c.__module__ != "bfsitl.errors"
    )
    assert elsewhere == [], "define these in bfsitl/errors.py (and re-export if needed)"


def test_every_error_derives_from_the_root_and_is_in_the_drawn_tree():
    doc = errors.__doc__ or ""
    for cls in bfsitl_exception_classes():
        # The one stop that is no error: SIGTERM taken like Ctrl-C.
        root = KeyboardInterrupt if cls is errors.Interrupted else errors.BfsitlError
        assert issubclass(cls, root), cls
        assert cls.__name__ in doc, f"{cls.__name__} is missing from the tree in errors.py"
