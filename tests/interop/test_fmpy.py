"""fmpy's SSP runner (fmpy.ssp.simulation.simulate_ssp) on the exported archives.

Its conventions (reference_loop.TOOL_MODES['fmpy']): time by addition
(t += h), every connector starting at 0 (the first step sees 0 at every
connected input, the escapement initializes from phi = w = 0), and
connections passed on after all FMUs have stepped, so a feedthrough output
(escapement and drag torque) reaches the pendulum one step late. It reads
parameters only from the set it is given: clockwork.scene.ssp.fmpy_parameter_set
collects the archive's bindings for it.
"""

import pytest

from interop_common import SCENES, check_tool, require


@pytest.mark.parametrize("name", SCENES)
def test_fmpy_matches_reference_loop_and_predicted_error(name, ssp_dir):
    require("fmpy.ssp.simulation")
    check_tool("fmpy", name, ssp_dir)
