"""Coulomb (dry) friction acting on the disc, as a viscorig effect term.

A guide or a seal rubbing on the disc resists it with a force of constant size ``F_c`` against
the motion. Over one cycle of a harmonic motion of displacement amplitude ``X`` it dissipates
``4 F_c X``, as much as a dashpot of ``c_eq = 4 F_c / (π ω X)`` would (the first-harmonic
describing function). It therefore adds ``iω c_eq = i 4 F_c / (π X)`` to the disc's dynamic
stiffness: a damping that, unlike the rubber's, grows as the amplitude falls. On the rig ``X``
is the reference (disc) acceleration amplitude over ``ω²``.

The package registers the term with viscorig through the ``viscorig.terms`` entry point (see
``pyproject.toml``); nothing in viscorig names it.
"""

from __future__ import annotations

import numpy as np

from viscorig.models import Parameter, Term

__all__ = ["DryFriction"]


class DryFriction(Term):
    """Coulomb friction force ``F_c`` (N) on the disc, equivalent-linearised."""

    keyword = "dry_friction"
    requires = ("reference_amplitude",)

    def parameters(self) -> tuple[Parameter, ...]:
        return (
            Parameter("F_c", "N", 0.0, 1e3, 1e-3, log=False,
                      description="Coulomb friction force on the disc"),
        )

    def disc_stiffness(self, ctx, p):
        displacement = np.maximum(np.abs(ctx.reference_amplitude), 1e-300) / ctx.omega**2
        return 1j * 4.0 * p["F_c"] / (np.pi * displacement)
