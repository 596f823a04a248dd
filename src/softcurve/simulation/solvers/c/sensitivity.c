/* softcurve_sensitivities (softcurve_driver.h): forward sensitivities of an experiment (softcurve.simulation.sensitivity): the state
 * x' = f(x, u(t), d) by CVODES with Newton's method on its own Newton matrix (the
 * callbacks above), the m sensitivity columns S' = f_x S + f_d by CVODES's staggered
 * corrector. By default only the state is in the error test (CVODES's default): with
 * the columns in it too (columns_tested), the paper robot's 300 s trial takes 1.6 times
 * the steps for columns more accurate than a fit needs (docs/validation.md, "Speed").
 * f_x S + f_d comes from the identification's compiled function
 * fs(x;vec(S), u, d;scale) -> f;vec(S'), or from two parts that sum to it, the second on
 * a helper thread (parts.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "driver_internal.h"

typedef struct {
    sc_work s; /* first member: the Newton-matrix callbacks read the data as an sc_work */
    sc_parts parts;
    double *xs, *u;
    const double *table, *times;
    int m, nu, count, linear, row, leading;
    long sensitivity_evaluations;
} sc_sensitivity;

/* The inputs at t: row k of the table holds interval (times[k-1], times[k]]; with the
 * linear hold the row is (a, b) and u = a + b t, else the row is u. */
static void inputs_at(sc_sensitivity *z, double t) {
    int k = z->row, i;
    const double *row;
    while (k < z->count - 1 && t > z->times[k]) ++k;
    while (k > 1 && t <= z->times[k - 1]) --k;
    z->row = k;
    row = z->table + (long)k * z->nu * (z->linear ? 2 : 1);
    for (i = 0; i < z->nu; ++i) z->u[i] = row[i] + (z->linear ? row[z->nu + i] * t : 0.0);
}

/* Adds CVODES's counters since its last (re)start to stats[0], [1], [3] and [4]. */
static void add_counters(void *mem, long *stats) {
    long counters[5] = {0, 0, 0, 0, 0};
    read_counters(mem, counters);
    stats[0] += counters[0];
    stats[1] += counters[1];
    stats[3] += counters[2];
    stats[4] += counters[3];
}

