/* Radau IIA of order 5 (three stages), the driver's L-stable one-step method, on one
 * member's scaled state (an sc_work: its right-hand side, its Newton Jacobian, exact or by
 * differences, and its real factors).
 *
 * The method is that of Hairer and Wanner, Solving Ordinary Differential Equations II
 * (2nd ed., 1996), Sect. IV.8. The stage increments Z_i = Y_i - y solve the collocation
 * equations by a simplified Newton iteration on W = (T^-1 (x) I) Z, which splits the
 * 3n x 3n Newton matrix into a real system (gamma / h - J) and a complex one
 * ((alpha + i beta) / h - J). Both are factored once per step size and Jacobian and reused
 * across the iterations, the stages and the steps. The error is estimated by the embedded
 * formula of order 3 filtered through the real factors (their eq. 8.19-8.20, filtered
 * twice on a first or rejected step); the step size comes from the predictive controller
 * of Gustafsson; the collocation polynomial gives the dense output and the next step's
 * starting stages. The method's constants (nodes, T, eigenvalues, error weights, dense
 * output) are computed by Python from the collocation conditions and passed in
 * sc_options.radau (softcurve_driver.h, RADAU_*). The control constants below are the
 * book's defaults for its code RADAU5, except where a comment gives another reason.
 *
 * Only the step size and the Jacobian carry over a change of the input (a one-step
 * method has no history): a restart costs one evaluation of the right-hand side, where a
 * multistep method starts again at order one with short steps.
 */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "driver_internal.h"

#define SAFETY 0.9          /* the step size factor's safety, lowered by slow Newton */
#define FACTOR_MIN 0.2      /* the smallest change of the step size (FACTOR_MAX: largest) */
#define KEEP_STEP 1.2 /* a step size that would grow by at most this factor is kept, and
                         with it the factors of the Newton matrices */
#define END_SLACK 1.0001 /* a step ending this little past the stop ends at the stop */
/* The Jacobian is computed again after a step whose Newton iteration took more than two
 * iterations contracting by more than this (SciPy's rule for its Radau: Hairer and
 * Wanner's code computes it after every step converging slower than this, a cost of
 * n + 1 right-hand sides that the forward differences make as dear as three Newton
 * iterations at one segment). */
#define KEEP_JACOBIAN 1e-3
/* An error norm below this counts as this: the step size factor is then FACTOR_MAX
 * anyway, and the predictive controller's ratio of two norms stays finite. */
#define ERROR_FLOOR 1e-10

/* The weighted RMS norm of `blocks` blocks of n entries, each divided by scale (n). */
static double rms(const double *v, const double *scale, int n, int blocks) {
    double sum = 0.0;
    int i, b;
    for (b = 0; b < blocks; ++b)
        for (i = 0; i < n; ++i) {
            double e = v[b * n + i] / scale[i];
            sum += e * e;
        }
    return sqrt(sum / (double)(n * blocks));
}

/* driver_internal.h */
int radau_open(sc_radau *r, sc_work *s, const sc_options *o) {
    int n = s->n;
    memset(r, 0, sizeof(*r));
    r->s = s, r->k = o->radau, r->n = n, r->rtol = o->rtol, r->atol = o->atol;
    /* Newton's tolerance in units of the error tolerance: Hairer and Wanner's default
     * applied to rtol itself, as SciPy's Radau does (their code applies it to rtol mapped
     * to 0.1 rtol^(2/3) first) */
    r->newton_tolerance = fmax(10.0 * DBL_EPSILON / o->rtol, fmin(0.03, sqrt(o->rtol)));
    r->block = (double *)malloc(sizeof(double) * 25 * (size_t)n);
    r->lu = malloc(sizeof(double complex) * (size_t)n * n + sizeof(double complex) * n);
    r->piv = (int *)malloc(sizeof(int) * (size_t)n);
    if (!r->block || !r->lu || !r->piv || r->k == NULL) return 1;
    r->y = r->block, r->fy = r->y + n, r->y_last = r->fy + n, r->scale = r->y_last + n;
    r->v = r->scale + n, r->e = r->v + n, r->ze = r->e + n;
    r->z = r->ze + n, r->w = r->z + 3 * n, r->dw = r->w + 3 * n, r->f = r->dw + 3 * n;
    r->g = r->f + 3 * n, r->q = r->g + 3 * n; /* 7 n + 18 n doubles */
    radau_reset(r);
    return 0;
}

void radau_close(sc_radau *r) {
    free(r->block);
    free(r->lu);
    free(r->piv);
}

/* driver_internal.h */
void radau_reset(sc_radau *r) {
    r->h = 0.0, r->h_factored = 0.0, r->h_last = 0.0, r->error_last = 0.0;
    r->eta = 1.0; /* no contraction known: the first step iterates at least twice */
    r->jacobian = JACOBIAN_NONE, r->continues = 0;
}

