/* Air: density of moist air by CIPM-2007 (Picard, Davis, Glaser and Fujii,
 * Metrologia 45, 149 (2008)) and the viscosity of dry air by Sutherland's
 * law. No state: the outputs are functions of the inputs at the current
 * communication point. */
#include <math.h>

#include "cw_runtime.h"
#include "cw_vars.h"

static const double GAS_CONSTANT = 8.314472;      /* J/(mol K), CIPM-2007 */
static const double MOLAR_MASS_VAPOUR = 18.01528e-3; /* kg/mol */

/* Saturation vapour pressure over water, Pa (CIPM-2007). */
static double saturation_vapour_pressure(double T) {
    return exp(1.2378847e-5 * T * T - 1.9121316e-2 * T + 33.93711047 -
               6.3431645e3 / T);
}

/* Enhancement factor f(p, t) (CIPM-2007), t in degrees Celsius. */
static double enhancement_factor(double p, double t) {
    return 1.00062 + 3.14e-8 * p + 5.6e-7 * t * t;
}

/* Compressibility factor Z (CIPM-2007). */
static double compressibility(double p, double T, double xv) {
    const double t = T - 273.15;
    const double a = 1.58123e-6 - 2.9331e-8 * t + 1.1043e-10 * t * t;
    const double b = 5.707e-6 - 2.051e-8 * t;
    const double c = 1.9898e-4 - 2.376e-6 * t;
    return 1.0 - (p / T) * (a + b * xv + c * xv * xv) +
           (p * p) / (T * T) * (1.83e-11 - 0.765e-8 * xv * xv);
}

/* Sutherland's law with White's constants for air. */
static double sutherland_viscosity(double T) {
    const double mu0 = 1.716e-5, T0 = 273.15, S = 110.4;
    return mu0 * pow(T / T0, 1.5) * (T0 + S) / (T + S);
}

static void calc_outputs(cw_instance *inst) {
    /* Read through cw_input so that an extrapolated input is seen at the
     * current time; clamp to the declared ranges, which an extrapolation
     * may leave. */
    const double p = fmin(fmax(IN(pressure, inst->time), 1000.0), 200000.0);
    const double T = fmin(fmax(IN(temperature, inst->time), 200.0), 373.15);
    const double h = fmin(fmax(IN(humidity, inst->time), 0.0), 1.0);
    const double t = T - 273.15;
    const double xv = h * enhancement_factor(p, t) *
                      saturation_vapour_pressure(T) / p;
    const double Z = compressibility(p, T, xv);
    const double Ma = (28.96546 + 12.011 * (R(x_CO2) - 0.0004)) * 1e-3;
    R(density) = p * Ma / (Z * GAS_CONSTANT * T) *
                 (1.0 - xv * (1.0 - MOLAR_MASS_VAPOUR / Ma));
    R(viscosity) = sutherland_viscosity(T);
    R(vapour_fraction) = xv;
    R(compressibility) = Z;
}