static int state_rhs(realtype t, N_Vector y, N_Vector ydot, void *data) {
    sc_sensitivity *z = (sc_sensitivity *)data;
    if (z->linear) inputs_at(z, t);
    return evaluate(&z->s, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
}

static int sensitivity_rhs(int m, realtype t, N_Vector y, N_Vector ydot, N_Vector *yS,
                           N_Vector *ySdot, void *data, N_Vector tmp1, N_Vector tmp2) {
    sc_sensitivity *z = (sc_sensitivity *)data;
    int n = z->s.n, i, j, k;
    size_t bytes = n * sizeof(double);
    (void)ydot; (void)tmp1; (void)tmp2;
    if (z->linear) inputs_at(z, t);
    memcpy(z->xs, N_VGetArrayPointer(y), bytes);
    for (j = 0; j < m; ++j) memcpy(z->xs + n * (1 + j), N_VGetArrayPointer(yS[j]), bytes);
    if (evaluate_parts(&z->parts)) return -1;
    z->sensitivity_evaluations++;
    for (j = 0; j < m; ++j) {
        double *column = N_VGetArrayPointer(ySdot[j]);
        memcpy(column, z->parts.part[0].out + z->leading + n * j, bytes);
        for (k = 1; k < z->parts.count; ++k) {
            const double *part = z->parts.part[k].out + z->leading + n * j;
            for (i = 0; i < n; ++i) column[i] += part[i];
        }
        for (i = 0; i < n; ++i)
            if (!isfinite(column[i])) return 1;
    }
    return 0;
}

/* softcurve_driver.h */
SC_EXPORT int softcurve_sensitivities(const sc_function *fn, const sc_options *options,
                                      const casadi_fn *fs, const long long *fs_sizes, int parts,
                                      int leading, int m, const double *d, const double *dsc,
                                      const double *times, int count, const double *table,
                                      int linear, double *out, long *stats, int *reached) {
    int n = fn->nx, width = fn->nx * (1 + m), i, j, flag = 0, counted = 0;
    size_t bytes = n * sizeof(double);
    sc_sensitivity z;
    void *mem = NULL;
    N_Vector y = N_VNew_Serial(n), *yS = NULL;
    double *ones = (double *)malloc(n * sizeof(double)), tret;
    const double *args[3];
    memset(&z, 0, sizeof(z));
    *reached = 1;
    flag = work_open(&z.s, fn, n) ? -100 : 0;
    z.s.p = d;
    z.xs = (double *)calloc(width + fn->nu, sizeof(double));
    args[0] = z.xs;
    args[1] = z.xs ? z.xs + width : NULL;
    args[2] = dsc;
    /* the state alone (m = 0) evaluates no columns: no parts, no helper thread */
    if (flag || !y || !ones || !z.xs ||
        (m > 0 && parts_open(&z.parts, parts, fs, fs_sizes, args, leading + (long)n * m,
                             options->helper)) ||
        (m > 0 && !(yS = N_VCloneVectorArray_Serial(m, y)))) {
        flag = -100;
        goto done;
    }
    if (count < 2) goto done;
    for (i = 0; i < n; ++i) ones[i] = 1.0;
    z.s.nominal = ones; /* unscaled: the absolute tolerance is in the state's units */
    z.m = m;
    z.leading = leading;
    z.nu = fn->nu;
    z.count = count;
    z.linear = linear;
    z.row = 1;
    z.table = table;
    z.times = times;
    z.u = z.xs + width;
    z.s.u = z.u;
    memcpy(N_VGetArrayPointer(y), out, bytes);
    for (j = 0; j < m; ++j) memcpy(N_VGetArrayPointer(yS[j]), out + n * (1 + j), bytes);
    inputs_at(&z, times[1]);
    mem = create(options->family == CV_BDF ? CV_BDF : CV_ADAMS, times[0], y, state_rhs, &z,
                 options->rtol, options->atol, options->max_steps, options->max_order);
    if (!mem || (m > 0 && (CVodeSensInit(mem, m, CV_STAGGERED, sensitivity_rhs, yS) ||
                   CVodeSensEEtolerances(mem) ||
                   CVodeSetSensErrCon(mem, options->columns_tested != 0)))) {
        flag = -100;
        goto done;
    }
    CVodeSetStopTime(mem, times[linear ? count - 1 : 1]);
    for (i = 1; i < count; ++i) {
        double *row = out + (long)i * width;
        if (!linear && i > 1) {
            z.row = i;
            inputs_at(&z, times[i]);
            add_counters(mem, stats);
            counted = 1;
            if (CVodeReInit(mem, times[i - 1], y) ||
                (m > 0 && CVodeSensReInit(mem, CV_STAGGERED, yS))) {
                flag = -100;
                break;
            }
            counted = 0;
            CVodeSetStopTime(mem, times[i]);
        }
        flag = CVode(mem, times[i], y, &tret, CV_NORMAL);
        if (flag >= 0 && m > 0) flag = CVodeGetSens(mem, &tret, yS);
        if (flag < 0) break;
        flag = 0;
        memcpy(row, N_VGetArrayPointer(y), bytes);
        for (j = 0; j < m; ++j) memcpy(row + n * (1 + j), N_VGetArrayPointer(yS[j]), bytes);
        *reached = i + 1;
    }
    if (!counted) add_counters(mem, stats);
    stats[2] = z.s.jacobians;
    stats[5] = z.sensitivity_evaluations;
done:
    if (mem) CVodeFree(&mem);
    if (yS) N_VDestroyVectorArray_Serial(yS, m);
    if (y) N_VDestroy(y);
    free(ones);
    parts_close(&z.parts);
    stats[6] = z.parts.helper_evaluations;
    work_close(&z.s);
    free(z.xs);
    return flag;
}
