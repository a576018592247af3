"""Terms from other packages, through the ``viscorig.terms`` entry-point group.

A package that defines its own effect (or K*) term declares it in its ``pyproject.toml``::

    [project.entry-points."viscorig.terms"]
    dry_friction = "viscorig_dry_friction:DryFriction"

The value names a :class:`~viscorig.models.base.Term` subclass (registered here when it is not
already) or a module whose import registers its terms with
:func:`~viscorig.models.base.register_term`. Entry points are loaded once, the first time a
spec names a keyword the registry does not know, so installing the package is all it takes for
``--model voigt+dry_friction`` to work, and a package that is installed but never named costs
nothing. A package that fails to load is named in the "unknown term" error instead of breaking
every other model.
"""

from __future__ import annotations

import logging
from importlib.metadata import EntryPoint, entry_points
from types import ModuleType

from viscorig.models.base import TERMS, Term, register_term

#: The entry-point group viscorig reads terms from.
GROUP = "viscorig.terms"

_log = logging.getLogger(__name__)
_problems: list[str] | None = None


def _register(point: EntryPoint) -> str | None:
    """Load one entry point; ``None`` when it worked, else why not (one line)."""
    try:
        loaded = point.load()
    except Exception as error:  # a broken third-party package must not break the others
        return f"{point.value} ({type(error).__name__}: {error})"
    if isinstance(loaded, ModuleType):
        return None
    if isinstance(loaded, type) and issubclass(loaded, Term):
        if TERMS.get(loaded.keyword) is loaded:
            return None
        try:
            register_term(loaded)
        except ValueError as error:
            return f"{point.value} ({error})"
        return None
    return f"{point.value} (neither a Term subclass nor a module)"


def load_entry_point_terms() -> list[str]:
    """Load every term of the ``viscorig.terms`` group (once); return the problems met.

    Returns
    -------
    list of str
        One line per entry point that could not be loaded, ``"name = value (reason)"``.
    """
    global _problems
    if _problems is None:
        _problems = []
        for point in entry_points(group=GROUP):
            problem = _register(point)
            if problem is None:
                _log.debug("term entry point %s = %s loaded", point.name, point.value)
            else:
                _log.info("term entry point %s = %s", point.name, problem)
                _problems.append(f"{point.name} = {problem}")
    return list(_problems)
