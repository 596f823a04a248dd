/* The continuous adjoint on CVODES (softcurve_adams_forward and _backward,
 * softcurve_driver.h): the gradient of a function of the states at the output times,
 * along the initial state, the held inputs and the parameters, by the adjoint equations
 * integrated backward by the same linear multistep method as the forward pass.
 *
 * The forward pass integrates the scaled state y = x / D (D the nominal sizes) by CVODES
 * one internal step at a time, restarting where the input changes and after every
 * restart interval, and tapes every step's end: its time and the polynomial CVODES
 * interpolates over the step (its Nordsieck array, as Taylor coefficients up to the
 * step's order). No checkpoints: the tape holds every step, so the backward pass never
 * integrates forward again. (CVODES's own adjoint module interpolates by cubic Hermite
 * pieces instead, whose error over a step h of a mode at w is about (h w)^4 / 384 of its
 * amplitude.)
 *
 * The backward pass integrates, segment by segment from the last output time,
 *     mu' = -g_y^T mu,   Q' = -(f_u^T nu, f_p^T nu),   nu = mu / D,
 * where g(y) = f(D y) / D is the scaled right-hand side and the forward state at t is the
 * taped polynomial of its step: mu is the adjoint of y (D times the physical one), and
 * Q, read at every output time, gives by differences the integral over each output
 * interval of the derivative along its input, and along the parameters. Q rides with mu
 * outside the error test and Newton's norm, so each right-hand side is one reverse-mode
 * evaluation of f (the caller's vjp). Where the scalar depends on the state at an output
 * time, mu jumps there by D times that derivative and CVODES starts afresh. Newton's
 * method runs on -J^T along mu, J the Jacobian of g at the interpolated forward state
 * (the problem's exact one, or forward differences, as the forward pass's), factored as
 * the forward pass factors its own. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "driver_internal.h"

/* The absolute tolerance of the backward pass's integrals: large enough that their weights
 * in CVODES's norms vanish, as CVODES leaves out its quadratures without error control,
 * and finite. */
#define UNWEIGHTED 1e100
/* Times closer than this many rounding units of their size are one: CVODES refuses to
 * integrate over less than two (CV_TOO_CLOSE), so a start is never put there. */
#define SAME_TIME 100.0
/* Whether times a and b lie more than SAME_TIME rounding units apart. */
static int apart(double a, double b) {
    return fabs(a - b) > SAME_TIME * DBL_EPSILON * fmax(1.0, fmax(fabs(a), fabs(b)));
}

/* Doubles of a taped point for n states and orders up to q (softcurve_driver.h). */
#define POINT_ENTRY(n, q) (ADAMS_HEAD + ((long)(q) + 1) * (long)(n))

/* The next free point of the tape (entry doubles each), its time and row set; NULL where
 * the tape is full. */
static double *next_point(double *tape, long capacity, long *used, long entry, double t,
                          int row) {
    double *at;
    if (*used >= capacity) return NULL;
    at = tape + *used * entry;
    at[ADAMS_T] = t, at[ADAMS_ROW] = row;
    ++*used;
    return at;
}

/* Tapes the end of CVODES's last step (at tret): its polynomial's Taylor coefficients
 * there, y^(k) / k! up to the step's order; 0, TAPE_FULL or -100. */
static int tape_step(void *mem, double *tape, long capacity, long *used, long entry, int n,
                     double tret, int row, N_Vector dkyv) {
    double *at = next_point(tape, capacity, used, entry, tret, row), factorial = 1.0;
    const double *dky = N_VGetArrayPointer(dkyv);
    int order, k, j;
    if (at == NULL) return TAPE_FULL;
    if (CVodeGetLastOrder(mem, &order) || ADAMS_HEAD + (order + 1L) * n > entry) return -100;
    at[ADAMS_ORDER] = order;
    for (k = 0; k <= order; ++k) {
        if (k > 1) factorial *= k;
        if (CVodeGetDky(mem, tret, k, dkyv)) return -100;
        for (j = 0; j < n; ++j) at[ADAMS_HEAD + k * n + j] = dky[j] / factorial;
    }
    return 0;
}

/* CVODES afresh at t from y (scaled) with the input s->u, stopping at t_stop, and the
 * start taped as a polynomial of order zero (row: the input's; it marks where the
 * segment's points begin, and the backward pass reads the steps' polynomials only);
 * created at the first call. 0, TAPE_FULL, or -100 where it cannot be set up. */