/* driver_internal.h */
void radau_mix(const double *M, const double *in, int n, double *out) {
    int i, j;
    for (i = 0; i < 3; ++i)
        for (j = 0; j < n; ++j)
            out[i * n + j] =
                M[3 * i] * in[j] + M[3 * i + 1] * in[n + j] + M[3 * i + 2] * in[2 * n + j];
}

/* The input at time t, where it moves with time (r->inputs). */
static void inputs_at_time(sc_radau *r, double t) {
    if (r->inputs != NULL) r->inputs(r->inputs_data, t);
}

/* f at time t */
static int rhs_at(sc_radau *r, double t, const double *y, double *f) {
    r->counters[1]++;
    inputs_at_time(r, t);
    return evaluate(r->s, y, f);
}

/* The Newton matrices' factors at step size h: I - (h / gamma) J and I - (h / (alpha +
 * i beta)) J; 1 where one is singular. */
static int factor_pair(sc_radau *r, double h) {
    const double *k = r->k;
    double complex mu = h / (k[RADAU_ALPHA] + I * k[RADAU_BETA]);
    r->counters[2]++;
    r->h_factored = 0.0;
    if (factor_newton(r->s->J, h / k[RADAU_GAMMA], r->n, r->s->LU, r->s->piv) ||
        factor_complex(r->s->J, mu, r->n, r->lu, r->piv))
        return 1;
    r->h_factored = h;
    return 0;
}

/* The first step size from y and fy = f(y) (Hairer, Norsett and Wanner, Solving Ordinary
 * Differential Equations I, Sect. II.4, for an error estimate of order 3): one more
 * evaluation of f. */
static double first_step(sc_radau *r) {
    int n = r->n, j;
    double d0, d1, d2, h0, h1;
    for (j = 0; j < n; ++j) r->scale[j] = r->atol + r->rtol * fabs(r->y[j]);
    d0 = rms(r->y, r->scale, n, 1), d1 = rms(r->fy, r->scale, n, 1);
    h0 = d0 < 1e-5 || d1 < 1e-5 ? 1e-6 : 0.01 * d0 / d1;
    h0 = fmin(h0, r->t_stop - r->t);
    for (j = 0; j < n; ++j) r->v[j] = r->y[j] + h0 * r->fy[j];
    if (rhs_at(r, r->t + h0, r->v, r->e)) return h0;
    for (j = 0; j < n; ++j) r->e[j] -= r->fy[j];
    d2 = rms(r->e, r->scale, n, 1) / h0;
    h1 = d1 <= 1e-15 && d2 <= 1e-15 ? fmax(1e-6, 1e-3 * h0) : pow(0.01 / fmax(d1, d2), 0.25);
    return fmin(100.0 * h0, h1);
}

/* driver_internal.h */
int radau_start(sc_radau *r, double t0, const double *y, double t_stop, int same_input) {
    int n = r->n;
    memset(r->counters, 0, sizeof(r->counters));
    r->t_stop = t_stop;
    if (same_input && r->continues && r->t >= t0) return 0; /* the steps go on */
    if (r->continues && r->t == t0) {
        /* a new input where the last step ended: its polynomial still starts the stages */
        r->first = 1;
    } else {
        r->t = t0;
        memcpy(r->y, y, sizeof(double) * n);
        r->continues = 0, r->predict = 0, r->rejected = 0, r->first = 1, r->h_last = 0.0;
    }
    if (rhs_at(r, r->t, r->y, r->fy)) return CV_FIRST_RHSFUNC_ERR;
    if (r->h <= 0.0) r->h = first_step(r);
    r->continues = 1;
    return 0;
}

/* driver_internal.h */
double radau_polynomial(const double *q, int n, double x, int j) {
    return x * (q[j] + x * (q[n + j] + x * q[2 * n + j]));
}

/* driver_internal.h */
void radau_value(const sc_radau *r, double t, const double *last, const double *q,
                 const double *now, double *out) {
    int n = r->n, j;
    double x = r->h_last > 0.0 ? (t - r->t_last) / r->h_last : 1.0;
    for (j = 0; j < n; ++j)
        out[j] = t == r->t || r->h_last == 0.0 ? now[j] : last[j] + radau_polynomial(q, n, x, j);
}

/* driver_internal.h */
void radau_interpolate(const sc_radau *r, double t, double *out) {
    radau_value(r, t, r->y_last, r->q, r->y, out);
}

