"""Instance and variable names, and "instance.variable" references.

SSP and FMI allow instance names such as ``0001_em``, ``edrive-mass`` or,
once nested systems are flattened, ``sub.comp``; FMI variable names may be
dotted (``MLoad.k``), derivatives (``der(x)``) or array elements
(``a[1]``). A reference "instance.variable" is therefore split against the
instance names that exist, the longest one first, never at the first dot.
This module is the one place that does it (links, ``record``, ``--set``,
plots).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Set

_FORBIDDEN = ("/", "\\", "->")  # a path separator would leave the output folder; -> separates a link


def instance_name_problem(name: object) -> str | None:
    """What is wrong with an instance name, or None when it is allowed."""
    if not isinstance(name, str) or not name:
        return "expected a non-empty instance name"
    if name != name.strip() or name.startswith(".") or name.endswith("."):
        return "expected an instance name without surrounding spaces or dots"
    if any(ord(ch) < 32 or ord(ch) == 127 for ch in name):
        return "expected an instance name without control characters"
    for bad in _FORBIDDEN:
        if bad in name:
            return f"expected an instance name without {bad!r}"
    return None


def split_ref(ref: str, instances: Iterable[str] | Mapping[str, object]) -> tuple[str, str] | None:
    """(instance, variable) of "instance.variable", or None.

    The longest instance name that is followed by a dot wins; when
    `instances` maps names to their variables (anything supporting ``in``),
    a prefix whose rest is not one of its variables gives way to a shorter
    one that fits, so that instances ``a`` and ``a.b`` can both be referred
    to.
    """
    ref = ref.strip()
    known = instances if isinstance(instances, (Mapping, Set)) else set(instances)
    # The prefixes before each dot, longest first: a few lookups, whatever
    # the number of instances (systems have thousands).
    candidates = [ref[:i] for i in range(len(ref) - 2, 0, -1) if ref[i] == "." and ref[:i] in known]
    if not candidates:
        return None
    if isinstance(instances, Mapping):
        for name in candidates:
            variables = instances[name]
            if variables is None or ref[len(name) + 1:] in variables:
                return name, ref[len(name) + 1:]
    name = candidates[0]
    return name, ref[len(name) + 1:]


def split_link(text: str) -> tuple[str, str] | None:
    """The two references of "src.output -> dst.input", or None."""
    parts = text.split("->")
    if len(parts) != 2:
        return None
    src, dst = (p.strip() for p in parts)
    return (src, dst) if src and dst else None