static int forward_start(void **mem, sc_work *s, const sc_options *options, double t,
                         N_Vector yv, double t_stop, int row, double *tape,
                         long capacity, long *used) {
    int n = s->n, lmm = options->family == FAMILY_BDF ? CV_BDF : CV_ADAMS;
    long entry = POINT_ENTRY(n, options->max_order);
    double *at;
    if (*mem == NULL) {
        *mem = create(lmm, t, yv, rhs, s, options->rtol, options->atol, options->max_steps,
                      options->max_order);
        if (*mem == NULL) return -100;
    } else if (CVodeReInit(*mem, t, yv)) {
        return -100;
    }
    if (CVodeSetStopTime(*mem, t_stop)) return -100;
    at = next_point(tape, capacity, used, entry, t, row);
    if (at == NULL) return TAPE_FULL;
    at[ADAMS_ORDER] = 0;
    memcpy(at + ADAMS_HEAD, N_VGetArrayPointer(yv), sizeof(double) * n);
    return 0;
}

/* softcurve_driver.h */
SC_EXPORT int softcurve_adams_forward(const sc_function *fn, const sc_options *options,
                                      double restart_interval, const double *u,
                                      const double *p, const double *nominal,
                                      const double *times, int count, const int *stops,
                                      double *out, double *tape, long capacity, long *used,
                                      long *stats, int *reached) {
    int n = states_of(fn), inputs = inputs_of(fn), start = 0, end, i, j, flag = 0;
    long counters[5], taken, entry = POINT_ENTRY(n, options->max_order);
    double tret, t_started, *y, *dky;
    N_Vector yv = N_VNew_Serial(n), dkyv = N_VNew_Serial(n);
    void *mem = NULL;
    sc_work s;
    *used = 0;
    *reached = 1;
    memset(&s, 0, sizeof(s));
    if (work_open(&s, fn, n) || yv == NULL || dkyv == NULL || options->max_order < 1) {
        flag = -100;
        goto done;
    }
    y = N_VGetArrayPointer(yv), dky = N_VGetArrayPointer(dkyv);
    s.nominal = nominal, s.p = p;
    for (j = 0; j < n; ++j) y[j] = out[j] / nominal[j];
    while (start < count - 1 && !flag) { /* one input from times[start] to the next stop */
        for (end = start + 1; end < count - 1 && !stops[end]; ++end) {}
        s.u = u + (long)start * inputs;
        flag = forward_start(&mem, &s, options, times[start], yv, times[end], start,
                             tape, capacity, used);
        tret = t_started = times[start];
        for (i = start + 1; i <= end && !flag; ++i) {
            for (taken = 0; tret < times[i] && !flag;) {
                if (tret - t_started >= restart_interval && apart(tret, times[i])) {
                    /* afresh: order one again */
                    read_counters(mem, counters);
                    add_counters(counters, stats, 1);
                    flag = forward_start(&mem, &s, options, tret, yv, times[end], start,
                                         tape, capacity, used);
                    t_started = tret;
                    if (flag) break;
                }
                flag = ++taken > options->max_steps
                           ? CV_TOO_MUCH_WORK
                           : CVode(mem, times[i], yv, &tret, CV_ONE_STEP);
                if (flag == CV_TSTOP_RETURN) flag = 0;
                if (!flag)
                    flag = tape_step(mem, tape, capacity, used, entry, n, tret, start, dkyv);
            }
            if (!flag && CVodeGetDky(mem, times[i], 0, dkyv)) flag = -100;
            if (flag) break;
            for (j = 0; j < n; ++j) out[(long)i * n + j] = dky[j] * nominal[j];
            *reached = i + 1;
        }
        if (mem != NULL) {
            read_counters(mem, counters);
            add_counters(counters, stats, 1);
        }
        start = end;
    }
    stats[2] += s.jacobians;
done:
    if (mem != NULL) CVodeFree(&mem);
    if (yv != NULL) N_VDestroy(yv);
    if (dkyv != NULL) N_VDestroy(dkyv);
    work_close(&s);
    return flag;
}

typedef struct {
    sc_work s; /* f and the Jacobians at the forward states (first: setup's data) */
    int n, m, np;
    casadi_fn vjp;
    sc_arrays c;
    const double *tape; /* the taped points of the segment: first .. last, entry doubles */
    long first, last, entry;
    double *x, *v, *xb, *ub, *pb; /* the vjp's arguments and results */
    double *y, *fy, *moved, *jt;  /* the forward state and its f, a copy, -J^T */
    double at;                    /* the time of y (NAN: none) */
    long jacobians;
} sc_backward;

