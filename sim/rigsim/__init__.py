"""Simulated vibration rig and virtual 35670A analyser.

Integrates the two-DOF equations of motion of the rig in the time domain and measures like the
analyser does. Shares no code with ``viscorig`` (the identification core) on purpose: a test that
identification recovers the truth must not test a function against itself.
"""
