/* The discrete adjoint of Radau IIA (radau.c): the gradient of a function of the states
 * the driver's Radau IIA computes at the output times (of its scheme, the step sizes
 * held), along the initial state,
 * the held inputs and the parameters (softcurve_adjoint_forward and _backward,
 * softcurve_driver.h).
 *
 * The forward pass steps to every output time (each a step's end: a restart there keeps
 * the step size and the Jacobian, radau.c) and tapes each accepted step: where it began,
 * its size, its input, its Jacobian and its converged stage increments Z. Differentiated,
 * a step y1 = y0 + Z_3 whose stages solve Z = h (A (x) I) F(y0 + Z, u, p) sends the
 * adjoint lambda of y1 back as follows (the step sizes are the forward pass's, not
 * differentiated, as CVODES's are not): nu = h (A^T (x) I) mu with
 * (I - h (A^T (x) I) diag(J_j^T)) nu = h (A^T (x) I) Zbar, Zbar = (0, 0, lambda), where J_j
 * is f's Jacobian at stage j; then lambda_0 = lambda + sum_j J_j^T nu_j, and the inputs'
 * and parameters' adjoints gain sum_j f_u(Y_j)^T nu_j and f_p(Y_j)^T nu_j. The products
 * J_j^T nu_j are one reverse-mode evaluation of f per stage (the caller's vjp), so each
 * stage has its own exact Jacobian; the linear system is solved by the simplified Newton
 * iteration of the forward pass, transposed: on W = T^T nu the matrix splits as in
 * radau.c into a real system gamma / h - J^T and a complex one (alpha - i beta) / h - J^T,
 * factored with the taped Jacobian J and reused while h and J stay. Where the iteration
 * does not converge on the taped Jacobian it runs once more on a fresh one at the step's
 * start. */
#include <complex.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "driver_internal.h"

#define TAPE_ENTRY(n) (TAPE_HEAD + 4 * (long)(n)) /* doubles of a taped step */
/* The multipliers of a step are converged when the simplified Newton correction is at
 * most this fraction of rtol of their size (their largest entry). On the paper robot's
 * 10 s swing at rtol 1e-6 (a step ending at each of 100 output times) the gradient then
 * differs from one converged to 1e-10 by 4e-6 to 9e-6 relative (7e-5 at 10 rtol), the
 * forward pass's own error being 4e-7 of the states' scales. */
#define ADJOINT_TOLERANCE 1.0
/* A step whose multipliers took more than this many rounds of vjp evaluations has the
 * next step start on a fresh Jacobian, kept from then on: the forward pass keeps its
 * Jacobian while its predicted stages converge, which the backward pass has no
 * predictor for. There, 2 took 9.5 ms against 10.9 ms never refreshing and 10.4 ms
 * refreshing at every step. */
#define SLOW_ROUNDS 2

/* Tapes the step r just accepted (its Jacobian too, where it is another than the last
 * taped, last[0] its count of Jacobians then), with its input row; 0 or TAPE_FULL. */
static int tape_step(const sc_radau *r, const sc_work *s, int row, double *tape, long capacity,
                     double *jacobians, long jacobian_capacity, long *used, long *last) {
    int n = r->n;
    double *at;
    if (used[0] >= capacity) return TAPE_FULL;
    at = tape + used[0] * TAPE_ENTRY(n);
    if (s->jacobians != *last) { /* the Jacobian this step iterated on */
        if (used[1] >= jacobian_capacity) return TAPE_FULL;
        memcpy(jacobians + used[1] * n * n, s->J, sizeof(double) * n * n);
        used[1]++, *last = s->jacobians;
    }
    at[TAPE_T] = r->t_last, at[TAPE_H] = r->h_last, at[TAPE_ROW] = row;
    at[TAPE_JACOBIAN] = (double)(used[1] - 1);
    memcpy(at + TAPE_HEAD, r->y_last, sizeof(double) * n);
    memcpy(at + TAPE_HEAD + n, r->z, sizeof(double) * 3 * n);
    used[0]++;
    return 0;
}

