/* The input polynomial: an input set at tref with value u0 and time
 * derivatives d1, d2 (fmi2SetRealInputDerivatives' orders 1 and 2) has the
 * value u0 + dt (d1 + dt d2 / 2) at tref + dt. The master's extrapolation
 * (cw_inputs.c), the FMI 3.0 adapter's intermediate update (which hands an
 * FMI 3.0 FMU the polynomial FMI 2.0 would) and the Model Exchange
 * wrapper's inputs (cw_me.c) all evaluate it here, in this order of
 * operations (the Python engine's, for the same bits). */
#ifndef CW_POLYNOMIAL_H
#define CW_POLYNOMIAL_H

static inline double input_polynomial(double u0, double d1, double d2, double dt)
{
    return u0 + dt * (d1 + 0.5 * dt * d2);
}

#endif
