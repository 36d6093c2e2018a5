"""The Python API's arguments, checked where they enter.

A public function or method declares what each argument must be with
``@checked(name=Spec, ...)``; a call that gives something else, leaves out
a required argument or names one that does not exist raises one
``UsageError`` naming the call, the argument, the value (shortened) and
what was expected, before anything is done: never the TypeError,
ValueError or AttributeError of some line deep inside. ``checked`` keeps
the declaration on the function (``__arguments__``), so that the tests
can give every declared argument values of every other kind
(``Spec.refused``).

The specs check the shape (a string, a finite number, a mapping of names
to something); what only the FMUs know (does the variable exist, is it a
Real) the engine checks next, with the same kind of line.
"""

from __future__ import annotations

import functools
import inspect
import math
import numbers
import os

from .errors import UsageError
from .numbers import shorten


class Spec:
    """What an argument must be: `what` says it in the error line."""

    what = "a value"

    def accepts(self, value) -> bool:
        raise NotImplementedError

    def refused(self) -> list:
        """Values this spec refuses (for the tests: one of each other kind)."""
        out = []
        for v in _samples():
            try:
                ok = self.accepts(v)
            except Exception:  # a hostile sample: what safe_check refuses
                ok = False
            if not ok:
                out.append(v)
        return out

    def check(self, where: str, value):
        if not self.accepts(value):
            raise UsageError(f"{where} = {show(value)}: expected {self.what}")
        return value

    def safe_check(self, where: str, value):
        """check(), with whatever a hostile value raises while it is looked
        at (a __float__, __iter__, __len__ or items() that fails) refused
        as the value is: one UsageError naming the argument."""
        try:
            return self.check(where, value)
        except UsageError:
            raise
        except RecursionError:
            raise UsageError(f"{where} = {show(value)}: expected {self.what} (nested too deep to read)") from None
        except Exception as e:
            raise UsageError(f"{where} = {show(value)}: expected {self.what} (reading it raised "
                             f"{type(e).__name__})") from None


def show(value) -> str:
    """A value as an error line echoes it: its repr, at most about 80 characters."""
    try:
        text = repr(value)
    except Exception:  # a hostile __repr__ must not replace the error
        text = f"<{type(value).__name__}>"
    return shorten(text, 80)


class Anything(Spec):
    """Any value (what it must be is checked later, e.g. against an FMU variable's type)."""

    def __init__(self, what: str = "a value"):
        self.what = what

    def accepts(self, value) -> bool:
        return True


class Text(Spec):
    def __init__(self, what: str = "a string", empty: bool = False):
        self.what, self.empty = what, empty

    def accepts(self, value) -> bool:
        return isinstance(value, str) and (self.empty or bool(value))


class Choice(Spec):
    """One of a few strings (a str subclass by its characters: its own __eq__ is not asked)."""

    def __init__(self, *choices: str):
        self.choices = choices
        self.what = " or ".join(map(repr, choices))

    def accepts(self, value) -> bool:
        return isinstance(value, str) and str.__str__(value) in self.choices


class Real(Spec):
    """A real number (int, float or a numpy number; not a bool, not NaN)."""

    def __init__(self, what: str = "a finite number", finite: bool = True, positive: bool = False):
        self.what, self.finite, self.positive = what, finite, positive

    def accepts(self, value) -> bool:
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            return False
        try:
            x = float(value)
        except Exception:  # 10**400, a Real whose __float__ fails (any way it likes)
            return False
        if math.isnan(x) or (self.finite and math.isinf(x)):
            return False
        return x > 0 if self.positive else True


class Integer(Spec):
    """A whole number a C int64 holds (int or a numpy integer; not a bool)."""

    def __init__(self, what: str = "a whole number"):
        self.what = what

    def accepts(self, value) -> bool:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            return False
        try:
            n = int(value)
        except Exception:  # an Integral whose __int__ fails
            return False
        return type(n) is int and -2**63 <= n < 2**63


class Flag(Spec):
    what = "true or false (a bool)"

    def accepts(self, value) -> bool:
        # numpy's too: numpy.bool_ (numpy 2 calls it numpy.bool), without importing numpy here
        return isinstance(value, bool) or (type(value).__module__ == "numpy" and type(value).__name__ in ("bool_", "bool"))