static void backward_close(sc_backward *b) {
    work_close(&b->s);
    arrays_close(&b->c);
    free(b->x);
}

/* 0, or 1 when out of memory (backward_close frees what was allocated). */
static int backward_open(sc_backward *b, const sc_function *fn, casadi_fn vjp,
                         const long long *sizes) {
    int n = states_of(fn), m = inputs_of(fn);
    memset(b, 0, sizeof(*b));
    b->n = n, b->m = m, b->np = fn->np, b->vjp = vjp, b->at = NAN;
    if (work_open(&b->s, fn, n) || arrays_open(&b->c, sizes[0], sizes[1], sizes[2], sizes[3], 0))
        return 1;
    b->x = (double *)calloc(7 * n + m + fn->np + (long)n * n, sizeof(double));
    if (!b->x) return 1;
    b->v = b->x + n, b->xb = b->v + n, b->ub = b->xb + n, b->pb = b->ub + m;
    b->y = b->pb + fn->np, b->fy = b->y + n, b->moved = b->fy + n, b->jt = b->moved + n;
    return 0;
}

/* b->y: the forward state at t by the polynomial of the segment's step that ended first
 * at or after t (CVODES's own interpolant over that step; the last step's beyond them). */
static void forward_state(sc_backward *b, double t) {
    long lo = b->first, hi = b->last, mid;
    int n = b->n, j, k;
    const double *at;
    double x;
    if (t == b->at) return;
    while (hi - lo > 1) { /* tape[lo].t < t <= tape[hi].t, or hi the last */
        mid = (lo + hi) / 2;
        if (b->tape[mid * b->entry + ADAMS_T] < t) lo = mid;
        else hi = mid;
    }
    at = b->tape + hi * b->entry, x = t - at[ADAMS_T];
    for (j = 0; j < n; ++j) { /* Horner's rule on the Taylor coefficients */
        double value = 0.0;
        for (k = (int)at[ADAMS_ORDER]; k >= 0; --k) value = value * x + at[ADAMS_HEAD + k * n + j];
        b->y[j] = value;
    }
    b->at = t;
}

/* The vjp at the forward state at t with the seed nu = mu / D: xb = D f_x^T nu (the
 * scaled state's), ub = f_u^T nu, pb = f_p^T nu; 0, or -1 where it fails or is not
 * finite (a failure CVODES does not retry). */
static int products(sc_backward *b, double t, const double *mu) {
    const double *nominal = b->s.nominal;
    int n = b->n, j;
    forward_state(b, t);
    for (j = 0; j < n; ++j) b->x[j] = nominal[j] * b->y[j], b->v[j] = mu[j] / nominal[j];
    b->c.arg[0] = b->x, b->c.arg[1] = b->s.u, b->c.arg[2] = b->s.p, b->c.arg[3] = b->v;
    b->c.res[0] = b->xb, b->c.res[1] = b->ub, b->c.res[2] = b->pb;
    if (b->vjp(b->c.arg, b->c.res, b->c.iw, b->c.w, 0)) return -1;
    for (j = 0; j < n; ++j) b->xb[j] *= nominal[j];
    for (j = 0; j < n + b->m + b->np; ++j) /* xb, ub and pb lie in a row */
        if (!isfinite(b->xb[j])) return -1;
    return 0;
}

/* The backward state's derivative: -xb along mu, then -ub and -pb along the integrals
 * (ub and pb lie in a row after xb in b->x's block). */
static int backward_rhs(realtype t, N_Vector z, N_Vector zdot, void *data) {
    sc_backward *b = (sc_backward *)data;
    double *out = N_VGetArrayPointer(zdot);
    int j;
    if (products(b, t, N_VGetArrayPointer(z))) return -1;
    for (j = 0; j < b->n + b->m + b->np; ++j) out[j] = -b->xb[j];
    return 0;
}

/* Where CVODES asks for one, -J^T at the forward state at t (J: newton_jacobian's), then
 * the LU factors of I - gamma (-J^T). */
