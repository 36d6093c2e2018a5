"""The test FMUs written by hand in C under tests/data (hostile.c, bouncer.c,
strict.c, alltypes.c, linear.c, clocked.c): what each build needs besides its source
and compiler flags, which tests/CMakeLists.txt holds. For the build NAME,

    python tests/c_fmus.py NAME OUT_DIR

writes OUT_DIR/modelDescription.xml and OUT_DIR/stubs.c (the FMI functions
the source leaves out, each failing: fmpy binds every symbol). CMake builds
them with the other test FMUs into build/test-fmus (FMI 3.0 ones into its
fmi3/ folder); tests find them with cwtest.test_fmu("Name") or
test_fmu("fmi3/Name"). The descriptions stay in the modules that explain
each FMU (fmi2_hostile.py, fmi3_bouncer.py, strict_fmu.py, fmi3_alltypes.py,
fmi3_linear.py, fmi3_clocked.py).
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import fmi2_hostile  # noqa: E402
import fmi3_alltypes  # noqa: E402
import fmi3_bouncer  # noqa: E402
import fmi3_clocked  # noqa: E402
import fmi3_linear  # noqa: E402
import strict_fmu  # noqa: E402


def _bouncer(**kw):
    return lambda: (3, fmi3_bouncer.description(**kw), fmi3_bouncer.SOURCE.read_text())


def _hostile():
    return 2, fmi2_hostile.MODEL_DESCRIPTION, fmi2_hostile.SOURCE.read_text()


def _strict(version, declares=False):
    return lambda: (version, strict_fmu.description(version, declares), strict_fmu.SOURCE.read_text())


def _alltypes(arrays):
    return lambda: (3, fmi3_alltypes.model_description(arrays), fmi3_alltypes.defined())


def _clocked(model, early_return=False):
    return lambda: (3, fmi3_clocked.description(model, early_return), fmi3_clocked.SOURCE.read_text())


def _linear(description):
    return lambda: (3, description(), fmi3_linear.SOURCE.read_text())


# NAME: () -> (FMI version, model description, the text whose fmiN functions need no stub).
BUILDS = {
    "Hostile": _hostile,
    "AbortInit": _hostile,
    "NoUnwind": _hostile,
    "Early": _bouncer(),
    "Inside": _bouncer(event_mode=False, early_return=False),
    "Indicator": _bouncer(indicator=True),
    "Refusing": _bouncer(early_return=False),
    "Strict2": _strict(2),
    "Claims": _strict(2, declares=True),
    "Strict3": _strict(3),
    "AllTypes": _alltypes(False),
    "Arrays": _alltypes(True),
    "Linear": _linear(lambda: fmi3_linear.MODEL_DESCRIPTION),
    "LinearCrash": _linear(lambda: fmi3_linear.MODEL_DESCRIPTION),
    "Empty": _linear(fmi3_linear.empty_output_description),
    "Ticker": _clocked("Ticker"),
    "EarlyTicker": _clocked("Ticker", early_return=True),
    "Counter": _clocked("Counter"),
    "Sampler": _clocked("Sampler"),
    "Partitions": _clocked("Partitions"),
}


def write(name: str, out: Path) -> None:
    version, description, defined = BUILDS[name]()
    out.mkdir(parents=True, exist_ok=True)
    (out / "modelDescription.xml").write_text(description)
    stubs = fmi2_hostile.stubs(defined) if version == 2 else fmi3_bouncer.stubs(defined)
    (out / "stubs.c").write_text(f'#include "fmi{version}Functions.h"\n' + stubs)


if __name__ == "__main__":
    write(sys.argv[1], Path(sys.argv[2]))