class Path(Spec):
    """A path: a string or an os.PathLike (pathlib.Path)."""

    def __init__(self, what: str = "a path (a string or pathlib.Path)"):
        self.what = what

    def accepts(self, value) -> bool:
        return fspath(value) is not None


def fspath(value) -> str | None:
    """A path argument as a plain str (a str subclass's own text, an
    os.PathLike's __fspath__ called once): None when it is empty, bytes,
    or its __fspath__ fails or gives something else."""
    if not isinstance(value, (str, os.PathLike)):
        return None
    try:
        text = os.fspath(value)
    except Exception:
        return None
    if not isinstance(text, str):
        return None
    text = str.__str__(text)  # the characters, whatever a subclass's __str__ says
    return text or None


class Call(Spec):
    what = "a function (a callable)"

    def accepts(self, value) -> bool:
        return callable(value)


class Instance(Spec):
    """An object of one of `classes` (checked by isinstance)."""

    def __init__(self, classes, what: str):
        self.classes, self.what = classes, what

    def accepts(self, value) -> bool:
        return isinstance(value, self.classes)


class Optional(Spec):
    def __init__(self, spec: Spec):
        self.spec = spec
        self.what = f"{spec.what}, or None"

    def accepts(self, value) -> bool:
        return value is None or self.spec.accepts(value)


class Either(Spec):
    def __init__(self, *specs: Spec, what: str | None = None):
        self.specs = specs
        self.what = what or " or ".join(s.what for s in specs)

    def accepts(self, value) -> bool:
        return any(s.accepts(value) for s in self.specs)


class Mapping(Spec):
    """A dict whose keys and values each match their spec."""

    def __init__(self, key: Spec, value: Spec, what: str):
        self.key, self.value, self.what = key, value, what

    def accepts(self, value) -> bool:
        return isinstance(value, dict) and all(self.key.accepts(k) and self.value.accepts(v)
                                               for k, v in value.items())

    def check(self, where: str, value):
        if not isinstance(value, dict):
            raise UsageError(f"{where} = {show(value)}: expected {self.what}")
        for k, v in value.items():
            if not self.key.accepts(k):
                raise UsageError(f"{where}: the key {show(k)}: expected {self.key.what} (in {self.what})")
            self.value.check(f"{where}[{k!r}]", v)
        return value


class Sequence(Spec):
    """A list or tuple whose every item matches `item` (not a string)."""

    def __init__(self, item: Spec, what: str, length: tuple[int, int] | None = None):
        self.item, self.what, self.length = item, what, length

    def _shape(self, value) -> bool:
        if not isinstance(value, (list, tuple)):
            return False
        return self.length is None or self.length[0] <= len(value) <= self.length[1]

    def accepts(self, value) -> bool:
        if isinstance(self.item, Anything):  # the items are checked later: no walk over them here
            return self._shape(value)
        return self._shape(value) and all(self.item.accepts(x) for x in value)

    def check(self, where: str, value):
        if not self._shape(value):
            raise UsageError(f"{where} = {show(value)}: expected {self.what}")
        if not isinstance(self.item, Anything):
            for i, x in enumerate(value):
                self.item.check(f"{where}[{i}]", x)
        return value


class Tuple(Spec):
    """A list or tuple of fixed kinds by position; the last `optional` may be left out."""

    def __init__(self, *items: Spec, what: str, optional: int = 0):
        self.items, self.what, self.optional = items, what, optional

    def _shape(self, value) -> bool:
        return isinstance(value, (list, tuple)) and len(self.items) - self.optional <= len(value) <= len(self.items)

    def accepts(self, value) -> bool:
        return self._shape(value) and all(s.accepts(x) for s, x in zip(self.items, value))

    def check(self, where: str, value):
        if not self._shape(value):
            raise UsageError(f"{where} = {show(value)}: expected {self.what}")
        for i, (s, x) in enumerate(zip(self.items, value)):
            if not s.accepts(x):
                raise UsageError(f"{where}[{i}] = {show(x)}: expected {s.what} (in {self.what})")
        return value


class _FloatRaises(float):
    """A float whose conversion raises (a hostile number)."""

    def __float__(self):
        raise RuntimeError("__float__")

    def __repr__(self):
        return "_FloatRaises()"


