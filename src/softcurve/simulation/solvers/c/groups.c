/* softcurve_integrate (softcurve_driver.h): members integrated one by one, by CVODES or by
 * Radau IIA (radau.c), or, where the problem has the state derivative over lanes
 * (lanes_derivative of softcurve.simulation.solvers), in groups whose members are stacked
 * into one CVODES system and evaluated together.
 *
 * Why groups: one lanes evaluation of four members costs about one scalar evaluation
 * (softcurve.compiled.LANE_WIDTH), and CVODES's own work per step (vector
 * operations, error test, interpolation) is shared by the group. The members then share
 * the group's steps, about 1.3 times the steps of each alone on the paper's batch
 * (benchmarks/study_stacked_batch.py). Each member keeps its own accuracy: the group's
 * tolerances are those of one member divided by the square root of the group's size, so
 * that the group's weighted RMS norm is at least every member's own. A group with a member
 * that fails or leaves the domain is integrated again member by member, so that a group's
 * failure reads exactly as the members' runs alone (a member that would fail alone may
 * succeed in its group, whose steps are smaller). Only members of one family (Adams or
 * BDF) form a group. */
#define _ISOC11_SOURCE /* aligned_alloc under -std=c99 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "driver_internal.h"

/* A group of g members stacked member-major (member l's scaled states at y[l n, l n + n))
 * with the lanes state derivative; the Newton matrix is block-diagonal, one block per
 * member, each from forward differences of all members at once. */
typedef struct {
    const sc_function *fn;
    int g, n;
    const double *nominal; /* g rows of n */
    double *X, *U, *P, *XD, *W; /* lanes: entry j of member l at [j g + l] */
    double *J, *LU, *ftmp, *saved, *step;
    int *piv;
    long jacobians;
} sc_group;

static double *aligned(long count) {
    long bytes = ((count * (long)sizeof(double) + 63) / 64) * 64;
    return (double *)aligned_alloc(64, bytes > 0 ? bytes : 64);
}

static void group_close(sc_group *G) {
    free(G->X), free(G->U), free(G->P), free(G->XD), free(G->W);
    free(G->J), free(G->LU), free(G->ftmp), free(G->saved), free(G->step), free(G->piv);
}

/* 0, or 1 when out of memory (group_close frees what was allocated). */
static int group_open(sc_group *G, const sc_function *fn, int n) {
    int g = fn->width, inputs = inputs_of(fn);
    memset(G, 0, sizeof(*G));
    G->fn = fn, G->g = g, G->n = n;
    G->X = aligned((long)g * n), G->XD = aligned((long)g * n);
    G->U = aligned((long)g * (inputs > 0 ? inputs : 1)), G->P = aligned((long)g * fn->np);
    G->W = aligned((long)g * fn->sz_lanes_w);
    G->J = (double *)malloc(sizeof(double) * g * n * n);
    G->LU = (double *)malloc(sizeof(double) * g * n * n);
    G->ftmp = (double *)malloc(sizeof(double) * g * n);
    G->saved = (double *)malloc(sizeof(double) * g);
    G->step = (double *)malloc(sizeof(double) * g);
    G->piv = (int *)malloc(sizeof(int) * g * n);
    return !(G->X && G->XD && G->U && G->P && G->W && G->J && G->LU && G->ftmp && G->saved &&
             G->step && G->piv);
}

/* ydot = f(nominal * y, u, p) / nominal for every member; 1 (recoverable) on a non-finite
 * value */
static int group_evaluate(sc_group *G, const double *y, double *ydot) {
    int g = G->g, n = G->n, l, j;
    for (l = 0; l < g; ++l)
        for (j = 0; j < n; ++j) G->X[j * g + l] = G->nominal[l * n + j] * y[l * n + j];
    if (G->fn->lanes(G->X, G->U, G->P, G->XD, G->W)) return -1;
    for (l = 0; l < g; ++l)
        for (j = 0; j < n; ++j) ydot[l * n + j] = G->XD[j * g + l] / G->nominal[l * n + j];
    for (j = 0; j < g * n; ++j)
        if (!isfinite(ydot[j])) return 1;
    return 0;
}