static int backward_setup(realtype t, N_Vector muv, N_Vector fmu, int jok, int *jcur,
                          realtype gamma, void *data, N_Vector t1, N_Vector t2, N_Vector t3) {
    sc_backward *b = (sc_backward *)data;
    int n = b->n, i, j;
    (void)muv; (void)fmu; (void)t1; (void)t2; (void)t3;
    if (!jok) {
        forward_state(b, t);
        memcpy(b->moved, b->y, sizeof(double) * n); /* newton_jacobian moves its y */
        int flag = evaluate(&b->s, b->moved, b->fy);
        if (flag || (flag = newton_jacobian(&b->s, b->moved, b->fy))) return flag;
        for (j = 0; j < n; ++j)
            for (i = 0; i < n; ++i) b->jt[i + j * n] = -b->s.J[j + i * n];
        b->jacobians++;
        *jcur = 1;
    } else {
        *jcur = 0;
    }
    return factor_newton(b->jt, gamma, n, b->s.LU, b->s.piv);
}

/* The Newton matrix of the backward state: I - gamma (-J^T) along mu, the identity along
 * the integrals, whose coupling to mu it leaves out (their weights are zero, so Newton's
 * iteration converges on mu alone, and the integrals take the derivative at its last
 * iterate). */
static int backward_solve(realtype t, N_Vector yv, N_Vector fyv, N_Vector rv, N_Vector zv,
                          realtype gamma, realtype delta, int lr, void *data, N_Vector tmp) {
    sc_backward *b = (sc_backward *)data;
    double *r = N_VGetArrayPointer(rv), *z = N_VGetArrayPointer(zv);
    (void)t; (void)yv; (void)fyv; (void)gamma; (void)delta; (void)lr; (void)tmp;
    if (z != r) memcpy(z, r, (b->n + b->m + b->np) * sizeof(double));
    solve_newton(b->s.LU, b->s.piv, b->n, z);
    return 0;
}

/* The product with the Jacobian the Newton matrix takes (backward_solve's). */
static int backward_jtimes(N_Vector vv, N_Vector Jvv, realtype t, N_Vector y, N_Vector fy,
                           void *data, N_Vector tmp) {
    sc_backward *b = (sc_backward *)data;
    double *Jv = N_VGetArrayPointer(Jvv);
    (void)t; (void)y; (void)fy; (void)tmp;
    times_jacobian(b->jt, N_VGetArrayPointer(vv), b->n, Jv);
    memset(Jv + b->n, 0, (b->m + b->np) * sizeof(double));
    return 0;
}

/* mu += D seed. */
static void add_seed(double *mu, const double *seed, const double *nominal, int n) {
    int j;
    for (j = 0; j < n; ++j) mu[j] += nominal[j] * seed[j];
}

/* Whether any of the n entries of v is nonzero. */
static int any_nonzero(const double *v, int n) {
    int j;
    for (j = 0; j < n && v[j] == 0.0; ++j) {}
    return j < n;
}

/* CVODES afresh at t from the backward state z (its integrals set to zero), stopping at
 * t_stop; created at the first call with mu's absolute tolerance atol; 0, or -100 where
 * it cannot be set up. */
static int restart(void **mem, sc_backward *b, const sc_options *options, N_Vector atol,
                   double t, N_Vector z, double t_stop) {
    int lmm = options->family == FAMILY_BDF ? CV_BDF : CV_ADAMS;
    memset(N_VGetArrayPointer(z) + b->n, 0, sizeof(double) * (b->m + b->np));
    if (*mem == NULL) {
        *mem = create_with(lmm, t, z, backward_rhs, backward_setup, backward_solve,
                           backward_jtimes, b, options->rtol, 1.0, options->max_steps,
                           options->max_order);
        if (*mem == NULL || CVodeSVtolerances(*mem, options->rtol, atol)) return -100;
    } else if (CVodeReInit(*mem, t, z)) {
        return -100;
    }
    return CVodeSetStopTime(*mem, t_stop) ? -100 : 0;
}

/* Adds CVODES's counters since its last start to stats (its right-hand sides are the vjp
 * evaluations: each calls products() once, and the Newton matrix's product is jtimes'). */
static void count_steps(void *mem, long *stats) {
    long counters[5];
    read_counters(mem, counters);
    add_counters(counters, stats, 0);
}

/* The integrals since the last read (z's, after mu's n entries) added to row i of d_u
 * and to d_p, and read := z's. */
static void add_integrals(const double *z, double *read, int n, int inputs, int np, int i,
                          double *d_u, double *d_p) {
    int j;
    for (j = 0; j < inputs; ++j) d_u[(long)i * inputs + j] += z[n + j] - read[j];
    for (j = 0; j < np; ++j) d_p[j] += z[n + inputs + j] - read[inputs + j];
    memcpy(read, z + n, sizeof(double) * (inputs + np));
}

