"""The composable model framework: parameters, terms, the registry and the evaluation pipeline.

A model predicts the FRFs the rig measures (accelerances ``ẍ_s/F_e`` and ``ẍ_v/F_v``, as stored
in the campaign file) from closed-form frequency-domain physics. It is a sum of *terms*, in the
manner of lmfit composite models: each term is a small class with named parameters (name, unit,
bounds, default), and terms combine with ``+``. Exactly one term is a *modulus term* (it gives
the complex stiffness ``K*`` of the specimens); any number of *effect terms* modify the chain.

Evaluation pipeline (a term takes part in a stage by overriding that stage's method):

1. ``modulus(ctx, p)``: ``K*(ω)`` from the one modulus term.
2. ``modify_modulus(ctx, p, kstar)``: modifiers of ``K*`` (amplitude, drift), in spec order.
3. ``disc_stiffness(ctx, p)``: additions to the disc's dynamic stiffness
   ``D_v = K* − ω² M_v (+ Σ additions)`` (a fixture mode, for example).
4. ``couple(ctx, p, d_table, d_disc)``: receptances from the table's dynamic stiffness
   ``D_t = K_s − ω² M_s + iω C_s`` and ``D_v``. The default is the rigid link of physics.md,
   ``X_s/F_e = 1/(D_t + D_v)`` and ``X_v/F_v = 1/D_v``; at most one term (``load_cell``)
   replaces it.
5. ``measure(ctx, p, frfs)``: changes to the measured accelerances (a sensor delay), in order.

One more stage changes what the table and the specimens are attached to: ``frame(ctx, p)``
gives the dynamic stiffness ``G`` (N/m) of the inertial frame that carries the shaker body, the
table suspension and the specimens, on its own isolators (at most one term, ``frame``). Without
it the frame is ground. With it the coupling stage solves the rig with the frame as one more
body (:meth:`Model.predict`); a coupling term then gives only its link stiffness
(:meth:`Term.link_stiffness`).

``p`` is always a mapping from the term's *local* parameter names (``f_n``) to values; the model
maps them to global names (``f_n_1``) so a term never sees suffixes.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError

#: The FRFs a model can predict: name -> what is measured (accelerance, m/s²/N).
FRF_NAMES: dict[str, str] = {
    "table": "accelerance_table, ẍ_s/F_e",
    "support": "accelerance_support, ẍ_v/F_v",
}


@dataclass(frozen=True)
class Parameter:
    """One named model parameter.

    Attributes
    ----------
    name
        Local name (``K_v``, ``f_n``); the model may add a suffix ``_1``, ``_2``.
    unit
        SI unit as text (``"N/m"``, ``"kg"``, ``"s"``, ``""`` for dimensionless).
    lower, upper
        Bounds the fitter respects.
    default
        Value used as a start when nothing better is known.
    log
        The parameter is strictly positive and is fitted as ``log(value)``: equal relative
        steps, and the scale of the parameter does not matter.
    description
        One line for humans.
    """

    name: str
    unit: str
    lower: float
    upper: float
    default: float
    log: bool = True
    description: str = ""

    def __post_init__(self) -> None:
        if not self.lower < self.upper:
            raise ValueError(f"parameter {self.name}: lower bound must be below upper bound")
        if self.log and self.lower <= 0.0:
            raise ValueError(f"parameter {self.name}: a log parameter needs a positive lower bound")
        if not self.lower <= self.default <= self.upper:
            raise ValueError(f"parameter {self.name}: default outside its bounds")

    def renamed(self, name: str) -> Parameter:
        """The same parameter under another (suffixed) name."""
        return Parameter(
            name, self.unit, self.lower, self.upper, self.default, self.log, self.description
        )

    def clip(self, value: float) -> float:
        """``value`` moved just inside the bounds (a start must be strictly feasible)."""
        span = self.upper / self.lower if self.log else self.upper - self.lower
        if self.log:
            margin = min(1e-6, math.log(span) * 1e-9)
            return float(np.clip(value, self.lower * (1 + margin), self.upper * (1 - margin)))
        margin = span * 1e-9
        return float(np.clip(value, self.lower + margin, self.upper - margin))


def table_dynamic_stiffness(
    omega: NDArray[np.float64], values: Mapping[str, float]
) -> NDArray[np.complex128]:
    """The table's ``D_t = K_s − ω² M_s + iω C_s`` (N/m) at ``omega`` (rad/s)."""
    return values["K_s"] - omega**2 * values["M_s"] + 1j * omega * values["C_s"]