/* softcurve_driver.h */
SC_EXPORT int softcurve_adjoint_forward(const sc_function *fn, const sc_options *options,
                                        const double *u, const double *p,
                                        const double *nominal, const double *times, int count,
                                        const int *stops, double *out, long *owner,
                                        double *abscissa, double *tape, long capacity,
                                        double *jacobians, long jacobian_capacity, long *used,
                                        long *stats, int *reached) {
    int n = states_of(fn), inputs = inputs_of(fn), i = 1, j, start = 0, end, flag = 0;
    long taken, last_jacobian = -1;
    double tret, *y0 = (double *)malloc(sizeof(double) * n);
    sc_work s;
    sc_radau r;
    used[0] = used[1] = 0;
    *reached = 1;
    owner[0] = -1, abscissa[0] = 0.0;
    memset(&r, 0, sizeof(r));
    if (work_open(&s, fn, n) || !y0 || radau_open(&r, &s, options)) {
        flag = -100;
        goto done;
    }
    s.nominal = nominal, s.p = p;
    for (j = 0; j < n; ++j) y0[j] = out[j] / nominal[j];
    while (i < count && !flag) { /* one input from times[start] to the next stop */
        for (end = i; end < count - 1 && !stops[end]; ++end) {}
        s.u = u + (long)start * inputs;
        flag = radau_start(&r, times[start], y0, times[end], 0);
        for (taken = 0; !flag && i <= end;) {
            if (++taken > options->max_steps) flag = CV_TOO_MUCH_WORK;
            if (!flag) flag = radau_step(&r, &tret);
            if (!flag) flag = tape_step(&r, &s, start, tape, capacity, jacobians,
                                        jacobian_capacity, used, &last_jacobian);
            for (; !flag && i <= end && times[i] <= r.t; ++i, taken = 0) { /* outputs passed */
                radau_interpolate(&r, times[i], out + (long)i * n);
                for (j = 0; j < n; ++j) out[(long)i * n + j] *= nominal[j];
                owner[i] = used[0] - 1;
                abscissa[i] = times[i] == r.t ? 1.0 : (times[i] - r.t_last) / r.h_last;
                *reached = i + 1;
            }
        }
        add_counters(r.counters, stats, 1);
        memset(r.counters, 0, sizeof(r.counters));
        start = end;
    }
    stats[2] += s.jacobians;
done:
    radau_close(&r);
    work_close(&s);
    free(y0);
    return flag;
}

/* out_i = sum_m M[3 m + i] in_m: radau_mix with the transpose of M. */
static void mix_transposed(const double *M, const double *in, int n, double *out) {
    int i, j;
    for (i = 0; i < 3; ++i)
        for (j = 0; j < n; ++j)
            out[i * n + j] = M[i] * in[j] + M[3 + i] * in[n + j] + M[6 + i] * in[2 * n + j];
}

typedef struct {
    sc_work s; /* f and the fresh Jacobians */
    const double *k; /* Radau IIA's constants */
    int n, m, np;
    casadi_fn vjp;
    sc_arrays c;
    double *x, *v;         /* the vjp's arguments: a physical stage state, its seed */
    double *xb, *ub, *pb;  /* per stage: the vjp's results (x scaled back), 3 blocks each */
    double *zbar, *start, *tz, *w, *dw, *g, *nu, *jt;
    double *f0;
    double complex *lu;    /* the complex factors, then n for a solve */
    int *piv;
    double h_factored;     /* the factors' step size (0: none) and Jacobian */
    long jacobian_factored;
    int own;   /* the factors are of a->s.J, a fresh Jacobian (else of a taped one) */
    int stale; /* the last step converged slowly: refresh before the next */
    long evaluations, iterations, factorizations, fresh;
} sc_adjoint;

static void adjoint_close(sc_adjoint *a) {
    work_close(&a->s);
    arrays_close(&a->c);
    free(a->x);
    free(a->lu);
    free(a->piv);
}