/* driver_internal.h */
void radau_predict(const sc_radau *r, const double *last, const double *q, const double *now,
                   double h_last, double h, double *z) {
    const double *c = r->k + RADAU_C;
    int n = r->n, i, j;
    if (!(h_last > 0.0 && h <= FACTOR_MAX * h_last)) {
        memset(z, 0, sizeof(double) * 3 * n);
        return;
    }
    for (i = 0; i < 3; ++i)
        for (j = 0; j < n; ++j)
            z[i * n + j] = last[j] + radau_polynomial(q, n, 1.0 + c[i] * h / h_last, j) - now[j];
}

/* driver_internal.h */
int radau_refresh(sc_radau *r) {
    if (rhs_at(r, r->t_last, r->y_last, r->e) || newton_jacobian(r->s, r->y_last, r->e))
        return 1;
    r->s->jacobians++;
    r->jacobian = JACOBIAN_KEPT;
    return factor_pair(r, r->h_last);
}

/* driver_internal.h */
void radau_correction(sc_radau *r, double h, const double *f, const double *w, double *dw) {
    const double *k = r->k;
    int n = r->n, j;
    double gamma = k[RADAU_GAMMA] / h, alpha = k[RADAU_ALPHA] / h, beta = k[RADAU_BETA] / h;
    double mu_real = h / k[RADAU_GAMMA];
    double complex mu = h / (k[RADAU_ALPHA] + I * k[RADAU_BETA]), *x = r->lu + n * n;
    radau_mix(k + RADAU_TI, f, n, r->g);
    for (j = 0; j < n; ++j) {
        double w1 = w[n + j], w2 = w[2 * n + j];
        dw[j] = mu_real * (r->g[j] - gamma * w[j]);
        x[j] = mu * ((r->g[n + j] - alpha * w1 + beta * w2) +
                     I * (r->g[2 * n + j] - beta * w1 - alpha * w2));
    }
    solve_newton(r->s->LU, r->s->piv, n, dw);
    solve_complex(r->lu, r->piv, n, x);
    for (j = 0; j < n; ++j) dw[n + j] = creal(x[j]), dw[2 * n + j] = cimag(x[j]);
}

/* The simplified Newton iteration of one step of size h from the stages in r->z: 0 when it
 * converged (the stages in r->z, its iterations and last contraction in *iterations and
 * *theta), 1 when it diverged or converges too slowly, or the failing right-hand side's
 * flag (1 recoverable, negative not). */
static int newton(sc_radau *r, double h, int *iterations, double *theta) {
    const double *k = r->k, *T = k + RADAU_T, *TI = k + RADAU_TI, *c = k + RADAU_C;
    int n = r->n, i, j, it, flag;
    double norm, previous = 0.0;
    double eta = pow(fmax(r->eta, DBL_EPSILON), 0.8); /* the last step's, as a first guess */
    *theta = 0.0;
    radau_mix(TI, r->z, n, r->w);
    for (it = 0; it < NEWTON_ITERATIONS; ++it) {
        for (i = 0; i < 3; ++i) {
            for (j = 0; j < n; ++j) r->v[j] = r->y[j] + r->z[i * n + j];
            flag = rhs_at(r, r->t + c[i] * h, r->v, r->f + i * n);
            if (flag) return flag;
        }
        radau_correction(r, h, r->f, r->w, r->dw);
        norm = rms(r->dw, r->scale, n, 3);
        if (!isfinite(norm)) return 1;
        if (it > 0) {
            *theta = norm / previous;
            if (*theta >= 1.0) return 1;
            eta = *theta / (1.0 - *theta);
            /* what the iterations left would leave beyond the tolerance */
            if (pow(*theta, NEWTON_ITERATIONS - 1 - it) * eta * norm > r->newton_tolerance)
                return 1;
        }
        previous = norm;
        for (j = 0; j < 3 * n; ++j) r->w[j] += r->dw[j];
        radau_mix(T, r->w, n, r->z);
        if (eta * norm <= r->newton_tolerance) {
            r->eta = eta;
            *iterations = it + 1;
            return 0;
        }
    }
    return 1;
}

/* The error estimate's norm of the converged step of size h (stages r->z), the estimate
 * filtered once more where `again`; INFINITY where it is not a number or the right-hand
 * side fails there. */
static double error_norm(sc_radau *r, double h, int again) {
    const double *E = r->k + RADAU_E;
    int n = r->n, j;
    double mu_real = h / r->k[RADAU_GAMMA], norm;
    for (j = 0; j < n; ++j) {
        double y_new = r->y[j] + r->z[2 * n + j];
        r->ze[j] = (E[0] * r->z[j] + E[1] * r->z[n + j] + E[2] * r->z[2 * n + j]) / h;
        r->e[j] = mu_real * (r->fy[j] + r->ze[j]);
        r->v[j] = r->atol + r->rtol * fmax(fabs(r->y[j]), fabs(y_new)); /* the error's scale */
    }
    solve_newton(r->s->LU, r->s->piv, n, r->e);
    norm = rms(r->e, r->v, n, 1);
    if (norm > 1.0 && again) {
        for (j = 0; j < n; ++j) r->e[j] += r->y[j];
        if (rhs_at(r, r->t, r->e, r->e)) return INFINITY; /* rejected: a shorter step */
        for (j = 0; j < n; ++j) r->e[j] = mu_real * (r->e[j] + r->ze[j]);
        solve_newton(r->s->LU, r->s->piv, n, r->e);
        norm = rms(r->e, r->v, n, 1);
    }
    return isnan(norm) ? INFINITY : fmax(norm, ERROR_FLOOR); /* NaN: rejected */
}