@dataclass(frozen=True)
class Context:
    """What a model needs besides its parameters: the measurement points.

    Attributes
    ----------
    frequency_hz
        Frequency of each point (Hz).
    time_s
        Seconds since the run's start at each point, or ``None`` (for drift effects).
    reference_amplitude
        The vibration amplitude achieved at each point (m/s², peak), or ``None``
        (for amplitude effects).
    temperature_c
        The specimen's recorded temperature at each point (°C), or ``None`` (for the
        ``temperature`` effect).
    """

    frequency_hz: NDArray[np.float64]
    time_s: NDArray[np.float64] | None = None
    reference_amplitude: NDArray[np.float64] | None = None
    temperature_c: NDArray[np.float64] | None = None
    omega: NDArray[np.float64] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        frequency = np.atleast_1d(np.asarray(self.frequency_hz, dtype=float))
        object.__setattr__(self, "frequency_hz", frequency)
        for name in ("time_s", "reference_amplitude", "temperature_c"):
            value = getattr(self, name)
            if value is not None:
                value = np.atleast_1d(np.asarray(value, dtype=float))
                if value.shape != frequency.shape:
                    raise ValueError(f"{name} must have one value per frequency point")
                object.__setattr__(self, name, value)
        object.__setattr__(self, "omega", 2.0 * np.pi * frequency)


