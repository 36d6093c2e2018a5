/* Drag: air resistance of the pendulum as a torque,
 *   tau = -((c1 + c1_air) w + (c2 + c2_air) w |w|),
 * the laminar (linear) and turbulent (quadratic) parts of Ziemkiewicz's
 * modified drag model (Fig. 6), plus, for a spherical bob of radius R in
 * air, the oscillating-sphere linear term (Stokes 1851) and the form drag
 * (Nelson and Olsson 1986). No state: the output is a function of the
 * inputs at the current communication point. */
#include <math.h>

#include "cw_runtime.h"
#include "cw_vars.h"

static const double PI = 3.14159265358979323846;

static void calc_outputs(cw_instance *inst) {
    /* Read through cw_input so that an extrapolated input (derivatives set
     * by the master) is seen at the current time. */
    const double w = IN(w, inst->time);
    double c1 = R(c1), c2 = R(c2);
    if (R(bob_radius) > 0) {
        const double rho = fmax(IN(rho_air, inst->time), 0.0);
        const double mu = fmax(IN(mu_air, inst->time), 0.0);
        const double r = R(bob_radius), arm = R(arm);
        /* 6 pi mu R (1 + R/delta) arm^2, written without 1/delta so that
         * rho = 0 gives the plain Stokes term. */
        c1 += 6.0 * PI * r * arm * arm *
              (mu + r * sqrt(0.5 * rho * mu * R(omega)));
        c2 += 0.5 * rho * R(drag_coefficient) * PI * r * r * arm * arm * arm;
    }
    R(tau) = -(c1 * w + c2 * w * fabs(w));
}
