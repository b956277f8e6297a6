"""bfsitl's version, written once: ``bfsitl.__version__`` shows it, a build's record keeps it.

A module of its own so that code inside bfsitl never imports the package root, whose table of
public names reaches every package.
"""

__version__ = "0.1.0"