class Term:
    """Base of every model term.

    A subclass sets :attr:`keyword` (its name in spec strings), declares its parameters in
    :meth:`parameters`, and overrides the stage methods it takes part in. Register it with
    :func:`register_term` so that :func:`parse_spec` knows it.

    Class attributes
    ----------------
    keyword
        Name in spec strings (``"fixture"``).
    kind
        ``"modulus"`` for a ``K*`` term (exactly one per model), ``"effect"`` otherwise.
    requires
        Context fields the term needs (``"time_s"``, ``"reference_amplitude"``).
    repeatable
        The same term (keyword and argument) may appear more than once in a model, each a
        distinct effect (two local modes); otherwise the copies would add into one effect that
        no data can split between them, and the model is refused.
    """

    keyword: ClassVar[str] = ""
    kind: ClassVar[str] = "effect"
    requires: ClassVar[tuple[str, ...]] = ()
    repeatable: ClassVar[bool] = False

    def __init__(self, argument: float | None = None) -> None:
        if argument is not None:
            raise InputError(f"term '{self.keyword}' takes no argument", "model spec")
        self.argument: float | None = argument

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def from_argument(cls, text: str | None) -> Term:
        """Build the term from the text inside its parentheses in a spec (``None`` if none)."""
        if text is None:
            return cls()
        if cls.__init__ is Term.__init__:
            raise InputError(f"term '{cls.keyword}' takes no argument, got '({text})'",
                             "model spec")
        try:
            value = float(text)
        except ValueError:
            raise InputError(
                f"term '{cls.keyword}' needs a number in parentheses, got '{text}'", "model spec"
            ) from None
        return cls(value)

    @property
    def spec(self) -> str:
        """Canonical spec text of this term (``fixture(58)``)."""
        if self.argument is None:
            return self.keyword
        return f"{self.keyword}({_format_number(self.argument)})"

    def sort_key(self) -> tuple[Any, ...]:
        """Order of terms of the same keyword in the canonical spec."""
        return (self.argument if self.argument is not None else -math.inf,)

    def parameters(self) -> tuple[Parameter, ...]:
        """The term's parameters, with local names."""
        return ()

    def candidates(self) -> list[Term] | None:
        """Concrete variants to choose from when the spec leaves a choice open (``maxwell``
        without an order); ``None`` when the term is already concrete. The fitter fits every
        variant and keeps the one with the lowest BIC."""
        return None

    def initial(self, ctx: Context, values: Mapping[str, float]) -> dict[str, float]:
        """Start values of the term's parameters (local names). ``values`` holds the start of
        everything else (global names). The default is each parameter's default."""
        return {parameter.name: parameter.default for parameter in self.parameters()}

    def start_from_data(
        self,
        model: Model,
        ctx: Context,
        values: Mapping[str, float],
        measured: Mapping[str, NDArray[np.complex128]],
    ) -> dict[str, float]:
        """Start values (local names) read off the measured FRFs ``{"table": ẍ_s/F_e, ...}``,
        called after :meth:`initial` with ``values`` the start of every parameter of ``model``.
        For what defaults cannot give (a fixture's frequency). The default returns ``{}``."""
        return {}

    # -- pipeline stages (override those the term takes part in) ------------------------------
    def modulus(self, ctx: Context, p: Mapping[str, float]) -> NDArray[np.complex128]:
        """Stage 1, modulus terms only: ``K*(ω)`` in N/m."""
        raise NotImplementedError

    def modify_modulus(
        self, ctx: Context, p: Mapping[str, float], kstar: NDArray[np.complex128]
    ) -> NDArray[np.complex128]:
        """Stage 2: return ``K*`` modified (amplitude or time dependence)."""
        raise NotImplementedError

    def disc_stiffness(self, ctx: Context, p: Mapping[str, float]) -> NDArray[np.complex128]:
        """Stage 3: dynamic stiffness (N/m) added to the disc's ``D_v``."""
        raise NotImplementedError

    def couple(
        self,
        ctx: Context,
        p: Mapping[str, float],
        d_table: NDArray[np.complex128],
        d_disc: NDArray[np.complex128],
    ) -> dict[str, NDArray[np.complex128]]:
        """Stage 4: receptances ``{"table": X_s/F_e, "support": X_v/F_v}`` (m/N)."""
        raise NotImplementedError

    def measure(
        self, ctx: Context, p: Mapping[str, float], frfs: dict[str, NDArray[np.complex128]]
    ) -> dict[str, NDArray[np.complex128]]:
        """Stage 5: return the measured accelerances changed by the measuring chain."""
        raise NotImplementedError

    def frame(self, ctx: Context, p: Mapping[str, float]) -> NDArray[np.complex128]:
        """The frame stage: dynamic stiffness (N/m) of the frame to ground (mass included)."""
        raise NotImplementedError

    def link_stiffness(self, p: Mapping[str, float]) -> float | None:
        """A coupling term's link stiffness between table and disc (N/m), for the frame stage;
        ``None`` when the term's coupling is not a spring."""
        return None

    # -- derivatives (optional: a model whose terms all give them is fitted with an analytic
    # Jacobian, Model.derivatives; a term that gives none makes the fitter take differences) --
    def disc_stiffness_derivatives(
        self, ctx: Context, p: Mapping[str, float]
    ) -> dict[str, NDArray[np.complex128]] | None:
        """Stage 3's ``∂ΔD_v/∂p`` (N/m per unit of ``p``) for every local parameter name;
        ``None`` (the default): unknown."""
        return None

    def couple_derivatives(
        self,
        ctx: Context,
        p: Mapping[str, float],
        d_table: NDArray[np.complex128],
        d_disc: NDArray[np.complex128],
    ) -> dict[str, dict[str, NDArray[np.complex128]]] | None:
        """Stage 4's derivatives of each receptance: per FRF, ``∂X/∂D_t`` (key ``"d_table"``),
        ``∂X/∂D_v`` (key ``"d_disc"``) and ``∂X/∂p`` for every local parameter name; ``None``
        (the default): unknown."""
        return None

    def measure_derivatives(
        self, ctx: Context, p: Mapping[str, float], frfs: Mapping[str, NDArray[np.complex128]]
    ) -> dict[str, tuple[NDArray[np.complex128], dict[str, NDArray[np.complex128]]]] | None:
        """Stage 5's derivatives, for a term that multiplies each FRF it changes by a factor
        ``s``: per FRF changed, ``(s, {local name: ∂(s H)/∂p})`` at the accelerances ``frfs``
        the stage receives; ``None`` (the default): unknown."""
        return None

    def frf_weights(self, frfs: Sequence[str]) -> dict[str, float] | None:
        """For a term whose effect has the same shape on every FRF it enters (a gain, a delay):
        its weight on each of ``frfs`` (``+1`` where it multiplies, ``−1`` where it divides),
        so that terms of one keyword whose weights are linearly dependent are refused: the
        data see only their combinations. ``None`` (the default): not such a term."""
        return None

    def takes_part_in(self, stage: str) -> bool:
        """The term overrides the stage method ``stage``."""
        return getattr(type(self), stage) is not getattr(Term, stage)

    # -- composition --------------------------------------------------------------------------
    def __add__(self, other: Term | Model) -> Model:
        return Model([self]) + other

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.spec}>"


