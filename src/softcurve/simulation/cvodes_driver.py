"""The C source of softcurve's CVODES driver, compiled by :mod:`softcurve.simulation.native`.

Kept as a Python string so that it ships with the package like any module.
"""

DRIVER_SOURCE = r"""
/* softcurve's driver of SUNDIALS CVODES: integrate members of a batch (or one run) on
 * a CasADi-generated right-hand side f(x, u, p) -> xdot, all in C.
 *
 * CVODES is the copy inside CasADi (SUNDIALS 2.x interface, libcasadi_integrator_cvodes),
 * declared here because CasADi ships no headers for it. The Newton systems are solved by
 * CVSPGMR preconditioned with the exact LU factors of the Newton matrix I - gamma J, whose
 * Jacobian J comes from forward differences of f; with the same J in the Jacobian-vector
 * product, GMRES converges in one iteration, so this is a direct dense solve. CVODES says
 * when J may be reused (jok): only then is it recomputed.
 *
 * The state is integrated scaled, xs = x / nominal, with one absolute tolerance.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef double realtype;
typedef struct _generic_N_Vector *N_Vector;
typedef int (*CVRhsFn)(realtype t, N_Vector y, N_Vector ydot, void *data);
typedef int (*CVPrecSetupFn)(realtype t, N_Vector y, N_Vector fy, int jok, int *jcur,
                             realtype gamma, void *data, N_Vector t1, N_Vector t2, N_Vector t3);
typedef int (*CVPrecSolveFn)(realtype t, N_Vector y, N_Vector fy, N_Vector r, N_Vector z,
                             realtype gamma, realtype delta, int lr, void *data, N_Vector tmp);
typedef int (*CVJacTimesFn)(N_Vector v, N_Vector Jv, realtype t, N_Vector y, N_Vector fy,
                            void *data, N_Vector tmp);
typedef void (*CVErrHandlerFn)(int code, const char *module, const char *function, char *msg,
                               void *data);

extern N_Vector N_VNew_Serial(long int length);
extern realtype *N_VGetArrayPointer(N_Vector v);
extern void N_VDestroy(N_Vector v);
extern void *CVodeCreate(int lmm, int iter);
extern int CVodeInit(void *mem, CVRhsFn f, realtype t0, N_Vector y0);
extern int CVodeReInit(void *mem, realtype t0, N_Vector y0);
extern int CVodeSStolerances(void *mem, realtype rtol, realtype atol);
extern int CVodeSetUserData(void *mem, void *data);
extern int CVodeSetMaxNumSteps(void *mem, long int mxsteps);
extern int CVodeSetMaxOrd(void *mem, int maxord);
extern int CVodeSetStopTime(void *mem, realtype tstop);
extern int CVodeGetDky(void *mem, realtype t, int k, N_Vector dky);
extern int CVodeSetErrHandlerFn(void *mem, CVErrHandlerFn f, void *data);
extern int CVode(void *mem, realtype tout, N_Vector yout, realtype *tret, int itask);
extern int CVodeGetNumSteps(void *mem, long int *n);
extern int CVodeGetNumRhsEvals(void *mem, long int *n);
extern int CVodeGetNumLinSolvSetups(void *mem, long int *n);
extern int CVodeGetNumErrTestFails(void *mem, long int *n);
extern int CVodeGetNumNonlinSolvConvFails(void *mem, long int *n);
extern void CVodeFree(void **mem);
extern int CVSpgmr(void *mem, int pretype, int maxl);
extern int CVSpilsSetPreconditioner(void *mem, CVPrecSetupFn setup, CVPrecSolveFn solve);
extern int CVSpilsSetJacTimesVecFn(void *mem, CVJacTimesFn jtimes);

#define CV_ADAMS 1
#define CV_BDF 2
#define CV_NEWTON 2
#define CV_NORMAL 1
#define CV_ONE_STEP 2
#define CV_TOO_MUCH_WORK -1
#define PREC_LEFT 1
#define GMRES_DIMENSION 2 /* one iteration converges (exact preconditioner); one spare */
#define STATS 6

typedef int (*casadi_fn)(const double **arg, double **res, long long *iw, double *w, int mem);

/* What the Python side passes: the model's generated right-hand side f(x, tau, p) (nx
 * states, nu forces, np parameters) with its work sizes (the largest over f and force), and
 * optionally an actuator's force(q, v) -> tau = H(q) v with m inputs: the member's input is
 * then v (m) or, with lag, the command of v, whose m states follow x with the rate
 * (clip(command, lower, upper) - v) / time_constant. */
typedef struct {
    casadi_fn f, force;
    int nx, nu, np, m, lag;
    long long sz_arg, sz_res, sz_iw, sz_w;
    const double *lower, *upper;
    double time_constant;
} sc_function;

typedef struct {
    const sc_function *fn;
    const double *u, *p, *nominal;
    const double **arg;
    double **res;
    long long *iw;
    double *w, *x, *xdot, *tau, *J, *LU, *ftmp;
    int n; /* states integrated: nx, plus m lagging inputs */
    int *piv;
    long jacobians;
} sc_work;

/* Work arrays of f for n states (x, xdot, tau, ftmp, J and LU in one block after f's own
 * work); 0, or 1 when out of memory (work_close frees what was allocated). */
static int work_open(sc_work *s, const sc_function *fn, int n) {
    memset(s, 0, sizeof(*s));
    s->fn = fn;
    s->n = n;
    s->arg = (const double **)calloc(fn->sz_arg > 3 ? fn->sz_arg : 3, sizeof(double *));
    s->res = (double **)calloc(fn->sz_res > 1 ? fn->sz_res : 1, sizeof(double *));
    s->iw = (long long *)calloc(fn->sz_iw + 1, sizeof(long long));
    s->w = (double *)calloc(fn->sz_w + 1 + 4 * n + fn->nx + 2 * n * n, sizeof(double));
    s->piv = (int *)calloc(n, sizeof(int));
    if (!s->arg || !s->res || !s->iw || !s->w || !s->piv) return 1;
    s->x = s->w + fn->sz_w + 1;
    s->xdot = s->x + n;
    s->tau = s->xdot + n;
    s->ftmp = s->tau + fn->nx;
    s->J = s->ftmp + n;
    s->LU = s->J + n * n;
    return 0;
}

static void work_close(sc_work *s) {
    free(s->arg);
    free(s->res);
    free(s->iw);
    free(s->w);
    free(s->piv);
}

/* CVODES's counters since its last (re)start: steps, right-hand sides, linear-solver
 * setups, error-test failures, Newton failures. */
static void read_counters(void *mem, long counters[5]) {
    CVodeGetNumSteps(mem, &counters[0]);
    CVodeGetNumRhsEvals(mem, &counters[1]);
    CVodeGetNumLinSolvSetups(mem, &counters[2]);
    CVodeGetNumErrTestFails(mem, &counters[3]);
    CVodeGetNumNonlinSolvConvFails(mem, &counters[4]);
}

static void quiet(int code, const char *module, const char *function, char *msg, void *data) {
    (void)code; (void)module; (void)function; (void)msg; (void)data;
}

/* ydot = f(nominal * y, u, p) / nominal; 1 (recoverable) on a non-finite value */
static int evaluate(sc_work *s, const double *y, double *ydot) {
    const sc_function *fn = s->fn;
    int i, n = s->n;
    for (i = 0; i < n; ++i) s->x[i] = s->nominal[i] * y[i];
    s->arg[1] = s->u;
    if (fn->force != NULL) {
        s->arg[0] = s->x;
        s->arg[1] = fn->lag ? s->x + fn->nx : s->u;
        s->res[0] = s->tau;
        if (fn->force(s->arg, s->res, s->iw, s->w, 0)) return -1;
        s->arg[1] = s->tau;
    }
    s->arg[0] = s->x;
    s->arg[2] = s->p;
    s->res[0] = s->xdot;
    if (fn->f(s->arg, s->res, s->iw, s->w, 0)) return -1;
    for (i = 0; fn->lag && i < fn->m; ++i) {
        double command = s->u[i] < fn->lower[i] ? fn->lower[i] : s->u[i];
        command = command > fn->upper[i] ? fn->upper[i] : command;
        s->xdot[fn->nx + i] = (command - s->x[fn->nx + i]) / fn->time_constant;
    }
    for (i = 0; i < n; ++i) ydot[i] = s->xdot[i] / s->nominal[i];
    for (i = 0; i < n; ++i)
        if (!isfinite(ydot[i])) return 1;
    return 0;
}

static int rhs(realtype t, N_Vector y, N_Vector ydot, void *data) {
    (void)t;
    return evaluate((sc_work *)data, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
}

/* Forward-difference Jacobian (column-major) when CVODES asks for a fresh one, then the LU
 * factors (partial pivoting) of I - gamma J. (Offering the previous segment's J after a
 * restart instead saved 9 of the paper case's 24 Jacobians but doubled the steps of the
 * actuated case with lag, 2,461 -> 5,555: CVODES takes the Jacobian of a first step for
 * current and keeps it for up to 50 steps.) */
static int setup(realtype t, N_Vector yv, N_Vector fyv, int jok, int *jcur, realtype gamma,
                 void *data, N_Vector t1, N_Vector t2, N_Vector t3) {
    sc_work *s = (sc_work *)data;
    int n = s->n, i, j, k, flag;
    double *y = N_VGetArrayPointer(yv), *fy = N_VGetArrayPointer(fyv), *A = s->LU;
    (void)t; (void)t1; (void)t2; (void)t3;
    if (!jok) {
        for (j = 0; j < n; ++j) {
            double saved = y[j];
            double step = 1.4901161193847656e-08 * (fabs(saved) > 1.0 ? fabs(saved) : 1.0);
            y[j] = saved + step;
            flag = evaluate(s, y, s->ftmp);
            y[j] = saved;
            if (flag) return flag;
            for (i = 0; i < n; ++i) s->J[i + j * n] = (s->ftmp[i] - fy[i]) / step;
        }
        s->jacobians++;
        *jcur = 1;
    } else {
        *jcur = 0;
    }
    for (k = 0; k < n * n; ++k) A[k] = -gamma * s->J[k];
    for (i = 0; i < n; ++i) A[i + i * n] += 1.0;
    for (k = 0; k < n; ++k) {
        int p = k;
        double big = fabs(A[k + k * n]);
        for (i = k + 1; i < n; ++i)
            if (fabs(A[i + k * n]) > big) big = fabs(A[i + k * n]), p = i;
        if (big == 0.0) return 1;
        s->piv[k] = p;
        if (p != k)
            for (j = 0; j < n; ++j) {
                double a = A[k + j * n];
                A[k + j * n] = A[p + j * n];
                A[p + j * n] = a;
            }
        for (i = k + 1; i < n; ++i) A[i + k * n] /= A[k + k * n];
        for (j = k + 1; j < n; ++j)
            for (i = k + 1; i < n; ++i) A[i + j * n] -= A[i + k * n] * A[k + j * n];
    }
    return 0;
}

static int solve(realtype t, N_Vector yv, N_Vector fyv, N_Vector rv, N_Vector zv, realtype gamma,
                 realtype delta, int lr, void *data, N_Vector tmp) {
    sc_work *s = (sc_work *)data;
    int n = s->n, i, k;
    double *r = N_VGetArrayPointer(rv), *z = N_VGetArrayPointer(zv), *A = s->LU;
    (void)t; (void)yv; (void)fyv; (void)gamma; (void)delta; (void)lr; (void)tmp;
    if (z != r) memcpy(z, r, n * sizeof(double));
    for (k = 0; k < n; ++k) /* the row swaps of the factorization, then L, then U */
        if (s->piv[k] != k) {
            double a = z[k];
            z[k] = z[s->piv[k]];
            z[s->piv[k]] = a;
        }
    for (k = 0; k < n; ++k)
        for (i = k + 1; i < n; ++i) z[i] -= A[i + k * n] * z[k];
    for (k = n - 1; k >= 0; --k) {
        z[k] /= A[k + k * n];
        for (i = 0; i < k; ++i) z[i] -= A[i + k * n] * z[k];
    }
    return 0;
}

static int jtimes(N_Vector vv, N_Vector Jvv, realtype t, N_Vector y, N_Vector fy, void *data,
                  N_Vector tmp) {
    sc_work *s = (sc_work *)data;
    int n = s->n, i, j;
    double *v = N_VGetArrayPointer(vv), *Jv = N_VGetArrayPointer(Jvv);
    (void)t; (void)y; (void)fy; (void)tmp;
    for (i = 0; i < n; ++i) Jv[i] = 0.0;
    for (j = 0; j < n; ++j)
        for (i = 0; i < n; ++i) Jv[i] += s->J[i + j * n] * v[j];
    return 0;
}

/* CVODES with Newton's method on the Newton matrix of the callbacks above, for x' = f
 * (f's data starts with the sc_work those callbacks read); max_order 0: CVODES's own. */
static void *create(int lmm, double t0, N_Vector y, CVRhsFn f, void *data, double rtol,
                    double atol, long max_steps, int max_order) {
    void *mem = CVodeCreate(lmm, CV_NEWTON);
    if (mem == NULL) return NULL;
    if (CVodeInit(mem, f, t0, y) || CVodeSStolerances(mem, rtol, atol) ||
        CVodeSetUserData(mem, data) || CVodeSetMaxNumSteps(mem, max_steps) ||
        CVodeSetErrHandlerFn(mem, quiet, NULL) || CVSpgmr(mem, PREC_LEFT, GMRES_DIMENSION) ||
        CVSpilsSetPreconditioner(mem, setup, solve) || CVSpilsSetJacTimesVecFn(mem, jtimes) ||
        (max_order > 0 && CVodeSetMaxOrd(mem, lmm == CV_BDF && max_order > 5 ? 5 : max_order))) {
        CVodeFree(&mem);
        return NULL;
    }
    return mem;
}

/* Whether the configuration q (n_seg segments of (l, kx, ky)) lies outside the model's
 * domain: l in (0, longest], bending angle l |kappa| <= max_bend, finite (the rule of
 * softcurve.description.robot.in_domain, which words the message). */
static int outside(const double *x, int width, const double *longest, int n_seg,
                   double max_bend) {
    int i;
    for (i = 0; i < width; ++i)
        if (!isfinite(x[i])) return 1;
    /* Squared, not hypot, at every output (hypot was a fifth of an output's cost); within
     * rounding of the bound, Python's own test (l hypot(kx, ky) <= max_bend), so that
     * both always agree. A square that overflows is outside, as it should be. */
    for (i = 0; longest != NULL && i < n_seg; ++i) {
        double l = x[3 * i], kx = x[3 * i + 1], ky = x[3 * i + 2];
        double bend2 = l * l * (kx * kx + ky * ky), bound2 = max_bend * max_bend;
        int inside = fabs(bend2 - bound2) > 1e-12 * bound2 ? bend2 < bound2
                                                           : l * hypot(kx, ky) <= max_bend;
        if (!(l > 0.0 && l <= longest[i] && inside)) return 1;
    }
    return 0;
}

/* Integrate `count` members over the grid `times[0..k)` from out[b, 0, :] (physical, at
 * times[0]), in segments ending at the output indices ends[0..n_ends) (the last is k - 1),
 * each a fresh start of CVODES with the member's input of that segment u[b, s, :]. Member b
 * starts with family lmm[b] (1 Adams, 2 BDF); where restart[s] and fastest[b] > 0, segment s
 * is integrated with BDF if the member has settled (max |xdot / nominal| * settled_ratio <
 * fastest[b]) and with lmm[b] otherwise. A member stops at its first output outside the
 * domain (longest[b, :] per segment, NULL: no check) or at a failure of CVODES. Writes
 * out[b, i, :], reached[b] (outputs filled, the one outside the domain included), flag[b]
 * (0, 1 outside the domain, CVODES's negative flag, -100 when it could not be set up),
 * used_bdf[b], and adds to stats[b, :]: steps, right-hand sides, Jacobians, linear-solver
 * setups, error-test failures, Newton failures. */
__attribute__((visibility("default"))) int softcurve_cvodes(
    const sc_function *fn, int count, const int *lmm, const double *fastest,
    double settled_ratio, const double *u, const double *p, const double *nominal,
    const double *longest, int n_seg, double max_bend, const double *times, int k,
    const int *ends, const int *restart, int n_ends, double rtol, double atol, long max_steps,
    int max_order, double *out, int *reached, int *flag, int *used_bdf, long *stats) {
    int n = fn->nx + (fn->lag ? fn->m : 0), inputs = fn->force ? fn->m : fn->nu, b, i, j, e;
    sc_work s;
    void *mem[3] = {NULL, NULL, NULL};
    N_Vector y = N_VNew_Serial(n), dky = N_VNew_Serial(n);
    double *out_y = dky ? N_VGetArrayPointer(dky) : NULL;
    if (work_open(&s, fn, n) || y == NULL || dky == NULL) {
        for (b = 0; b < count; ++b) flag[b] = -100, reached[b] = 1;
        goto done;
    }
    for (b = 0; b < count; ++b) {
        int family = lmm[b] == CV_BDF ? CV_BDF : CV_ADAMS, first = 0;
        double *ys = N_VGetArrayPointer(y), *row = out + (long)b * k * n, tret;
        s.p = p + (long)b * fn->np;
        s.nominal = nominal + (long)b * n;
        flag[b] = 0;
        used_bdf[b] = family == CV_BDF;
        reached[b] = 1;
        for (e = 0; e < n_ends && flag[b] == 0; first = ends[e], ++e) {
            long counters[5] = {0, 0, 0, 0, 0};
            s.u = u + ((long)b * n_ends + e) * inputs;
            for (j = 0; j < n; ++j) ys[j] = row[(long)first * n + j] / s.nominal[j];
            if (e > 0 && restart[e] && fastest[b] > 0.0) {
                double fastest_state = 0.0;
                if (evaluate(&s, ys, s.ftmp) == 0)
                    for (j = 0; j < n; ++j)
                        if (fabs(s.ftmp[j]) > fastest_state) fastest_state = fabs(s.ftmp[j]);
                family = fastest_state * settled_ratio < fastest[b] ? CV_BDF : lmm[b];
                used_bdf[b] |= family == CV_BDF;
            }
            s.jacobians = 0;
            if (mem[family] == NULL)
                mem[family] = create(family, times[first], y, rhs, &s, rtol, atol, max_steps,
                                     max_order);
            else if (CVodeReInit(mem[family], times[first], y))
                flag[b] = -100;
            if (mem[family] == NULL) flag[b] = -100;
            if (flag[b]) break;
            CVodeSetStopTime(mem[family], times[ends[e]]);
            tret = times[first];
            for (i = first + 1; i <= ends[e]; ++i) {
                /* One internal step at a time, and every output it passed interpolated:
                 * CVODES's normal mode costs a call per output, a third of the cost of an
                 * output on a 1 ms grid. The step budget is per output, as in that mode,
                 * and tout the next output: CVODES sizes a restart's first step by it. */
                long taken = 0;
                while (tret < times[i] && flag[b] == 0) {
                    int status = ++taken > max_steps
                                     ? CV_TOO_MUCH_WORK
                                     : CVode(mem[family], times[i], y, &tret, CV_ONE_STEP);
                    if (status < 0) flag[b] = status;
                }
                if (flag[b] == 0 && CVodeGetDky(mem[family], times[i], 0, dky)) flag[b] = -100;
                if (flag[b]) break;
                for (j = 0; j < n; ++j) row[(long)i * n + j] = out_y[j] * s.nominal[j];
                reached[b] = i + 1;
                if (outside(row + (long)i * n, n, longest ? longest + (long)b * n_seg : NULL,
                            n_seg, max_bend)) {
                    flag[b] = 1;
                    break;
                }
            }
            read_counters(mem[family], counters);
            stats[b * STATS + 0] += counters[0];
            stats[b * STATS + 1] += counters[1];
            stats[b * STATS + 2] += s.jacobians;
            stats[b * STATS + 3] += counters[2];
            stats[b * STATS + 4] += counters[3];
            stats[b * STATS + 5] += counters[4];
        }
    }
done:
    for (i = 1; i < 3; ++i)
        if (mem[i] != NULL) CVodeFree(&mem[i]);
    if (y != NULL) N_VDestroy(y);
    if (dky != NULL) N_VDestroy(dky);
    work_close(&s);
    return 0;
}
"""