class _IntRaises(int):
    def __int__(self):
        raise RuntimeError("__int__")

    __index__ = __int__

    def __repr__(self):
        return "_IntRaises()"


class _PathRaises:
    def __fspath__(self):
        raise RuntimeError("__fspath__")


class _IterRaises:
    def __iter__(self):
        raise RuntimeError("__iter__")


class _ItemsRaise(dict):
    def items(self):
        raise RuntimeError("items")


# One value of every kind a caller might give by mistake, and hostile
# objects whose conversion or reading raises (refused as the value is).
def _samples() -> list:
    import decimal  # for the tests only: not on every command's start-up path

    return ["", "abc", 42, -1, 0, 1.5, math.nan, math.inf, True, None, [1, 2], ("a", "b"), {"a": 1}, b"x",
            object(), len, 10**400, -10**400, 1 + 2j, decimal.Decimal("1.5"), {1, 2}, bytearray(b"x"),
            _FloatRaises(1.5), _IntRaises(2), _PathRaises(), _IterRaises(), _ItemsRaise(a=1)]


def checked(**specs: Spec):
    """Decorator: check the named arguments of each call against their
    specs (a default that is not given is not checked), and the call's
    shape (too many arguments, a missing or unknown one), raising one
    UsageError naming the function and the argument."""
    def wrap(func):
        sig = inspect.signature(func)
        params = list(sig.parameters.values())
        names = [p.name for p in params]
        unknown = set(specs) - set(names)
        if unknown:
            raise TypeError(f"{func.__qualname__}: no argument {', '.join(sorted(unknown))}")
        positional = [p.name for p in params
                      if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
        required = {p.name for p in params if p.default is p.empty
                    and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
        var_kw = any(p.kind == p.VAR_KEYWORD for p in params)
        var_pos = any(p.kind == p.VAR_POSITIONAL for p in params)
        known = set(names)
        keyword_required = [p.name for p in params if p.kind == p.KEYWORD_ONLY and p.default is p.empty]
        method = bool(positional) and positional[0] == "self"
        call = func.__qualname__.replace(".__init__", "")
        index = {n: positional.index(n) for n in specs if n in positional}

        @functools.wraps(func)
        def wrapper(*args, **kwargs):
            if len(args) > len(positional) and not var_pos:
                _refuse_shape(call, method, positional, names, args, {})
            if kwargs:
                if not var_kw and not kwargs.keys() <= known:
                    _refuse_shape(call, method, positional, names, args, kwargs)
                twice = [n for n in positional[:len(args)] if n in kwargs]
                if twice:
                    raise UsageError(f"{call}(): the argument {twice[0]} is given twice (by position and by name)")
            for i, n in enumerate(positional):
                if i >= len(args) and n in required and n not in kwargs:
                    raise UsageError(f"{call}(): the argument {n} is missing")
            for n in keyword_required:
                if n not in kwargs:
                    raise UsageError(f"{call}(): the argument {n} is missing")
            for name, spec in specs.items():
                i = index.get(name)
                if i is not None and i < len(args):
                    spec.safe_check(f"{call}(): {name}", args[i])
                elif name in kwargs:
                    spec.safe_check(f"{call}(): {name}", kwargs[name])
            return func(*args, **kwargs)

        wrapper.__arguments__ = dict(specs)
        return wrapper

    return wrap


def _refuse_shape(call, method, positional, names, args, kwargs) -> None:
    extra = [k for k in kwargs if k not in names]
    if extra:
        import difflib

        close = difflib.get_close_matches(extra[0], names, n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise UsageError(f"{call}(): no argument named {extra[0]}{hint}; "
                         f"the arguments are {', '.join(n for n in names if n != 'self')}")
    given = len(args) - method
    most = len(positional) - method
    raise UsageError(f"{call}(): {given} positional arguments, at most {most} "
                     f"({', '.join(n for n in positional if n != 'self')})")


def public_calls(*owners) -> dict[str, object]:
    """{qualified name: function} of every `checked` function or method of
    the given modules or classes: the API the tests give hostile arguments."""
    out = {}
    for owner in owners:
        for name, obj in vars(owner).items():
            if hasattr(obj, "__arguments__"):
                out[f"{getattr(owner, '__qualname__', owner.__name__)}.{name}"] = obj
    return out
