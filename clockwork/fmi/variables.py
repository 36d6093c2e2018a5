"""The variables as the master sees them: one read-only table per model
description, with each output's direct-feedthrough inputs.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from types import MappingProxyType


from .description import var_unit


@dataclass
class Variable:
    name: str
    vr: int
    type: str
    causality: str
    variability: str
    unit: str | None
    dependencies: list[str] | None  # the inputs an output depends on directly (outputs only; else None)
    shape: tuple[int, ...] = ()  # an FMI 3.0 array's shape; () for a scalar or an element
    array: str | None = None  # an array element's array (its vr is the element's code, fmu3.Instance3)
    index: int = 0  # an array element's place in its array's values (row-major)


def direct_feedthrough(md) -> dict[str, list[str]]:
    """{output: the inputs it depends on directly}, from the ModelStructure.

    Only a dependency on a variable of causality "input" is direct
    feedthrough: outputs that depend on states, parameters or locals only
    (a Dymola motor's current, a pendulum's angle) are known at the
    communication point without their inputs. A missing `dependencies`
    attribute means "depends on all knowns" (FMI 2.0, 3.3.2), hence on every
    input. Every dependenciesKind is a dependency, so the kinds do not matter.
    """
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    return {u.variable.name: list(inputs) if u.dependencies is None
            else [d.name for d in u.dependencies if d.causality == "input"] for u in md.outputs}

# (per FMU file), shared read-only by all its instances.
_INSTANCE_VARIABLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def instance_variables(md) -> MappingProxyType:
    """{name: Variable} of a model description, built on first use."""
    table = _INSTANCE_VARIABLES.get(md)
    if table is None:
        deps = direct_feedthrough(md)
        table = _INSTANCE_VARIABLES[md] = MappingProxyType({
            v.name: Variable(v.name, v.valueReference, v.type, v.causality, v.variability, var_unit(v),
                             deps.get(v.name))
            for v in md.modelVariables})
    return table
