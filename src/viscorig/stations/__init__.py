"""Stations: the one place where the driver (``agilent35670a``) and the simulated rig
(``rigsim``) meet the core.

The command line and the bench's queue both use it: :mod:`~viscorig.stations.opening` opens a
station (the lab's analyser, or the embedded simulated rig on loopback) and says how a sequence
runs on it, :mod:`~viscorig.stations.checking` checks a sequence against it before anything runs,
:mod:`~viscorig.stations.forecasting` predicts its test time, and
:mod:`~viscorig.stations.simpoints` measures a plan's points on a simulated rig.
"""