class ModulusTerm(Term):
    """Base of the ``K*`` terms.

    Besides :meth:`Term.modulus`, a modulus term provides :meth:`start`, a start of its
    parameters and of the disc mass ``M_v`` from an estimate of the disc's dynamic stiffness
    ``D_v = K* − ω² M_v`` (which is linear in ``M_v``), so that no fit ever needs a user guess.
    """

    kind: ClassVar[str] = "modulus"
    #: The specimens hold a disc of mass ``M_v`` (False only for the bare table).
    has_disc: ClassVar[bool] = True

    def start(
        self,
        omega: NDArray[np.float64],
        d_disc: NDArray[np.complex128],
        weight: NDArray[np.float64],
    ) -> dict[str, float]:
        """Start values (local names, plus ``M_v``) from ``D_v`` samples and their weights."""
        raise NotImplementedError

    def resolved(self, omega: NDArray[np.float64], p: Mapping[str, float]) -> bool:
        """Whether data over ``omega`` (rad/s) pin each of these values (local names): False
        where only a combination of them shapes ``K*`` there, so that a fit started at them
        follows a long valley; a fitter then starts from :meth:`start` instead."""
        return True

    def modulus_derivatives(
        self, ctx: Context, p: Mapping[str, float]
    ) -> dict[str, NDArray[np.complex128]] | None:
        """Optional: ``∂K*/∂p`` (N/m per unit of ``p``) for every local parameter name, one
        complex value per point, so that a fitter can use an analytic Jacobian. ``None`` (the
        default) makes it use finite differences instead."""
        return None


TERMS: dict[str, type[Term]] = {}
"""The registry: spec keyword -> term class. Filled by :func:`register_term`."""


def register_term(cls: type[Term]) -> type[Term]:
    """Class decorator that makes a term known to :func:`parse_spec` under ``cls.keyword``."""
    if not re.fullmatch(r"[a-z][a-z0-9_]*", cls.keyword):
        raise ValueError(f"term keyword {cls.keyword!r} must be lower-case letters, digits, _")
    if cls.keyword in TERMS and TERMS[cls.keyword] is not cls:
        raise ValueError(f"term keyword {cls.keyword!r} is already registered")
    TERMS[cls.keyword] = cls
    return cls


#: The FRFs as the analyser's channels make them.
FRF_LABELS = {"table": "x_s/F_e", "support": "x_v/F_v"}

#: The table suspension, part of every model; fixed when a specimen run is identified.
TABLE_PARAMETERS = (
    Parameter("M_s", "kg", 1e-3, 1e4, 3.4, description="moving mass of the table"),
    Parameter("K_s", "N/m", 1e-3, 1e10, 5e4, description="suspension stiffness of the table"),
    Parameter("C_s", "N·s/m", 1e-6, 1e6, 5.0, description="suspension damping of the table"),
)
DISC_MASS = Parameter(
    "M_v", "kg", 1e-6, 1e3, 0.25, description="disc mass plus a third of the specimens' mass"
)