/* 0, or 1 when out of memory (adjoint_close frees what was allocated). */
static int adjoint_open(sc_adjoint *a, const sc_function *fn, const sc_options *options,
                        casadi_fn vjp, const long long *sizes) {
    int n = states_of(fn), m = inputs_of(fn);
    long nn = (long)n * n;
    memset(a, 0, sizeof(*a));
    a->k = options->radau, a->n = n, a->m = m, a->np = fn->np, a->vjp = vjp;
    a->jacobian_factored = -1;
    if (work_open(&a->s, fn, n) || arrays_open(&a->c, sizes[0], sizes[1], sizes[2], sizes[3], 0))
        return 1;
    a->x = (double *)calloc(3 * n + 3 * (n + m + fn->np) + 21 * n + nn + n, sizeof(double));
    a->lu = malloc(sizeof(double complex) * (size_t)(nn + n));
    a->piv = (int *)malloc(sizeof(int) * (size_t)n);
    if (!a->x || !a->lu || !a->piv || a->k == NULL) return 1;
    a->v = a->x + n, a->xb = a->v + n, a->ub = a->xb + 3 * n, a->pb = a->ub + 3 * m;
    a->zbar = a->pb + 3 * fn->np, a->start = a->zbar + 3 * n, a->tz = a->start + n;
    a->w = a->tz + 3 * n;
    a->dw = a->w + 3 * n, a->g = a->dw + 3 * n, a->nu = a->g + 3 * n, a->f0 = a->nu + 3 * n;
    a->jt = a->f0 + 3 * n; /* after f0: 3 n spare for newton_jacobian's f, then J^T */
    return 0;
}

/* The Newton matrices transposed, I - (h / gamma) J^T and I - conj(mu) J^T, factored for
 * the Jacobian J (column-major, n x n); 1 where one is singular. */
static int factor_transposed(sc_adjoint *a, const double *J, double h, long which) {
    int n = a->n, i, j;
    double complex mu = h / (a->k[RADAU_ALPHA] + I * a->k[RADAU_BETA]);
    for (j = 0; j < n; ++j)
        for (i = 0; i < n; ++i) a->jt[i + j * n] = J[j + i * n];
    a->h_factored = 0.0;
    a->factorizations++;
    if (factor_newton(a->jt, h / a->k[RADAU_GAMMA], n, a->s.LU, a->s.piv) ||
        factor_complex(a->jt, conj(mu), n, a->lu, a->piv))
        return 1;
    a->h_factored = h, a->jacobian_factored = which;
    return 0;
}

/* The vjp at stage i of the step from y0 (scaled) with stages z: xb_i = D f_x^T (nu_i / D)
 * (the scaled state's), ub_i, pb_i; 0 or the vjp's nonzero. */
static int stage_products(sc_adjoint *a, const double *y0, const double *z, const double *u,
                          const double *p, const double *nominal, int i) {
    int n = a->n, j, flag;
    for (j = 0; j < n; ++j) {
        a->x[j] = nominal[j] * (y0[j] + z[i * n + j]);
        a->v[j] = a->nu[i * n + j] / nominal[j];
    }
    a->c.arg[0] = a->x, a->c.arg[1] = u, a->c.arg[2] = p, a->c.arg[3] = a->v;
    a->c.res[0] = a->xb + i * n, a->c.res[1] = a->ub + i * a->m, a->c.res[2] = a->pb + i * a->np;
    flag = a->vjp(a->c.arg, a->c.res, a->c.iw, a->c.w, 0);
    a->evaluations++;
    for (j = 0; j < n; ++j) a->xb[i * n + j] *= nominal[j];
    return flag;
}

/* nu of one step (its size h, start y0, stages z, the adjoints of its stages in a->zbar:
 * its end's and its outputs') by the transposed simplified Newton iteration on the
 * factors in a, and the vjp's results at it in xb, ub, pb: 0, 1 where it does not
 * converge, -1 where the vjp fails; *rounds: its rounds of vjp evaluations. */
