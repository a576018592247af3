"""viscorig: swept-sine characterisation of viscoelastic dampers.

The core package: campaign storage, identification, diagnosis, sequences and the command line.
It knows no transport and no simulator; the command line wires in the ``agilent35670a`` driver
and the ``rigsim`` simulated rig.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("viscorig")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0"

__all__ = ["__version__"]
