"""ecos (through ecospy) on the exported archives.

Its conventions (reference_loop.TOOL_MODES['ecos']): time by addition,
initial values iterated to consistency in initialization mode, and the
outputs a connection passes on are the ones read right after each FMU's
step, so a feedthrough output (escapement and drag torque) reaches the
pendulum one step late. ecos applies the archive's parameter set only
when it is named at init (clockwork.scene.ssp.PARAMETER_SET).
"""

import pytest

from interop_common import SCENES, check_tool, require


@pytest.mark.parametrize("name", SCENES)
def test_ecos_matches_reference_loop_and_predicted_error(name, ssp_dir):
    require("ecospy")
    check_tool("ecos", name, ssp_dir)
