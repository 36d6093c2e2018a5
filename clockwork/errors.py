"""Exceptions with one-line messages meant for the user.

Every error clockwork raises on purpose is a `ClockworkError`:

- `SceneError`: a scene file, an override or a setting that is malformed;
- `UsageError`: bad use of the command line or of the Python API (an unknown
  instance or variable, a stop time that is not finite or lies in the past);
  `ClosedError`, a subclass, for a System used after it was freed;
- `SimulationError`: a run that failed (an FMU error, divergence).

A run that runs out of a resource (disk space, a file size limit, memory)
ends in Python's own OSError or MemoryError; the CLI reports it as a failed
run (exit code 1) naming the file.

The CLI prints `clockwork: error: <str(exc)>` and exits with 2 for
`SceneError`/`UsageError` (bad input) and 1 for `SimulationError` (a run
that failed).
"""

from __future__ import annotations

import re


class ClockworkError(Exception):
    """Base class of every error clockwork raises on purpose; str() is a
    single line, meant for the user as it is."""


class SceneError(ClockworkError):
    """A scene file (or a --set override) that is malformed or inconsistent,
    and a bad setting or FMU in the Python API (``MasterSettings(step=0)``, a
    missing FMU file): bad input, exit code 2 on the command line.

    str() joins `path`, `key` and `detail` into one line.

    Attributes:
        path: The scene (or SSP, FMU) file, or None.
        key: The dotted key (e.g. ``components.pendulum.parameters.L``,
            ``connections[2]``, ``--set pendulum.L``, ``master.step``), or None.
        detail: What was wrong or expected.
    """

    def __init__(self, detail: str, path: object = None, key: str | None = None):
        self.path = None if path is None else str(path)
        self.key = key
        self.detail = _one_line(detail)
        parts = [p for p in (self.path, self.key) if p]
        super().__init__(printable(": ".join(parts + [self.detail])))


class UsageError(ClockworkError):
    """Bad use of the command line or of the Python API, or an unusable
    output directory: an unknown instance or variable (named, with the
    nearest name), an output neither connected nor recorded, a stop time
    that is not finite or lies in the past. Bad input, exit code 2 on the
    command line."""

    def __init__(self, message: str):
        super().__init__(_one_line(message))


class ClosedError(UsageError):
    """A System (or its master) used after its `with` block or `free()`."""


class SimulationError(ClockworkError):
    """A run that failed (an FMU returned an error, a step did not converge,
    an output became NaN, infinite or diverged): exit code 1 on the command
    line. str() starts with the time, instance and variable where known.

    Attributes:
        message: What failed (an FMU's error with the FMU's own message).
        time: The communication point where it failed, s, or None.
        instance: The instance that failed, or None.
        variable: The variable, or None.
    """

    def __init__(self, message: str, time: float | None = None,
                 instance: str | None = None, variable: str | None = None):
        self.message = _one_line(message)
        self.time = time
        self.instance = instance
        self.variable = variable
        where = []
        if time is not None:
            where.append(f"t = {time!r} s")
        if instance is not None:
            where.append(instance if variable is None else f"{instance}.{variable}")
        prefix = ", ".join(where) + ": " if where else ""
        super().__init__(printable(prefix + self.message))


class SimulationEnded(SimulationError):
    """An FMU ended the simulation (FMI 2.0: fmi2Discard with fmi2Terminated,
    4.2.3; FMI 3.0: terminateSimulation): a clean end, not a failure of the
    master. The results up to `time` (the last communication point, s)
    stand; `fmu_time` is where the FMU stopped (its last successful time), s."""

    def __init__(self, message: str, time: float | None = None, instance: str | None = None,
                 fmu_time: float | None = None):
        super().__init__(message, time=time, instance=instance)
        self.fmu_time = fmu_time


class ParametersRefused(SimulationError):
    """An FMU refused the parameter values it was given (setting them, or its
    cross-parameter checks at the end of initialization): bad input, which the
    run layer reports against the scene file."""


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the process is, like Ctrl-C's
    KeyboardInterrupt, so that the same cleanup runs (clockwork.cli installs
    the handlers). `signo` is the signal's number."""

    def __init__(self, signo: int):
        super().__init__(signo)
        self.signo = signo


def _one_line(text: str) -> str:
    return printable(" ".join(str(text).split()))


# What a terminal acts on or a reader cannot see: C0 controls, DEL, C1
# controls (0x9b is a CSI on its own), the bidirectional overrides and
# isolates (they reorder what follows them on the line), the line and
# paragraph separators, and lone surrogates (a file name's undecodable
# bytes, which the terminal's encoder would refuse).
_UNPRINTABLE = "[\x00-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028-\u202e\u2066-\u2069\ud800-\udfff]"


def _escape(m: re.Match) -> str:
    c = ord(m.group())
    return f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}"


def printable(text: object) -> str:
    """`text` with every character that a terminal would act on (an escape
    sequence, a carriage return, a bidirectional override) written as a
    visible escape, ``\\x1b`` or ``\\u202e``: text from a file (a variable
    name, a CSV header, a unit) quoted in a line on stderr or in a plot."""
    # re caches the compiled pattern: compiled on the first message, not at every start-up
    return re.sub(_UNPRINTABLE, _escape, str(text))


def say(kind: str, text: object) -> None:
    """One line ``clockwork: <kind>: <text>`` on stderr (kind: error,
    warning or note), its blanks collapsed and its control characters
    escaped (``printable``): the one way such a line is printed."""
    import sys

    print(f"clockwork: {kind}: {_one_line(text)}", file=sys.stderr)
