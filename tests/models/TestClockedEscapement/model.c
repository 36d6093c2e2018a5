/* TestClockedEscapement: the GrasshopperEscapement's own code, with its
 * switch of the mode as an FMI 3.0 output clock (model.toml). In Event
 * Mode, before fmi3UpdateDiscreteStates commits the mode, the clock ticks
 * when the mode decided from the current inputs differs from the
 * committed one: the switch that commit() then makes. */
#include "../../../src_c/models/GrasshopperEscapement/model.c"

static int clock_ticks(cw_instance *inst) { return pending_state(inst).switched; }