static int group_rhs(realtype t, N_Vector y, N_Vector ydot, void *data) {
    (void)t;
    return group_evaluate((sc_group *)data, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
}

/* setup() of every block: column j of all members' Jacobians from one evaluation. */
static int group_setup(realtype t, N_Vector yv, N_Vector fyv, int jok, int *jcur,
                       realtype gamma, void *data, N_Vector t1, N_Vector t2, N_Vector t3) {
    sc_group *G = (sc_group *)data;
    int g = G->g, n = G->n, i, j, l, flag;
    double *y = N_VGetArrayPointer(yv), *fy = N_VGetArrayPointer(fyv);
    (void)t; (void)t1; (void)t2; (void)t3;
    if (!jok) {
        for (j = 0; j < n; ++j) {
            for (l = 0; l < g; ++l) {
                G->saved[l] = y[l * n + j];
                G->step[l] = difference_step(G->saved[l]);
                y[l * n + j] = G->saved[l] + G->step[l];
            }
            flag = group_evaluate(G, y, G->ftmp);
            for (l = 0; l < g; ++l) y[l * n + j] = G->saved[l];
            if (flag) return flag;
            for (l = 0; l < g; ++l)
                for (i = 0; i < n; ++i)
                    G->J[(long)l * n * n + i + j * n] =
                        (G->ftmp[l * n + i] - fy[l * n + i]) / G->step[l];
        }
        G->jacobians++;
        *jcur = 1;
    } else {
        *jcur = 0;
    }
    for (l = 0; l < g; ++l)
        if (factor_newton(G->J + (long)l * n * n, gamma, n, G->LU + (long)l * n * n,
                          G->piv + l * n))
            return 1;
    return 0;
}

static int group_solve(realtype t, N_Vector yv, N_Vector fyv, N_Vector rv, N_Vector zv,
                       realtype gamma, realtype delta, int lr, void *data, N_Vector tmp) {
    sc_group *G = (sc_group *)data;
    int n = G->n, l;
    double *r = N_VGetArrayPointer(rv), *z = N_VGetArrayPointer(zv);
    (void)t; (void)yv; (void)fyv; (void)gamma; (void)delta; (void)lr; (void)tmp;
    if (z != r) memcpy(z, r, (size_t)G->g * n * sizeof(double));
    for (l = 0; l < G->g; ++l) solve_newton(G->LU + (long)l * n * n, G->piv + l * n, n, z + l * n);
    return 0;
}

static int group_jtimes(N_Vector vv, N_Vector Jvv, realtype t, N_Vector y, N_Vector fy,
                        void *data, N_Vector tmp) {
    sc_group *G = (sc_group *)data;
    int n = G->n, l;
    double *v = N_VGetArrayPointer(vv), *Jv = N_VGetArrayPointer(Jvv);
    (void)t; (void)y; (void)fy; (void)tmp;
    for (l = 0; l < G->g; ++l) times_jacobian(G->J + (long)l * n * n, v + l * n, n, Jv + l * n);
    return 0;
}

/* One call of softcurve_integrate: its arguments and its work. */
typedef struct {
    const sc_function *fn;
    const int *lmm, *ends, *restart;
    const sc_options *o;
    const double *fastest, *u, *p, *nominal, *times;
    int n, inputs, check_domain, k, n_ends;
    double *out;
    int *reached, *flag, *used_bdf;
    long *stats;
    sc_work s;
    sc_group G;
    sc_radau radau;
    int radau_open; /* radau is allocated */
    void *mem[5]; /* by family (1 Adams, 2 BDF), + 2 for a group */
    N_Vector y[2], dky[2]; /* one member's, a group's */
} sc_call;

/* Integrate members b .. b + g - 1: one alone (g == 1) or a group stacked in one system.
 * Returns 1 where a member of a group failed or left the domain (the caller then
 * integrates them again alone), else 0. */
static int integrate_members(sc_call *c, int b, int g) {
    int n = c->n, grouped = g > 1, own, family, radau, first = 0, stop = 0, l, i, j, e;
    double *ys = N_VGetArrayPointer(c->y[grouped]), *out_y = N_VGetArrayPointer(c->dky[grouped]);
    double tret, *ftmp = grouped ? c->G.ftmp : c->s.ftmp;
    const double *nominal = c->nominal + (long)b * n;
    void *data = grouped ? (void *)&c->G : (void *)&c->s;
    for (l = 0; l < g; ++l) c->flag[b + l] = 0, c->reached[b + l] = 1;
    own = family = c->lmm[b] == FAMILY_RADAU ? FAMILY_RADAU
                   : c->lmm[b] == CV_BDF      ? CV_BDF
                                              : CV_ADAMS; /* a group's members share it */
    radau = family == FAMILY_RADAU; /* never in a group */
    for (l = 0; l < g; ++l) c->used_bdf[b + l] = family == CV_BDF;
    if (radau) radau_reset(&c->radau);
    if (grouped) {
        c->G.nominal = nominal;
        for (l = 0; l < g; ++l)
            for (j = 0; j < c->fn->np; ++j) c->G.P[j * g + l] = c->p[(long)(b + l) * c->fn->np + j];
    } else {
        c->s.p = c->p + (long)b * c->fn->np;
        c->s.nominal = nominal;
    }
    for (e = 0; e < c->n_ends && !stop; first = c->ends[e], ++e) {
        long counters[5] = {0, 0, 0, 0, 0};
        int slot;
        int switches = e > 0 && c->restart[e] && !radau;
        for (l = 0; l < g; ++l) {
            const double *u = c->u + ((long)(b + l) * c->n_ends + e) * c->inputs;
            const double *start = c->out + ((long)(b + l) * c->k + first) * n;
            for (j = 0; grouped && j < c->inputs; ++j) c->G.U[j * g + l] = u[j];
            if (!grouped) c->s.u = u;
            for (j = 0; j < n; ++j) ys[l * n + j] = start[j] / nominal[l * n + j];
            switches = switches && c->fastest[b + l] > 0.0;
        }
        if (switches) { /* to BDF where every member has settled, as each alone would */
            int settled = 1, ok = grouped ? group_evaluate(&c->G, ys, ftmp) == 0
                                          : evaluate(&c->s, ys, ftmp) == 0;
            for (l = 0; l < g; ++l) {
                double fastest_state = 0.0;
                for (j = 0; ok && j < n; ++j)
                    fastest_state = fmax(fastest_state, fabs(ftmp[l * n + j]));
                settled = settled && fastest_state * c->o->settled_ratio < c->fastest[b + l];
            }
            family = settled ? CV_BDF : own;
            for (l = 0; l < g; ++l) c->used_bdf[b + l] |= family == CV_BDF;
        }
        if (grouped) c->G.jacobians = 0; else c->s.jacobians = 0;
        slot = family + 2 * grouped;
        if (radau) { /* steps stop only where the input changes */
            const double *u = c->u + ((long)b * c->n_ends + e) * c->inputs;
            size_t bytes = sizeof(double) * c->inputs;
            int same = e > 0 && memcmp(u, u - c->inputs, bytes) == 0, last = e;
            while (last + 1 < c->n_ends && memcmp(u, u + (last + 1 - e) * c->inputs, bytes) == 0)
                ++last;
            stop = radau_start(&c->radau, c->times[first], ys, c->times[c->ends[last]], same);
        } else if (c->mem[slot] == NULL) {
            double shrink = sqrt((double)g); /* the group's norm bounds every member's */
            c->mem[slot] = grouped ? create_with(family, c->times[first], c->y[1], group_rhs,
                                                 group_setup, group_solve, group_jtimes, data,
                                                 c->o->rtol / shrink, c->o->atol / shrink,
                                                 c->o->max_steps, c->o->max_order)
                                   : create(family, c->times[first], c->y[0], rhs, data,
                                            c->o->rtol, c->o->atol, c->o->max_steps, c->o->max_order);
            stop = c->mem[slot] == NULL ? -100 : 0;
        } else if (CVodeReInit(c->mem[slot], c->times[first], c->y[grouped])) {
            stop = -100;
        }
        if (stop) {
            for (l = 0; l < g; ++l) c->flag[b + l] = stop;
            break;
        }
        if (!radau) CVodeSetStopTime(c->mem[slot], c->times[c->ends[e]]);
        tret = radau ? c->radau.t : c->times[first]; /* Radau IIA may be ahead */
        for (i = first + 1; i <= c->ends[e] && !stop; ++i) {
            /* One internal step at a time, and every output it passed interpolated:
             * CVODES's normal mode costs a call per output, a third of the cost of an
             * output on a 1 ms grid. The step budget is per output, as in that mode, and
             * tout the next output: CVODES sizes a restart's first step by it. */
            long taken = 0;
            while (tret < c->times[i] && !stop) {
                int status = ++taken > c->o->max_steps ? CV_TOO_MUCH_WORK
                             : radau ? radau_step(&c->radau, &tret)
                                     : CVode(c->mem[slot], c->times[i], c->y[grouped], &tret,
                                             CV_ONE_STEP);
                if (status < 0) stop = status;
            }
            if (!stop && radau)
                radau_interpolate(&c->radau, c->times[i], out_y);
            else if (!stop && CVodeGetDky(c->mem[slot], c->times[i], 0, c->dky[grouped]))
                stop = -100;
            if (stop) {
                for (l = 0; l < g; ++l) c->flag[b + l] = stop;
                break;
            }
            for (l = 0; l < g; ++l) {
                double *row = c->out + ((long)(b + l) * c->k + i) * n;
                for (j = 0; j < n; ++j) row[j] = out_y[l * n + j] * nominal[l * n + j];
                c->reached[b + l] = i + 1;
                if (outside(&c->s, row, n,
                            c->check_domain ? c->p + (long)(b + l) * c->fn->np : NULL))
                    c->flag[b + l] = stop = 1;
            }
        }
        if (radau)
            memcpy(counters, c->radau.counters, sizeof(counters));
        else
            read_counters(c->mem[slot], counters);
        for (l = 0; l < g; ++l) {
            long *stats = c->stats + (long)(b + l) * STATS;
            add_counters(counters, stats, 1);
            stats[2] += grouped ? c->G.jacobians : c->s.jacobians;
        }
    }
    return grouped && stop != 0;
}

/* softcurve_driver.h */
SC_EXPORT int softcurve_integrate(const sc_function *fn, const sc_options *options, int count,
                                  const int *lmm, const double *fastest, const double *u,
                                  const double *p, const double *nominal, int check_domain,
                                  const double *times, int k, const int *ends,
                                  const int *restart, int n_ends, double *out, int *reached,
                                  int *flag, int *used_bdf, long *stats) {
    int width = fn->lanes != NULL && fn->width > 1 ? fn->width : 1, b, g, l, i, e, failed;
    long *kept = (long *)malloc(sizeof(long) * STATS * width); /* counters before a group */
    sc_call c;
    memset(&c, 0, sizeof(c));
    c.fn = fn, c.o = options, c.lmm = lmm, c.ends = ends, c.restart = restart;
    c.fastest = fastest, c.u = u, c.p = p, c.nominal = nominal, c.check_domain = check_domain;
    c.times = times, c.n = states_of(fn), c.inputs = inputs_of(fn);
    c.k = k, c.n_ends = n_ends, c.out = out, c.reached = reached, c.flag = flag;
    c.used_bdf = used_bdf, c.stats = stats;
    c.y[0] = N_VNew_Serial(c.n), c.dky[0] = N_VNew_Serial(c.n);
    c.y[1] = N_VNew_Serial((long)width * c.n), c.dky[1] = N_VNew_Serial((long)width * c.n);
    failed = work_open(&c.s, fn, c.n) || !c.y[0] || !c.dky[0] || !c.y[1] || !c.dky[1] || !kept;
    if (width > 1) failed = group_open(&c.G, fn, c.n) || failed;
    for (b = 0; b < count && !c.radau_open; ++b)
        if (lmm[b] == FAMILY_RADAU) {
            c.radau_open = 1;
            failed = radau_open(&c.radau, &c.s, options) || failed;
        }
    for (b = 0; b < count && failed; ++b) flag[b] = -100, reached[b] = 1;
    for (b = 0; b < count && !failed; b += g) {
        int alike = 1, tried = 0;
        g = width > 1 && count - b >= width ? width : 1;
        for (l = 0; l < g; ++l) alike = alike && lmm[b + l] == lmm[b] && lmm[b] != FAMILY_RADAU;
        if (g > 1 && alike) {
            memcpy(kept, stats + (long)b * STATS, sizeof(long) * STATS * g);
            if (!integrate_members(&c, b, g)) continue;
            memcpy(stats + (long)b * STATS, kept, sizeof(long) * STATS * g);
            tried = 1;
        }
        for (l = 0; l < g; ++l) { /* alone: the rest, a group of mixed families, or failed */
            int before = reached[b + l];
            double *rows = out + (long)(b + l) * k * c.n;
            integrate_members(&c, b + l, 1);
            /* what the group wrote beyond what the member reaches alone is not an output */
            for (i = reached[b + l]; tried && i < before; ++i)
                for (e = 0; e < c.n; ++e) rows[(long)i * c.n + e] = NAN;
        }
    }
    for (i = 1; i < 5; ++i)
        if (c.mem[i] != NULL) CVodeFree(&c.mem[i]);
    for (i = 0; i < 2; ++i) {
        if (c.y[i] != NULL) N_VDestroy(c.y[i]);
        if (c.dky[i] != NULL) N_VDestroy(c.dky[i]);
    }
    work_close(&c.s);
    if (width > 1) group_close(&c.G);
    if (c.radau_open) radau_close(&c.radau);
    free(kept);
    return 0;
}
