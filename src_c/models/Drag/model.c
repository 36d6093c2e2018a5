/* Drag: air resistance of the pendulum as a torque,
 *   tau = -(c1 w + c2 w |w|),
 * the laminar (linear) and turbulent (quadratic) parts of Ziemkiewicz's
 * modified drag model (Fig. 6). No state: the output is a function of the
 * input at the current communication point. */
#include <math.h>

#include "cw_runtime.h"
#include "cw_vars.h"

static void calc_outputs(cw_instance *inst) {
    /* Read through cw_input so that an extrapolated input (derivatives set
     * by the master) is seen at the current time. */
    const double w = IN(w, inst->time);
    R(tau) = -(R(c1) * w + R(c2) * w * fabs(w));
}
