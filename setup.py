"""Package discovery for the three import packages of the viscorig distribution.

pyproject.toml holds all metadata; this file only lists packages, because the rig presets in
``sim/rigs`` are shipped as the subpackage ``rigsim.rigs`` and automatic discovery cannot express
that mapping.
"""

from setuptools import find_packages, setup

setup(
    packages=[
        *find_packages("src"),
        *find_packages("drivers"),
        *find_packages("sim", include=["rigsim", "rigsim.*"]),
        "rigsim.rigs",
    ]
)