class Model:
    """A sum of terms with exactly one modulus term, predicting the rig's FRFs.

    Parameters are, in order: the table's ``M_s K_s C_s``, the modulus term's, the disc mass
    ``M_v`` (unless the bare table), then each effect term's in canonical order, suffixed
    ``_1``, ``_2``… when a keyword appears more than once.
    """

    def __init__(self, terms: Sequence[Term]) -> None:
        moduli = [term for term in terms if term.kind == "modulus"]
        if len(moduli) > 1:
            specs = ", ".join(term.spec for term in moduli)
            raise InputError(f"a model has exactly one K* term, got {specs}", "model spec")
        self.terms: tuple[Term, ...] = tuple(terms)
        self.modulus_term: ModulusTerm | None = moduli[0] if moduli else None  # type: ignore[assignment]
        order = {keyword: index for index, keyword in enumerate(TERMS)}
        self.effects: tuple[Term, ...] = tuple(
            sorted(
                (term for term in terms if term.kind != "modulus"),
                key=lambda term: (order.get(term.keyword, len(order)), term.sort_key()),
            )
        )
        self._check_effects()
        couplers = [term for term in self.effects if term.takes_part_in("couple")]
        if len(couplers) > 1:
            raise InputError("a model has at most one coupling term (load_cell)", "model spec")
        self._coupler = couplers[0] if couplers else None
        frames = [term for term in self.effects if term.takes_part_in("frame")]
        if len(frames) > 1:
            raise InputError("a model has at most one frame term", "model spec")
        self._frame = frames[0] if frames else None
        self._names: dict[int, dict[str, str]] = {}
        parameters = list(TABLE_PARAMETERS)
        if self.modulus_term is not None:
            parameters += self._claim(self.modulus_term, "")
            if self.modulus_term.has_disc:
                parameters.append(DISC_MASS)
        counts: dict[str, int] = {}
        for term in self.effects:
            counts[term.keyword] = counts.get(term.keyword, 0) + 1
        seen: dict[str, int] = {}
        for term in self.effects:
            seen[term.keyword] = seen.get(term.keyword, 0) + 1
            suffix = f"_{seen[term.keyword]}" if counts[term.keyword] > 1 else ""
            parameters += self._claim(term, suffix)
        names = [parameter.name for parameter in parameters]
        duplicated = sorted({name for name in names if names.count(name) > 1})
        if duplicated:
            raise InputError(f"parameter names clash: {', '.join(duplicated)}", "model spec")
        self.parameters: tuple[Parameter, ...] = tuple(parameters)
        self.by_name: dict[str, Parameter] = {p.name: p for p in parameters}
        self._stage_terms = {
            stage: [t for t in self.effects if t.takes_part_in(stage)]
            for stage in ("modify_modulus", "disc_stiffness", "measure")
        }

    def __reduce__(self) -> tuple[type[Model], tuple[tuple[Term, ...]]]:
        # rebuilt from its terms: the names are keyed by the terms' identities
        return type(self), (self.terms,)

    def _check_effects(self) -> None:
        """Refuse effects whose parameters no data can fit: the same term twice (unless
        :attr:`Term.repeatable`), a specimen's term on the bare table, and terms of one keyword
        that the FRFs see in fewer combinations than there are terms
        (:meth:`Term.frf_weights`: ``gain(F_e)+gain(x_s)`` act on ``x_s/F_e`` through their
        ratio alone)."""
        given = [term.spec for term in self.effects if not term.repeatable]
        repeated = sorted({spec for spec in given if given.count(spec) > 1})
        if repeated:
            raise InputError(
                f"'{repeated[0]}' is given more than once: the copies would add "
                "into one effect the data cannot split between them; give it once", "model spec")
        if self.modulus_term is not None and not self.modulus_term.has_disc:
            specimen = [term.spec for term in self.effects
                        if term.takes_part_in("modify_modulus") or term.takes_part_in("couple")]
            if specimen:
                raise InputError(
                    f"'{specimen[0]}' acts on the specimens (their K* or their link to the "
                    f"table) and '{self.modulus_term.spec}' has none: give it with a "
                    f"specimen's K* term, e.g. 'voigt+{specimen[0]}'", "model spec")
        frfs = self.frfs
        by_keyword: dict[str, list[tuple[Term, dict[str, float]]]] = {}
        for term in self.effects:
            weights = term.frf_weights(frfs)
            if weights is not None:
                by_keyword.setdefault(term.keyword, []).append((term, weights))
        for terms in by_keyword.values():
            matrix = np.array([[weights.get(frf, 0.0) for frf in frfs] for _, weights in terms])
            rank = int(np.linalg.matrix_rank(matrix))
            if rank == len(terms):
                continue
            seen = ", ".join(FRF_LABELS.get(frf, frf) for frf in frfs)
            idle = [term.spec for term, weights in terms
                    if not any(weights.get(frf, 0.0) for frf in frfs)]
            if idle:
                raise InputError(f"'{idle[0]}' acts on no FRF the model predicts ({seen})",
                                 "model spec")
            specs = " and ".join(f"'{term.spec}'" for term, _ in terms)
            raise InputError(
                f"{specs} act on the FRFs ({seen}) through {rank} combination"
                f"{'s' if rank > 1 else ''} only, which no data can split: give {rank} of them",
                "model spec")

    def _claim(self, term: Term, suffix: str) -> list[Parameter]:
        local = term.parameters()
        self._names[id(term)] = {p.name: p.name + suffix for p in local}
        return [p.renamed(p.name + suffix) for p in local]

    # -- description --------------------------------------------------------------------------
    @property
    def spec(self) -> str:
        """Canonical spec string: the K* term, then effects in registry order."""
        parts = [self.modulus_term.spec] if self.modulus_term else []
        return "+".join(parts + [term.spec for term in self.effects])

    @property
    def names(self) -> tuple[str, ...]:
        """Global parameter names, in order."""
        return tuple(parameter.name for parameter in self.parameters)

    @property
    def frfs(self) -> tuple[str, ...]:
        """Names of the FRFs this model predicts."""
        if self.modulus_term is None or not self.modulus_term.has_disc:
            return ("table",)
        return ("table", "support")

    @property
    def requires(self) -> tuple[str, ...]:
        """Context fields the model needs besides frequency."""
        return tuple(sorted({field for term in self.terms for field in term.requires}))

    @property
    def is_open(self) -> bool:
        """A term leaves a choice to the fitter (``maxwell`` without an order)."""
        return any(term.candidates() is not None for term in self.terms)

    def require_modulus(self) -> ModulusTerm:
        """The K* term; ``InputError`` for a model without one (the bare table)."""
        if self.modulus_term is None:
            raise InputError(f"'{self.spec}' has no K* term", "model spec")
        return self.modulus_term

    def local_names(self, term: Term) -> dict[str, str]:
        """Local -> global parameter names of one of the model's terms."""
        return dict(self._names[id(term)])

    def defaults(self) -> dict[str, float]:
        """Every parameter at its default value."""
        return {parameter.name: parameter.default for parameter in self.parameters}

    def candidates(self) -> list[Model]:
        """Concrete models to choose from (one, unless a term leaves a choice open)."""
        variants: list[list[Term]] = [[]]
        for term in self.terms:
            options = term.candidates() or [term]
            variants = [[*done, option] for done in variants for option in options]
        return [Model(terms) for terms in variants]

    def local_values(self, term: Term, values: Mapping[str, float]) -> dict[str, float]:
        """The values of one term's parameters under its local names."""
        return {local: values[name] for local, name in self._names[id(term)].items()}

    # -- evaluation ---------------------------------------------------------------------------
    def kstar(self, ctx: Context, values: Mapping[str, float]) -> NDArray[np.complex128]:
        """``K*(ω)`` after the modifiers (stages 1 and 2), N/m."""
        if self.modulus_term is None:
            return np.zeros(ctx.omega.shape, dtype=complex)
        kstar = np.asarray(
            self.modulus_term.modulus(ctx, self.local_values(self.modulus_term, values)),
            dtype=complex,
        )
        for term in self._stage_terms["modify_modulus"]:
            kstar = term.modify_modulus(ctx, self.local_values(term, values), kstar)
        return kstar

    def disc_dynamic_stiffness(
        self, ctx: Context, values: Mapping[str, float]
    ) -> NDArray[np.complex128]:
        """``D_v = K* − ω² M_v + additions`` (stages 1 to 3), N/m."""
        d_disc = self.kstar(ctx, values)
        if self.modulus_term is not None and self.modulus_term.has_disc:
            d_disc = d_disc - ctx.omega**2 * values["M_v"]
        for term in self._stage_terms["disc_stiffness"]:
            d_disc = d_disc + term.disc_stiffness(ctx, self.local_values(term, values))
        return d_disc

    def predict(
        self, ctx: Context, values: Mapping[str, float]
    ) -> dict[str, NDArray[np.complex128]]:
        """Predicted accelerances ``{"table": ẍ_s/F_e, "support": ẍ_v/F_v}`` in m/s²/N.

        ``values`` maps every global parameter name to its value (see :meth:`defaults`).
        """
        if self.is_open:
            raise InputError(f"'{self.spec}' leaves a choice open; fit it first", "model spec")
        w = ctx.omega
        d_disc = self.disc_dynamic_stiffness(ctx, values)
        d_table = table_dynamic_stiffness(ctx.omega, values)
        if self._frame is not None:
            receptance = self._on_frame(ctx, values, d_table, d_disc)
        elif self._coupler is not None:
            receptance = self._coupler.couple(
                ctx, self.local_values(self._coupler, values), d_table, d_disc
            )
        else:
            receptance = {"table": 1.0 / (d_table + d_disc)}
            if "support" in self.frfs:
                receptance["support"] = 1.0 / d_disc
        frfs = {name: -(w**2) * receptance[name] for name in self.frfs}
        for term in self._stage_terms["measure"]:
            frfs = term.measure(ctx, self.local_values(term, values), frfs)
        return frfs

    def derivatives(
        self,
        ctx: Context,
        values: Mapping[str, float],
        names: Sequence[str],
        predicted: Mapping[str, NDArray[np.complex128]] | None = None,
    ) -> dict[str, NDArray[np.complex128]] | None:
        """``∂H/∂p`` of each predicted accelerance (points × ``len(names)``, m/s²/N per unit of
        each parameter of ``names``, global names), through the stages of :meth:`predict`;
        ``None`` where a term gives no derivatives of its stage (the frame, the modifiers of
        ``K*``, a term without them): a fitter then takes finite differences. ``predicted``:
        :meth:`predict` at ``values``, when at hand (with a rigid link and no measuring term, the
        receptances are read from it, not evaluated again)."""
        if (self.is_open or self._frame is not None or self._stage_terms["modify_modulus"]
                or self.modulus_term is None):
            return None
        w = ctx.omega
        w2 = w * w
        term = self.modulus_term
        own = term.modulus_derivatives(ctx, self.local_values(term, values))
        if own is None:
            return None
        by_disc: dict[str, NDArray[Any] | complex] = self._global(term, own)
        if term.has_disc:
            by_disc["M_v"] = -w2
        asked = set(names)
        for effect in self._stage_terms["disc_stiffness"]:
            if asked.isdisjoint(self._names[id(effect)].values()):
                continue  # held: its addition to D_v reaches the others through D_v alone
            own = effect.disc_stiffness_derivatives(ctx, self.local_values(effect, values))
            if own is None:
                return None
            by_disc.update(self._global(effect, own))
        by_table: dict[str, NDArray[Any] | complex] = {"M_s": -w2, "K_s": 1.0, "C_s": 1j * w}
        if self._coupler is None:
            if predicted is not None and not self._stage_terms["measure"]:
                receptance = {frf: predicted[frf] / -w2 for frf in self.frfs}
            else:
                d_disc = self.disc_dynamic_stiffness(ctx, values)
                d_table = table_dynamic_stiffness(ctx.omega, values)
                receptance = {"table": 1.0 / (d_table + d_disc)}
                if "support" in self.frfs:
                    receptance["support"] = 1.0 / d_disc
            chain = {"table": {"d_table": -(receptance["table"] ** 2),
                               "d_disc": -(receptance["table"] ** 2)}}
            if "support" in self.frfs:
                chain["support"] = {"d_disc": -(receptance["support"] ** 2)}
        else:
            d_disc = self.disc_dynamic_stiffness(ctx, values)
            d_table = table_dynamic_stiffness(ctx.omega, values)
            local = self.local_values(self._coupler, values)
            coupled = self._coupler.couple_derivatives(ctx, local, d_table, d_disc)
            if coupled is None:
                return None
            if self._stage_terms["measure"]:
                receptance = self._coupler.couple(ctx, local, d_table, d_disc)
            names_of = self._names[id(self._coupler)]  # "d_table", "d_disc" are kept as they are
            chain = {frf: {names_of.get(key, key): d for key, d in by.items()}
                     for frf, by in coupled.items()}
        # rows: one parameter each (contiguous), turned to points × parameters at the end
        column = {name: j for j, name in enumerate(names)}
        stages = {"d_table": self._rows(by_table, column, w.size),
                  "d_disc": self._rows(by_disc, column, w.size)}
        out = {}
        for frf in self.frfs:
            rows = np.zeros((len(column), w.size), dtype=complex)
            for key, d in chain[frf].items():
                if key in stages:
                    stage = stages[key]
                    if stage is not None:
                        rows += (d * -w2) * stage
                elif key in column:
                    rows[column[key]] += d * -w2
            out[frf] = rows
        if self._stage_terms["measure"]:
            frfs = {frf: -w2 * receptance[frf] for frf in self.frfs}
        for effect in self._stage_terms["measure"]:
            measured = effect.measure_derivatives(ctx, self.local_values(effect, values), frfs)
            if measured is None:
                return None
            for frf, (factor, own) in measured.items():
                out[frf] *= factor
                for name, d in self._global(effect, own).items():
                    if name in column:
                        out[frf][column[name]] += d
                frfs[frf] = factor * frfs[frf]
        return {frf: rows.T for frf, rows in out.items()}

    @staticmethod
    def _rows(by_name: Mapping[str, Any], column: Mapping[str, int], points: int
              ) -> NDArray[np.complex128] | None:
        """``by_name``'s derivatives as rows in ``column``'s order (zero elsewhere); ``None``
        where none of them is asked for."""
        asked = [name for name in by_name if name in column]
        if not asked:
            return None
        rows = np.zeros((len(column), points), dtype=complex)
        for name in asked:
            rows[column[name]] = by_name[name]
        return rows

    def _global(self, term: Term, by_local: Mapping[str, Any]) -> dict[str, Any]:
        """``by_local`` keyed by the term's global parameter names."""
        names = self._names[id(term)]
        return {names[local]: value for local, value in by_local.items()}

    def _on_frame(
        self,
        ctx: Context,
        values: Mapping[str, float],
        d_table: NDArray[np.complex128],
        d_disc: NDArray[np.complex128],
    ) -> dict[str, NDArray[np.complex128]]:
        """Receptances with the frame as a body (see the module text and ``Frame``).

        Absolute displacements ``x_s`` (table), ``x_v`` (disc), ``x_g`` (frame). The suspension
        ``S = K_s + iωC_s`` and the specimens ``K*`` act between their body and the frame, the
        masses (and modes attached to the disc) on inertial space, the shaker pushes the table
        with ``F_e`` and the frame with ``−F_e``, and the frame sits on ``G`` to ground.
        """
        w = ctx.omega
        frame = self._frame
        assert frame is not None
        g = frame.frame(ctx, self.local_values(frame, values))
        s = values["K_s"] + 1j * w * values["C_s"]
        a_table = d_table - s
        kstar = self.kstar(ctx, values) if "support" in self.frfs else np.zeros_like(w)
        a_disc = d_disc - kstar  # the disc's inertia and what is attached to it
        k_c = None
        if self._coupler is not None:
            k_c = self._coupler.link_stiffness(self.local_values(self._coupler, values))
            if k_c is None:
                raise InputError(
                    f"'{self._coupler.spec}' cannot be combined with a frame term", "model spec"
                )
        if "support" not in self.frfs:  # the bare table on the frame
            return {"table": 1.0 / (a_table + s * (1.0 + a_table / g))}
        if k_c is None:  # rigid link: table and disc move as one
            a = a_table + a_disc
            spring = s + kstar
            return {
                "table": 1.0 / (a + spring * (1.0 + a / g)),
                "support": 1.0 / (a_disc + kstar * (1.0 + a / g)),
            }
        # The symmetric 3x3 system of table, disc and frame, solved by its cofactors for the
        # force (1, 0, −1) in one vectorised expression: a batched LAPACK solve of 3x3 systems
        # took most of a frame model's evaluation. The load cell's stretch x_s − x_v is
        # written without k_c, which would cancel there (1.8·10⁻¹⁰ relative error at most
        # against extended precision, where the solve left 2.2·10⁻¹⁰).
        a00, a01, a02 = a_table + s + k_c, -k_c, -s
        a11, a12, a22 = a_disc + kstar + k_c, -kstar, g + s + kstar
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a11 * a02
        c12 = a01 * a02 - a00 * a12
        det = a00 * c00 + a01 * c01 + a02 * c02
        disc, table = a_disc + kstar, a_table + s
        stretch = (disc * a22 - kstar * (kstar + s)) - (s * disc - kstar * table)
        return {"table": (c00 - c02) / det, "support": (c01 - c12) / (k_c * stretch)}

    # -- composition --------------------------------------------------------------------------
    def __add__(self, other: Term | Model) -> Model:
        if isinstance(other, Model):
            return Model(self.terms + other.terms)
        if isinstance(other, Term):
            return Model((*self.terms, other))
        return NotImplemented

    def __iter__(self) -> Iterator[Term]:
        return iter(self.terms)

    def __repr__(self) -> str:
        return f"<Model {self.spec}>"


def _format_number(value: float) -> str:
    """Shortest text of a number that reads back to the same value (58.0 -> '58')."""
    return f"{int(value)}" if float(value).is_integer() else repr(float(value))


def stage_methods() -> tuple[str, ...]:
    """Names of the pipeline stage methods, in evaluation order."""
    return ("modulus", "modify_modulus", "disc_stiffness", "frame", "couple", "measure")