static int step_multipliers(sc_adjoint *a, double h, const double *y0, const double *z,
                            const double *u, const double *p,
                            const double *nominal, double tolerance, int *rounds) {
    const double *k = a->k;
    int n = a->n, i, j, it;
    double gamma = k[RADAU_GAMMA] / h, alpha = k[RADAU_ALPHA] / h, beta = k[RADAU_BETA] / h;
    double complex mu = conj(h / (k[RADAU_ALPHA] + I * k[RADAU_BETA])), *x = a->lu + n * n;
    double previous = 0.0;
    memset(a->xb, 0, sizeof(double) * 3 * n);
    memset(a->w, 0, sizeof(double) * 3 * n);
    for (it = 0; it <= NEWTON_ITERATIONS; ++it) {
        double norm = 0.0, size = 0.0;
        if (it > 0)
            for (i = 0; i < 3; ++i)
                if (stage_products(a, y0, z, u, p, nominal, i)) return -1;
        for (j = 0; j < 3 * n; ++j) a->g[j] = a->xb[j] + a->zbar[j];
        mix_transposed(k + RADAU_T, a->g, n, a->tz);
        for (j = 0; j < n; ++j) {
            double w1 = a->w[n + j], w2 = a->w[2 * n + j];
            a->dw[j] = (h / k[RADAU_GAMMA]) * (a->tz[j] - gamma * a->w[j]);
            x[j] = (a->tz[n + j] - alpha * w1 - beta * w2) +
                   I * (a->tz[2 * n + j] + beta * w1 - alpha * w2);
        }
        solve_newton(a->s.LU, a->s.piv, n, a->dw);
        solve_complex(a->lu, a->piv, n, x);
        for (j = 0; j < n; ++j) {
            double complex v = mu * x[j];
            a->dw[n + j] = creal(v), a->dw[2 * n + j] = cimag(v);
        }
        for (j = 0; j < 3 * n; ++j) {
            if (!isfinite(a->dw[j])) return 1; /* fmax would pass over a NaN */
            norm = fmax(norm, fabs(a->dw[j]));
            size = fmax(size, fabs(a->w[j] + a->dw[j]));
        }
        a->iterations++;
        *rounds = it;
        if (it > 0) {
            if (norm <= tolerance * size || size == 0.0) return 0;
            if (it > 1 && norm >= previous) return 1; /* not contracting */
        }
        previous = norm;
        for (j = 0; j < 3 * n; ++j) a->w[j] += a->dw[j];
        mix_transposed(k + RADAU_TI, a->w, n, a->nu);
    }
    return 1;
}

/* A fresh Jacobian at the step's start y0 (scaled) with the inputs u, kept in a->s.J from
 * here on (a->own), and the transposed Newton matrices factored at h; 0, or 1 where f, the
 * Jacobian or the factors fail. */
static int refresh(sc_adjoint *a, const double *y0, const double *u, double h) {
    int n = a->n;
    a->s.u = u;
    memcpy(a->f0 + n, y0, sizeof(double) * n); /* newton_jacobian moves its y */
    if (evaluate(&a->s, y0, a->f0) || newton_jacobian(&a->s, a->f0 + n, a->f0)) return 1;
    a->fresh++, a->own = 1, a->stale = 0;
    return factor_transposed(a, a->s.J, h, -1);
}

/* Adds the seed of output i (physical, seeds[i, :]) to a step's adjoints: its end's
 * (lambda) where the output is the step's end, else the stages' (a->zbar) and its
 * start's (a->start) by the collocation polynomial at the output's abscissa x. Returns
 * whether the stages got any. */
static int seed_output(sc_adjoint *a, const double *seed, const double *nominal, double x,
                       double *lambda) {
    const double *P = a->k + RADAU_P;
    int n = a->n, j, m;
    if (x == 1.0) {
        for (j = 0; j < n; ++j) lambda[j] += nominal[j] * seed[j];
        return 0;
    }
    for (m = 0; m < 3; ++m) { /* stage m's weight: the polynomial of P's column m */
        double weight = radau_polynomial(P + m, 3, x, 0);
        for (j = 0; j < n; ++j) a->zbar[m * n + j] += weight * nominal[j] * seed[j];
    }
    for (j = 0; j < n; ++j) a->start[j] += nominal[j] * seed[j];
    return 1;
}

