/* softcurve_sensitivities (softcurve_driver.h): forward sensitivities of an experiment
 * (softcurve.simulation.sensitivity): the state x' = f(x, u(t), d) by CVODES with Newton's
 * method on its own Newton matrix (driver.c's callbacks), the m sensitivity columns
 * S' = f_x S + f_d by CVODES's staggered corrector; or both by Radau IIA (radau.c), the
 * columns as the derivative of its discrete scheme (below). By default only the state is in the error test (CVODES's default): with
 * the columns in it too (columns_tested), the paper robot's 300 s trial takes 1.6 times
 * the steps for columns more accurate than a fit needs (docs/validation.md, "Speed").
 * f_x S + f_d comes from the identification's compiled function
 * fs(x;vec(S), u, d;scale) -> f;vec(S'), or from two parts that sum to it, the second on
 * a helper thread (parts.c). */
#include <float.h>
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

/* add_counters of CVODES's counters since its last (re)start. */
static void add_cvodes_counters(void *mem, long *stats) {
    long counters[5] = {0, 0, 0, 0, 0};
    read_counters(mem, counters);
    add_counters(counters, stats, 0);
}

static int state_rhs(realtype t, N_Vector y, N_Vector ydot, void *data) {
    sc_sensitivity *z = (sc_sensitivity *)data;
    if (z->linear) inputs_at(z, t);
    return evaluate(&z->s, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
}

/* Column j of the columns' right-hand side, f_x S_j + f_d, from the parts just evaluated
 * (their sum); 1 where an entry is not finite. */
static int column_of_parts(const sc_sensitivity *z, int j, double *column) {
    int n = z->s.n, i, k;
    memcpy(column, z->parts.part[0].out + z->leading + n * j, n * sizeof(double));
    for (k = 1; k < z->parts.count; ++k) {
        const double *part = z->parts.part[k].out + z->leading + n * j;
        for (i = 0; i < n; ++i) column[i] += part[i];
    }
    for (i = 0; i < n; ++i)
        if (!isfinite(column[i])) return 1;
    return 0;
}

static int sensitivity_rhs(int m, realtype t, N_Vector y, N_Vector ydot, N_Vector *yS,
                           N_Vector *ySdot, void *data, N_Vector tmp1, N_Vector tmp2) {
    sc_sensitivity *z = (sc_sensitivity *)data;
    int n = z->s.n, j;
    size_t bytes = n * sizeof(double);
    (void)ydot; (void)tmp1; (void)tmp2;
    if (z->linear) inputs_at(z, t);
    memcpy(z->xs, N_VGetArrayPointer(y), bytes);
    for (j = 0; j < m; ++j) memcpy(z->xs + n * (1 + j), N_VGetArrayPointer(yS[j]), bytes);
    if (evaluate_parts(&z->parts)) return -1;
    z->sensitivity_evaluations++;
    for (j = 0; j < m; ++j)
        if (column_of_parts(z, j, N_VGetArrayPointer(ySdot[j]))) return 1;
    return 0;
}

/* Radau IIA's columns (family FAMILY_RADAU): the sensitivities of the discrete scheme. A
 * step's stages Z solve Z = h (A (x) I) F(y + Z); differentiated, the columns' increments
 * dZ solve dZ_i = h sum_j a_ij (f_x(Y_j) (S + dZ_j) + f_d(Y_j)), a linear system whose
 * matrix is the exact one of the stages, solved by the simplified Newton iteration on the
 * step's own factors (radau_correction) to the state's Newton tolerance: one evaluation of
 * the columns' right-hand side per stage and iteration, from the last step's columns'
 * polynomial extrapolated. Where the kept Jacobian does not solve it (the state's
 * iteration converged on it), once more on a fresh one (radau_refresh). S then moves to
 * S + dZ_3 (the method is stiffly accurate), and the collocation polynomial of dZ gives
 * the columns between steps. The step sizes are the state's, not differentiated, as in
 * CVODES. */
typedef struct {
    double *start, *now;    /* S at the last step's start and end (m columns of n) */
    double *dz, *w, *f, *q; /* per column 3 n: the stages' increments, transformed, their
                               right-hand sides, the polynomial's coefficients */
    double *dw;             /* 3 n: a correction */
    double h;               /* the last step's size (0: none yet, no polynomial) */
} sc_columns;

static void columns_close(sc_columns *c) { free(c->start); }

/* 0, or 1 when out of memory (columns_close frees what was allocated). */
static int columns_open(sc_columns *c, int n, int m) {
    long nm = (long)n * (m > 0 ? m : 1);
    c->start = (double *)calloc(14 * nm + 3 * (long)n, sizeof(double));
    if (c->start == NULL) return 1;
    c->now = c->start + nm, c->dz = c->now + nm, c->w = c->dz + 3 * nm;
    c->f = c->w + 3 * nm, c->q = c->f + 3 * nm, c->dw = c->q + 3 * nm;
    c->h = 0.0;
    return 0;
}

/* The simplified Newton iteration of the columns' increments from those in c->dz: 0 when
 * it converged, 1 where it diverges, converges too slowly or a column is not finite, -1
 * where the columns' right-hand side fails. */
static int iterate_columns(sc_sensitivity *z, sc_radau *r, sc_columns *c) {
    const double *nodes = r->k + RADAU_C;
    int n = r->n, m = z->m, i, j, k, it;
    double h = r->h_last, previous = 0.0, eta = pow(fmax(r->eta, DBL_EPSILON), 0.8);
    for (j = 0; j < m; ++j) radau_mix(r->k + RADAU_TI, c->dz + 3 * j * n, n, c->w + 3 * j * n);
    for (it = 0; it < NEWTON_ITERATIONS; ++it) {
        double norm = 0.0;
        for (i = 0; i < 3; ++i) {
            if (z->linear) inputs_at(z, r->t_last + nodes[i] * h);
            for (k = 0; k < n; ++k) z->xs[k] = r->y_last[k] + r->z[i * n + k];
            for (j = 0; j < m; ++j)
                for (k = 0; k < n; ++k)
                    z->xs[n * (1 + j) + k] = c->start[j * n + k] + c->dz[(3 * j + i) * n + k];
            if (evaluate_parts(&z->parts)) return -1;
            z->sensitivity_evaluations++;
            for (j = 0; j < m; ++j)
                if (column_of_parts(z, j, c->f + (3 * j + i) * n)) return 1;
        }
        for (j = 0; j < m; ++j) {
            double *w = c->w + 3 * j * n, sum = 0.0;
            radau_correction(r, h, c->f + 3 * j * n, w, c->dw);
            for (k = 0; k < 3 * n; ++k) {
                double e = c->dw[k] / (r->atol + r->rtol * fabs(c->start[j * n + k % n]));
                sum += e * e, w[k] += c->dw[k];
            }
            if (!isfinite(sum)) return 1;
            norm = fmax(norm, sqrt(sum / (3.0 * n)));
            radau_mix(r->k + RADAU_T, w, n, c->dz + 3 * j * n);
        }
        if (it > 0) { /* the contraction, as the state's iteration measures it */
            double theta = norm / previous;
            if (theta >= 1.0) return 1;
            eta = theta / (1.0 - theta);
        }
        if (eta * norm <= r->newton_tolerance) return 0;
        previous = norm;
    }
    return 1;
}

/* The columns at the end of the step just accepted by r; 0, 1 where their iteration fails
 * on a fresh Jacobian too, or -1 where the columns' right-hand side or the Jacobian
 * fails. */
static int step_columns(sc_sensitivity *z, sc_radau *r, sc_columns *c) {
    int n = r->n, m = z->m, j, k, flag;
    double h = r->h_last;
    for (j = 0; j < m; ++j) /* the last step's polynomial extrapolated, as the state's */
        radau_predict(r, c->start + j * n, c->q + 3 * j * n, c->now + j * n, c->h, h,
                      c->dz + 3 * j * n);
    memcpy(c->start, c->now, sizeof(double) * n * m);
    flag = iterate_columns(z, r, c);
    if (flag == 1) {
        if (radau_refresh(r)) return -1;
        flag = iterate_columns(z, r, c);
    }
    if (flag) return flag;
    for (j = 0; j < m; ++j) {
        for (k = 0; k < n; ++k) c->now[j * n + k] = c->start[j * n + k] + c->dz[(3 * j + 2) * n + k];
        radau_mix(r->k + RADAU_P, c->dz + 3 * j * n, n, c->q + 3 * j * n);
    }
    c->h = h;
    return 0;
}

/* The columns at t within the last accepted step into out (m columns of n). */
static void interpolate_columns(const sc_radau *r, const sc_columns *c, int m, double t,
                                double *out) {
    int n = r->n, j;
    for (j = 0; j < m; ++j)
        radau_value(r, t, c->start + j * n, c->q + 3 * j * n, c->now + j * n, out + j * n);
}

static void inputs_moved(void *data, double t) { inputs_at((sc_sensitivity *)data, t); }

/* The state and columns by Radau IIA from out[0] over times[1..count) (the rest as
 * softcurve_sensitivities); 0 or the failure's CVODES flag. */
static int radau_columns(sc_sensitivity *z, const sc_options *options, double *out,
                         long *stats, int *reached) {
    int n = z->s.n, m = z->m, width = n * (1 + m), i, j, flag = 0;
    long taken;
    double tret;
    sc_radau r;
    sc_columns c;
    memset(&c, 0, sizeof(c));
    if (radau_open(&r, &z->s, options) || columns_open(&c, n, m)) {
        flag = -100;
        goto done;
    }
    if (z->linear) r.inputs = inputs_moved, r.inputs_data = z;
    for (j = 0; j < m; ++j) memcpy(c.now + j * n, out + n * (1 + j), sizeof(double) * n);
    for (i = 1; i < z->count && !flag; ++i) {
        double *row = out + (long)i * width;
        if (i == 1 || !z->linear) { /* held inputs: each interval its own, a new start */
            z->row = i;
            inputs_at(z, z->times[i]);
            flag = radau_start(&r, z->times[i - 1], row - width,
                               z->linear ? z->times[z->count - 1] : z->times[i], 0);
        }
        for (taken = 0; !flag && r.t < z->times[i];) {
            if (++taken > options->max_steps) flag = CV_TOO_MUCH_WORK;
            if (!flag) flag = radau_step(&r, &tret);
            if (!flag && m > 0 && (flag = step_columns(z, &r, &c)) != 0)
                flag = flag < 0 ? CV_RHSFUNC_FAIL : COLUMNS_FAILURE;
        }
        if (!z->linear || i == z->count - 1 || flag) {
            add_counters(r.counters, stats, 0);
            memset(r.counters, 0, sizeof(r.counters));
        }
        if (flag) break;
        radau_interpolate(&r, z->times[i], row);
        interpolate_columns(&r, &c, m, z->times[i], row + n);
        *reached = i + 1;
    }
done:
    columns_close(&c);
    radau_close(&r);
    return flag;
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
    if (options->family == FAMILY_RADAU) {
        flag = radau_columns(&z, options, out, stats, reached);
        stats[2] = z.s.jacobians;
        stats[5] = z.sensitivity_evaluations;
        goto done;
    }
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
            add_cvodes_counters(mem, stats);
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
    if (!counted) add_cvodes_counters(mem, stats);
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
