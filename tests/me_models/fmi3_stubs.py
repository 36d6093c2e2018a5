"""Writes the FMI 3.0 functions me_fmi3.c leaves out, each failing (fmpy
binds every symbol of an FMI 3.0 binary), with tests/fmi3_bouncer.py's
stubs() from fmpy's headers.

    python fmi3_stubs.py <me_fmi3.c> <out.c>
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from fmi3_bouncer import stubs  # noqa: E402

source, out = sys.argv[1:]
Path(out).write_text('#include "fmi3Functions.h"\n' + stubs(Path(source).read_text()))
