"""libcosim (through libcosimpy) on the exported archives.

Its conventions (reference_loop.TOOL_MODES['libcosim']): time in integer
nanoseconds, initial values iterated to consistency in initialization
mode, and outputs read right after each FMU's step and passed on after all
have stepped, so a feedthrough output (escapement and drag torque) reaches
the pendulum one step late. The step comes from the archive's
osp:FixedStepAlgorithm annotation.
"""

import pytest

from interop_common import SCENES, check_tool, require


@pytest.mark.parametrize("name", SCENES)
def test_libcosim_matches_reference_loop_and_predicted_error(name, ssp_dir):
    require("libcosimpy")
    check_tool("libcosim", name, ssp_dir)