/* softcurve_driver.h */
SC_EXPORT int softcurve_adams_backward(const sc_function *fn, const sc_options *options,
                                       double restart_interval, casadi_fn vjp,
                                       const long long *vjp_sizes, const double *u,
                                       const double *p, const double *nominal,
                                       const double *times, int count, const int *stops,
                                       const double *tape, long points, const double *seeds,
                                       double *lambda, double *d_u, double *d_p, long *stats) {
    int n = states_of(fn), inputs = inputs_of(fn), np = fn->np, nz = n + inputs + np;
    int end = count - 1, start, i, j, r, flag = 0, live = 0;
    long point = points - 1;
    double scale = 0.0, tret, t_started = 0.0, t_stop, due = 0.0, *z, *read;
    N_Vector zv = N_VNew_Serial(nz), atol = N_VNew_Serial(nz);
    void *mem = NULL;
    sc_backward b;
    memset(lambda, 0, sizeof(double) * n);
    read = (double *)calloc(inputs + np, sizeof(double));
    if (backward_open(&b, fn, vjp, vjp_sizes) || zv == NULL || atol == NULL || read == NULL) {
        flag = -100;
        goto done;
    }
    z = N_VGetArrayPointer(zv);
    b.s.nominal = nominal, b.s.p = p, b.tape = tape;
    b.entry = POINT_ENTRY(n, options->max_order);
    /* mu's absolute tolerance: the call's, in the units of the largest seed */
    for (i = 0; i < count * n; ++i) scale = fmax(scale, fabs(nominal[i % n] * seeds[i]));
    for (j = 0; j < nz; ++j)
        N_VGetArrayPointer(atol)[j] = j < n ? options->atol * scale : UNWEIGHTED;
    memset(z, 0, sizeof(double) * nz);
    add_seed(z, seeds + (long)end * n, nominal, n);
    while (end > 0 && !flag) { /* the segment of one input from the stop before `end` */
        for (start = end - 1; start > 0 && !stops[start]; --start) {}
        b.last = point;
        for (b.first = point;
             b.first > 0 && tape[(b.first - 1) * b.entry + ADAMS_ROW] == start;
             --b.first) {}
        b.s.u = u + (long)start * inputs, b.at = NAN;
        tret = times[end];
        for (i = end - 1; i >= start && !flag;) { /* mu from tret to times[i] */
            if (!live && any_nonzero(z, n)) { /* afresh: where mu jumped, or order one */
                for (r = i; r > start && !any_nonzero(seeds + (long)r * n, n); --r) {}
                t_stop = fmax(times[r], tret - restart_interval);
                flag = restart(&mem, &b, options, atol, tret, zv, t_stop);
                memset(read, 0, sizeof(double) * (inputs + np));
                live = !flag, t_started = tret, stats[5]++;
                if (flag) break;
            }
            due = t_started - restart_interval; /* where CVODES starts afresh, if live */
            if (live && times[i] < due && apart(times[i], due)) { /* afresh on the way */
                flag = CVode(mem, due, zv, &tret, CV_NORMAL);
                if (flag == CV_TSTOP_RETURN) flag = 0;
                if (flag) break;
                add_integrals(z, read, n, inputs, np, i, d_u, d_p);
                count_steps(mem, stats);
                live = 0;
                continue;
            }
            if (live) { /* the integrals over [times[i], times[i + 1]]: row i's */
                flag = CVode(mem, times[i], zv, &tret, CV_NORMAL);
                if (flag == CV_TSTOP_RETURN) flag = 0;
                if (flag) break;
                add_integrals(z, read, n, inputs, np, i, d_u, d_p);
            }
            tret = times[i];
            if (live && !apart(times[i], due)) { /* at the restart: afresh from here */
                count_steps(mem, stats);
                live = 0;
            }
            if (i > start && any_nonzero(seeds + (long)i * n, n)) { /* mu jumps */
                if (live) count_steps(mem, stats);
                live = 0;
                add_seed(z, seeds + (long)i * n, nominal, n);
            }
            --i;
        }
        if (live) count_steps(mem, stats);
        live = 0;
        add_seed(z, seeds + (long)start * n, nominal, n); /* the one before's, or x0's */
        point = b.first - 1;
        end = start;
    }
    for (j = 0; !flag && j < n; ++j) lambda[j] = z[j] / nominal[j]; /* the physical state's */
    stats[2] += b.jacobians;
done:
    if (mem != NULL) CVodeFree(&mem);
    if (zv != NULL) N_VDestroy(zv);
    if (atol != NULL) N_VDestroy(atol);
    free(read);
    backward_close(&b);
    return flag;
}
