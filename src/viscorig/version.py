"""The installed version of viscorig (``"0.0.0"`` in a source tree that is not installed).

A module of its own, importing nothing of the package, so that the modules that stamp files with
the version (storage, exchange, report) need not import the package's ``__init__``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("viscorig")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0"

__all__ = ["__version__"]