/* driver_internal.h */
int radau_step(sc_radau *r, double *tret) {
    int n = r->n, j, flag, iterations = 0;
    int failure = CV_ERR_FAILURE; /* or what made the last attempt fail */
    for (;;) {
        double h = r->h, theta, error, factor, h_new, *y_new = r->ze, *f_new = r->e;
        int clipped = r->t + END_SLACK * h >= r->t_stop;
        if (clipped) h = r->t_stop - r->t;
        if (!(h > 16.0 * DBL_EPSILON * fmax(fabs(r->t), fabs(r->t_stop)))) return failure;
        for (j = 0; j < n; ++j) r->scale[j] = r->atol + r->rtol * fabs(r->y[j]);
        if (r->jacobian == JACOBIAN_NONE) {
            inputs_at_time(r, r->t);
            if (newton_jacobian(r->s, r->y, r->fy)) return CV_LSETUP_FAIL;
            r->s->jacobians++;
            r->jacobian = JACOBIAN_FRESH;
            r->h_factored = 0.0;
        }
        if (h != r->h_factored && factor_pair(r, h)) {
            r->counters[4]++, failure = CV_LSETUP_FAIL; /* singular: a shorter step */
            r->h = 0.5 * h, r->rejected = 1;
            continue;
        }
        radau_predict(r, r->y_last, r->q, r->y, r->predict ? r->h_last : 0.0, h, r->z);
        flag = newton(r, h, &iterations, &theta);
        if (flag < 0) return CV_RHSFUNC_FAIL;
        if (flag > 0) {
            r->counters[4]++, failure = CV_CONV_FAILURE;
            r->rejected = 1;
            if (r->jacobian == JACOBIAN_KEPT)
                r->jacobian = JACOBIAN_NONE; /* a fresh Jacobian, the same step size */
            else
                r->h = 0.5 * h;
            continue;
        }
        error = error_norm(r, h, r->first || r->rejected);
        factor = SAFETY * (2 * NEWTON_ITERATIONS + 1) / (2 * NEWTON_ITERATIONS + iterations) *
                 pow(error, -0.25);
        for (j = 0; j < n && error <= 1.0; ++j) y_new[j] = r->y[j] + r->z[2 * n + j];
        flag = error <= 1.0 ? rhs_at(r, clipped ? r->t_stop : r->t + h, y_new, f_new) : 0;
        if (flag < 0) return CV_RHSFUNC_FAIL;
        if (error > 1.0 || flag > 0) { /* rejected, or the new state's derivative not finite */
            r->counters[3]++, failure = CV_ERR_FAILURE;
            r->rejected = 1;
            r->h = flag > 0 ? 0.5 * h : h * fmax(FACTOR_MIN, factor);
            continue;
        }
        /* accepted: the dense output's coefficients, the new state and its derivative */
        radau_mix(r->k + RADAU_P, r->z, n, r->q);
        memcpy(r->y_last, r->y, sizeof(double) * n);
        memcpy(r->y, y_new, sizeof(double) * n);
        memcpy(r->fy, f_new, sizeof(double) * n);
        if (r->h_last > 0.0 && r->error_last > 0.0) /* Gustafsson's predictive controller */
            factor *= fmin(1.0, h / r->h_last * pow(r->error_last / error, 0.25));
        r->t_last = r->t, r->h_last = h, r->error_last = error;
        r->t = clipped ? r->t_stop : r->t + h;
        r->counters[0]++;
        factor = fmin(FACTOR_MAX, fmax(FACTOR_MIN, factor));
        if (r->rejected) factor = fmin(factor, 1.0);
        h_new = factor >= 1.0 && factor <= KEEP_STEP ? h : h * factor;
        if (clipped && factor >= 1.0) h_new = fmax(h_new, r->h); /* as wanted before the stop */
        r->h = h_new;
        r->jacobian = iterations > 2 && theta > KEEP_JACOBIAN ? JACOBIAN_NONE : JACOBIAN_KEPT;
        r->predict = 1, r->rejected = 0, r->first = 0;
        *tret = r->t;
        return 0;
    }
}
