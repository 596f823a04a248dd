/* The driver's small entries (softcurve_driver.h): the right-hand side at many states in
 * one call (the linearization that picks the integrator family) and the sizes of the
 * structs, which the tests check against Python's declarations. */
#include <stdlib.h>

#include "driver_internal.h"

/* f at `count` states x[b, :] (physical, nx + lagging inputs) with inputs u[b, :] and
 * parameters p (shared): xdot[b, :]. Returns 0, or -100 when out of memory. */
SC_EXPORT int softcurve_rhs(const sc_function *fn, int count, const double *x, const double *u,
                            const double *p, double *xdot) {
    int n = fn->nx + (fn->lag ? fn->m : 0), inputs = fn->force ? fn->m : fn->nu, b, i, status = 0;
    sc_work s;
    double *ones = (double *)malloc(n * sizeof(double));
    if (work_open(&s, fn, n) || !ones) {
        status = -100;
    } else {
        for (i = 0; i < n; ++i) ones[i] = 1.0;
        s.nominal = ones;
        s.p = p;
        for (b = 0; b < count && status == 0; ++b) {
            s.u = u + (long)b * inputs;
            if (evaluate(&s, x + (long)b * n, xdot + (long)b * n) < 0) status = -1;
        }
    }
    free(ones);
    work_close(&s);
    return status;
}

SC_EXPORT long softcurve_sizeof_sc_function(void) { return (long)sizeof(sc_function); }

SC_EXPORT long softcurve_sizeof_sc_options(void) { return (long)sizeof(sc_options); }
