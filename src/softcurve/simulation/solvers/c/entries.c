/* The driver's small entries (softcurve_driver.h): the right-hand side at many states in
 * one call (the linearization that picks the integrator family), the Newton matrix's
 * Jacobian at one state (which the tests check) and the sizes of the structs, which the
 * tests check against Python's declarations. */
#include <stdlib.h>
#include <string.h>

#include "driver_internal.h"

/* f at `count` states x[b, :] (physical, nx + lagging inputs) with inputs u[b, :] and
 * parameters p (shared): xdot[b, :]. Returns 0, or -100 when out of memory. */
SC_EXPORT int softcurve_rhs(const sc_function *fn, int count, const double *x, const double *u,
                            const double *p, double *xdot) {
    int n = states_of(fn), inputs = inputs_of(fn), b, i, status = 0;
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

/* The Jacobian of the integrated scaled state's derivative, J (n x n, column-major), that
 * the Newton matrix takes at the physical state x (nx + lagging inputs) with inputs u,
 * parameters p and state scales nominal: the problem's exact one, or forward
 * differences. Returns 0, -1 when a function fails, or -100 when out of memory. */
SC_EXPORT int softcurve_newton_jacobian(const sc_function *fn, const double *x, const double *u,
                                        const double *p, const double *nominal, double *J) {
    int n = states_of(fn), i, status = 0;
    sc_work s;
    double *y = (double *)malloc(2 * n * sizeof(double));
    if (work_open(&s, fn, n) || !y) {
        status = -100;
    } else {
        s.nominal = nominal;
        s.p = p;
        s.u = u;
        for (i = 0; i < n; ++i) y[i] = x[i] / nominal[i];
        if (evaluate(&s, y, y + n) || newton_jacobian(&s, y, y + n)) status = -1;
        else memcpy(J, s.J, (size_t)n * n * sizeof(double));
    }
    free(y);
    work_close(&s);
    return status;
}

SC_EXPORT long softcurve_sizeof_sc_function(void) { return (long)sizeof(sc_function); }

SC_EXPORT long softcurve_sizeof_sc_options(void) { return (long)sizeof(sc_options); }
