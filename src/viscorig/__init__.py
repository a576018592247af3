"""viscorig: swept-sine characterisation of viscoelastic dampers.

The core package: campaign storage, identification, diagnosis, sequences and the command line.
It knows no transport and no simulator; the command line wires in the ``agilent35670a`` driver
and the ``rigsim`` simulated rig.

For notebooks and scripts, :func:`open_campaign` opens a campaign file
(:mod:`viscorig.api`): runs by name, ``identify``, ``diagnose`` and ``compare``, and
``to_pandas()``/``to_xarray()`` with ``frequency_hz`` as the index. It is loaded on first use,
so ``import viscorig`` stays light.
"""

import logging

from viscorig.version import __version__

# A library logs and leaves the output to the application (the command line sets -v/-q).
logging.getLogger(__name__).addHandler(logging.NullHandler())

_API = {"open_campaign", "Campaign", "Run", "Fit", "Diagnosis", "Comparison"}


def __getattr__(name: str):
    if name in _API:
        # keeps `import viscorig` light: numpy and h5py load with the API
        from viscorig import api

        return getattr(api, name)
    raise AttributeError(f"module 'viscorig' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])


__all__ = ["Campaign", "Comparison", "Diagnosis", "Fit", "Run", "__version__", "open_campaign"]