/* softcurve_driver.h */
SC_EXPORT int softcurve_adjoint_backward(const sc_function *fn, const sc_options *options,
                                         casadi_fn vjp, const long long *vjp_sizes,
                                         const double *u, const double *p,
                                         const double *nominal, int count, const long *owner,
                                         const double *abscissa, const double *tape,
                                         long steps, const double *jacobians,
                                         const double *seeds, double *lambda, double *d_u,
                                         double *d_p, long *stats) {
    int n = states_of(fn), inputs = inputs_of(fn), i, j, flag = 0, rounds = 0, inner, fresh;
    long step, entry = TAPE_ENTRY(n), next = count - 1;
    double tolerance = fmax(ADJOINT_TOLERANCE * options->rtol, 10.0 * DBL_EPSILON);
    sc_adjoint a;
    memset(lambda, 0, sizeof(double) * n);
    if (adjoint_open(&a, fn, options, vjp, vjp_sizes)) {
        flag = -100;
        goto done;
    }
    a.s.nominal = nominal, a.s.p = p;
    for (step = steps - 1; step >= 0; --step) {
        const double *at = tape + step * entry, *y0 = at + TAPE_HEAD, *z = y0 + n;
        const double *u_step = u + (long)at[TAPE_ROW] * inputs;
        double h = at[TAPE_H], *du = d_u + (long)at[TAPE_ROW] * inputs;
        long which = (long)at[TAPE_JACOBIAN];
        memset(a.zbar, 0, sizeof(double) * 3 * n);
        memset(a.start, 0, sizeof(double) * n);
        for (inner = 0; next > 0 && owner[next] == step; --next) /* the outputs it passed */
            inner |= seed_output(&a, seeds + next * n, nominal, abscissa[next], lambda);
        for (j = 0; j < n && lambda[j] == 0.0; ++j) {}
        if (j == n && !inner) continue; /* nothing after this step is seeded */
        for (j = 0; j < n; ++j) a.zbar[2 * n + j] += lambda[j]; /* y1 = y0 + Z_3 */
        fresh = a.stale;
        if (fresh) { /* the last step converged slowly: a fresh Jacobian from here on */
            if (refresh(&a, y0, u_step, h)) {
                flag = CV_LSETUP_FAIL;
                break;
            }
        } else if (h != a.h_factored || (!a.own && which != a.jacobian_factored)) {
            if (factor_transposed(&a, a.own ? a.s.J : jacobians + which * n * n, h, which)) {
                flag = CV_LSETUP_FAIL;
                break;
            }
        }
        flag = step_multipliers(&a, h, y0, z, u_step, p, nominal, tolerance, &rounds);
        if (flag == 1 && !fresh) { /* once more on a fresh Jacobian at the step's start */
            if (refresh(&a, y0, u_step, h)) {
                flag = CV_LSETUP_FAIL;
                break;
            }
            flag = step_multipliers(&a, h, y0, z, u_step, p, nominal, tolerance, &rounds);
        }
        a.stale = rounds > SLOW_ROUNDS;
        if (flag) {
            flag = flag < 0 ? CV_RHSFUNC_FAIL : CV_CONV_FAILURE;
            break;
        }
        for (j = 0; j < n; ++j) lambda[j] += a.start[j];
        for (i = 0; i < 3; ++i) {
            for (j = 0; j < n; ++j) lambda[j] += a.xb[i * n + j];
            for (j = 0; j < inputs; ++j) du[j] += a.ub[i * inputs + j];
            for (j = 0; j < fn->np; ++j) d_p[j] += a.pb[i * fn->np + j];
        }
        for (j = 0; j < 3 * inputs && isfinite(a.ub[j]); ++j) {}
        for (i = 0; i < 3 * fn->np && isfinite(a.pb[i]); ++i) {}
        if (j < 3 * inputs || i < 3 * fn->np) { /* the multipliers' own test passes these */
            flag = CV_RHSFUNC_FAIL;
            break;
        }
    }
    if (!flag) {
        for (; next >= 0; --next) /* the start, and outputs no step passed */
            for (j = 0; j < n; ++j) lambda[j] += nominal[j] * seeds[next * n + j];
        for (j = 0; j < n; ++j) lambda[j] /= nominal[j]; /* the physical state's */
    }
    stats[0] += a.evaluations, stats[1] += a.iterations, stats[2] += a.factorizations;
    stats[3] += a.fresh;
done:
    adjoint_close(&a);
    return flag;
}
