"""Driver for the Agilent (HP) 35670A dynamic signal analyser in swept-sine mode.

Built on pyvisa; imports nothing of ``viscorig`` or ``rigsim``. Facts about the instrument:
``shared/docs/35670a.md``.
"""
