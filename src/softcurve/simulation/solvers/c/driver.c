/* softcurve's driver of SUNDIALS CVODES: integrate members of a batch (or one run) on
 * a CasADi-generated right-hand side f(x, u, p) -> xdot, all in C; here the work of one
 * member, its Newton matrices (CVODES's and, through newton_lu.h, Radau IIA's of
 * radau.c) and the domain test.
 *
 * CVODES is the copy inside CasADi (sundials2.h). The Newton systems are solved by
 * CVSPGMR preconditioned with the exact LU factors of the Newton matrix I - gamma J, whose
 * Jacobian J is the model's exact one where the problem has it (an actuator's force then
 * by its own exact derivatives, or by forward differences where they are not given) or
 * else forward differences of f; with the
 * same J in the Jacobian-vector product, GMRES converges in one iteration, so this is a
 * direct dense solve. CVODES says when J may be reused (jok): only then is it recomputed.
 *
 * The state is integrated scaled, xs = x / nominal, with one absolute tolerance.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "driver_internal.h"

/* The arrays for a function of work sizes sz_arg, sz_res, sz_iw, sz_w (at least the
 * three arguments and one result every function here takes), with `extra` doubles after
 * w's own, from w + sz_w + 1; 0, or 1 when out of memory (arrays_close frees what was
 * allocated). */
int arrays_open(sc_arrays *c, long long sz_arg, long long sz_res, long long sz_iw,
                     long long sz_w, long extra) {
    c->arg = (const double **)calloc(sz_arg > 3 ? sz_arg : 3, sizeof(double *));
    c->res = (double **)calloc(sz_res > 1 ? sz_res : 1, sizeof(double *));
    c->iw = (long long *)calloc(sz_iw + 1, sizeof(long long));
    c->w = (double *)calloc(sz_w + 1 + extra, sizeof(double));
    return !c->arg || !c->res || !c->iw || !c->w;
}

void arrays_close(sc_arrays *c) {
    free(c->arg);
    free(c->res);
    free(c->iw);
    free(c->w);
}

/* Work arrays of f for n states (x, xdot, tau, ftmp, J and LU in one block after f's own
 * work); 0, or 1 when out of memory (work_close frees what was allocated). */
int work_open(sc_work *s, const sc_function *fn, int n) {
    long exact = fn->jacobian == NULL ? 0 : fn->nx * fn->nx + fn->nu * fn->nu + fn->nu;
    if (fn->jacobian != NULL && fn->force_jacobian != NULL) exact += fn->nu * (fn->nu + fn->m);
    memset(s, 0, sizeof(*s));
    s->fn = fn;
    s->n = n;
    s->piv = (int *)calloc(n, sizeof(int));
    if (arrays_open(&s->c, fn->sz_arg, fn->sz_res, fn->sz_iw, fn->sz_w,
                  4 * n + fn->nx + 2 * n * n + exact) || !s->piv)
        return 1;
    s->x = s->c.w + fn->sz_w + 1;
    s->xdot = s->x + n;
    s->tau = s->xdot + n;
    s->ftmp = s->tau + fn->nx;
    s->J = s->ftmp + n;
    s->LU = s->J + n * n;
    if (fn->jacobian != NULL) {
        s->Jx = s->LU + n * n;
        s->mass = s->Jx + fn->nx * fn->nx;
        s->dtau = s->mass + fn->nu * fn->nu;
        s->dforce = fn->force_jacobian == NULL ? NULL : s->dtau + fn->nu;
    }
    return 0;
}

void work_close(sc_work *s) {
    arrays_close(&s->c);
    free(s->piv);
}

/* CVODES's counters since its last (re)start: steps, right-hand sides, linear-solver
 * setups, error-test failures, Newton failures. */
void read_counters(void *mem, long counters[5]) {
    CVodeGetNumSteps(mem, &counters[0]);
    CVodeGetNumRhsEvals(mem, &counters[1]);
    CVodeGetNumLinSolvSetups(mem, &counters[2]);
    CVodeGetNumErrTestFails(mem, &counters[3]);
    CVodeGetNumNonlinSolvConvFails(mem, &counters[4]);
}

/* driver_internal.h */
void add_counters(const long counters[5], long *stats, int newton_failures) {
    stats[0] += counters[0];
    stats[1] += counters[1];
    stats[3] += counters[2];
    stats[4] += counters[3];
    if (newton_failures) stats[5] += counters[4];
}

/* driver_internal.h */
int states_of(const sc_function *fn) { return fn->nx + (fn->lag ? fn->m : 0); }
int inputs_of(const sc_function *fn) { return fn->force ? fn->m : fn->nu; }

/* The force's arguments at the state s->x: q, and the lagging inputs or the member's. */
static void force_arguments(sc_work *s) {
    s->c.arg[0] = s->x;
    s->c.arg[1] = s->fn->lag ? s->x + s->fn->nx : s->u;
}

static void quiet(int code, const char *module, const char *function, char *msg, void *data) {
    (void)code; (void)module; (void)function; (void)msg; (void)data;
}

/* The generalized force at the state s->x: the actuator's H(q) v into `tau` (returned), or
 * the member's forces; NULL where the force function fails. */
static const double *input_force(sc_work *s, double *tau) {
    const sc_function *fn = s->fn;
    if (fn->force == NULL) return s->u;
    force_arguments(s);
    s->c.res[0] = tau;
    return fn->force(s->c.arg, s->c.res, s->c.iw, s->c.w, 0) ? NULL : tau;
}

/* ydot = f(nominal * y, u, p) / nominal; 1 (recoverable) on a non-finite value */
int evaluate(sc_work *s, const double *y, double *ydot) {
    const sc_function *fn = s->fn;
    int i, n = s->n;
    for (i = 0; i < n; ++i) s->x[i] = s->nominal[i] * y[i];
    s->c.arg[1] = input_force(s, s->tau);
    if (s->c.arg[1] == NULL) return -1;
    s->c.arg[0] = s->x;
    s->c.arg[2] = s->p;
    s->c.res[0] = s->xdot;
    if (fn->f(s->c.arg, s->c.res, s->c.iw, s->c.w, 0)) return -1;
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

int rhs(realtype t, N_Vector y, N_Vector ydot, void *data) {
    (void)t;
    return evaluate((sc_work *)data, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
}

/* Forward-difference step of a state entry's value v: the square root of the machine
 * epsilon, relative where |v| > 1. */
double difference_step(double v) {
    return 1.4901161193847656e-08 * (fabs(v) > 1.0 ? fabs(v) : 1.0);
}

/* LAPACK's dgetf2 and dgetrs, and zgetf2 and zgetrs for the complex ones (SciPy's,
 * softcurve_use_lapack), for the Newton matrices of lapack_from states and more; NULL:
 * the loops of newton_lu.h for all. dgetf2, the unblocked LU,
 * because SciPy's OpenBLAS runs its blocked dgetrf (and dgemv) on threads of its own
 * at these sizes, which made a batch on two threads of the driver slower than on the
 * loops. Set once, when the library is loaded, before any integration. */
typedef void (*getf2_fn)(int *m, int *n, double *a, int *lda, int *ipiv, int *info);
typedef void (*getrs_fn)(char *trans, int *n, int *nrhs, double *a, int *lda, int *ipiv,
                         double *b, int *ldb, int *info);
typedef void (*zgetf2_fn)(int *m, int *n, double complex *a, int *lda, int *ipiv, int *info);
typedef void (*zgetrs_fn)(char *trans, int *n, int *nrhs, double complex *a, int *lda,
                          int *ipiv, double complex *b, int *ldb, int *info);
static getf2_fn lapack_getf2;
static getrs_fn lapack_getrs;
static zgetf2_fn lapack_zgetf2;
static zgetrs_fn lapack_zgetrs;
static int lapack_from;

/* softcurve_driver.h */
SC_EXPORT void softcurve_use_lapack(void *getf2, void *getrs, void *zgetf2, void *zgetrs,
                                    int from) {
    lapack_getf2 = (getf2_fn)getf2;
    lapack_getrs = (getrs_fn)getrs;
    lapack_zgetf2 = (zgetf2_fn)zgetf2;
    lapack_zgetrs = (zgetrs_fn)zgetrs;
    lapack_from = from;
}

static int by_lapack(int n) { return lapack_getf2 != NULL && n >= lapack_from; }

/* driver_internal.h: factor_newton, solve_newton, and for Radau IIA's complex Newton
 * matrix factor_complex, solve_complex */
#define LU_SCALAR double
#define LU_ABS fabs
#define LU_GETF2 lapack_getf2
#define LU_GETRS lapack_getrs
#define LU_FACTOR factor_newton
#define LU_SOLVE solve_newton
#include "newton_lu.h"
#define LU_SCALAR double complex
#define LU_ABS cabs
#define LU_GETF2 lapack_zgetf2
#define LU_GETRS lapack_zgetrs
#define LU_FACTOR factor_complex
#define LU_SOLVE solve_complex
#include "newton_lu.h"

/* Jv = J v (n x n, column-major). */
void times_jacobian(const double *J, const double *v, int n, double *Jv) {
    int i, j;
    for (i = 0; i < n; ++i) Jv[i] = 0.0;
    for (j = 0; j < n; ++j)
        for (i = 0; i < n; ++i) Jv[i] += J[i + j * n] * v[j];
}

/* a = L L^T in place (lower triangle, column-major k x k) for a symmetric positive
 * definite a; 1 where it is not. */
static int cholesky(double *a, int k) {
    int i, j, m;
    for (j = 0; j < k; ++j) {
        double d = a[j + j * k];
        for (m = 0; m < j; ++m) d -= a[j + m * k] * a[j + m * k];
        if (!(d > 0.0)) return 1;
        d = sqrt(d);
        a[j + j * k] = d;
        for (i = j + 1; i < k; ++i) {
            double v = a[i + j * k];
            for (m = 0; m < j; ++m) v -= a[i + m * k] * a[j + m * k];
            a[i + j * k] = v / d;
        }
    }
    return 0;
}

/* b = (L L^T)^-1 b for one column b of k entries, L from cholesky(). */
static void cholesky_solve(const double *l, int k, double *b) {
    int i, m;
    for (i = 0; i < k; ++i) {
        for (m = 0; m < i; ++m) b[i] -= l[i + m * k] * b[m];
        b[i] /= l[i + i * k];
    }
    for (i = k - 1; i >= 0; --i) {
        for (m = i + 1; m < k; ++m) b[i] -= l[m + i * k] * b[m];
        b[i] /= l[i + i * k];
    }
}

/* The force's derivative along state j (q's first nu, or a lagging input from nx) into
 * s->dtau: exact from s->dforce (force_jacobian just evaluated), else by a forward
 * difference of the scaled state from tau; 0, or -1 where the force fails. */
static int force_column(sc_work *s, const double *y, const double *tau, int j) {
    const sc_function *fn = s->fn;
    int nu = fn->nu, i;
    double saved, step;
    if (s->dforce != NULL) {
        const double *column = j < nu ? s->dforce + j * nu : s->dforce + nu * (nu + j - fn->nx);
        memcpy(s->dtau, column, nu * sizeof(double));
        return 0;
    }
    saved = s->x[j], step = s->nominal[j] * difference_step(y[j]);
    s->x[j] = saved + step;
    if (input_force(s, s->dtau) == NULL) return -1;
    s->x[j] = saved;
    for (i = 0; i < nu; ++i) s->dtau[i] = (s->dtau[i] - tau[i]) / step;
    return 0;
}

/* J (column-major, the integrated scaled state's, n x n) from the model's exact Jacobian
 * at y: J_x at (x, tau); with an actuator, the accelerations' rows gain D^-1 dtau/dx (the
 * force H(q) v differentiated along q and the lagging inputs, the only states it reads:
 * by force_jacobian, or by forward differences of the scaled state) and the lagging
 * inputs' rows their rate's -1 / time_constant. 0, or the failing call's nonzero. */
static int exact_jacobian(sc_work *s, double *y, double *J) {
    const sc_function *fn = s->fn;
    int n = s->n, nx = fn->nx, nu = fn->nu, i, j;
    const double *tau;
    for (i = 0; i < n; ++i) s->x[i] = s->nominal[i] * y[i];
    tau = input_force(s, s->tau);
    if (tau == NULL) return -1;
    s->c.arg[0] = s->x;
    s->c.arg[1] = tau;
    s->c.arg[2] = s->p;
    s->c.res[0] = s->Jx;
    s->c.res[1] = s->mass;
    if (fn->jacobian(s->c.arg, s->c.res, s->c.iw, s->c.w, 0)) return -1;
    memset(J, 0, (size_t)n * n * sizeof(double));
    for (j = 0; j < nx; ++j)
        for (i = 0; i < nx; ++i) J[i + j * n] = s->Jx[i + j * nx];
    if (fn->force != NULL) {
        if (cholesky(s->mass, nu)) return 1;
        if (s->dforce != NULL) {
            force_arguments(s);
            s->c.res[0] = s->dforce;
            s->c.res[1] = s->dforce + nu * nu;
            if (fn->force_jacobian(s->c.arg, s->c.res, s->c.iw, s->c.w, 0)) return -1;
        }
        for (j = 0; j < n; ++j) {
            if (j >= nu && j < nx) continue;
            if (force_column(s, y, tau, j)) return -1;
            cholesky_solve(s->mass, nu, s->dtau);
            for (i = 0; i < nu; ++i) J[nu + i + j * n] += s->dtau[i];
        }
        for (i = nx; fn->lag && i < n; ++i) J[i + i * n] = -1.0 / fn->time_constant;
    }
    for (j = 0; j < n; ++j)
        for (i = 0; i < n; ++i) J[i + j * n] *= s->nominal[j] / s->nominal[i];
    return 0;
}

/* driver_internal.h; the exact Jacobian is formed in the factors' array and copied only
 * whole, so that a failure never leaves s->J half new */
int newton_jacobian(sc_work *s, double *y, const double *fy) {
    int n = s->n, i, j, flag;
    if (s->fn->jacobian != NULL) {
        flag = exact_jacobian(s, y, s->LU);
        if (flag == 0) memcpy(s->J, s->LU, (size_t)n * n * sizeof(double));
        return flag;
    }
    for (j = 0; j < n; ++j) {
        double saved = y[j], step = difference_step(saved);
        y[j] = saved + step;
        flag = evaluate(s, y, s->ftmp);
        y[j] = saved;
        if (flag) return flag;
        for (i = 0; i < n; ++i) s->J[i + j * n] = (s->ftmp[i] - fy[i]) / step;
    }
    return 0;
}

/* A fresh Jacobian (newton_jacobian) when CVODES asks for one, then the LU factors of
 * I - gamma J. (Offering the previous segment's J after a restart instead saved
 * 9 of the paper case's 24 Jacobians but doubled the steps of the actuated case with lag,
 * 2,461 -> 5,555: CVODES takes the Jacobian of a first step for current and keeps it for
 * up to 50 steps.) */
static int setup(realtype t, N_Vector yv, N_Vector fyv, int jok, int *jcur, realtype gamma,
                 void *data, N_Vector t1, N_Vector t2, N_Vector t3) {
    sc_work *s = (sc_work *)data;
    int flag;
    (void)t; (void)t1; (void)t2; (void)t3;
    if (!jok) {
        flag = newton_jacobian(s, N_VGetArrayPointer(yv), N_VGetArrayPointer(fyv));
        if (flag) return flag;
        s->jacobians++;
        *jcur = 1;
    } else {
        *jcur = 0;
    }
    return factor_newton(s->J, gamma, s->n, s->LU, s->piv);
}

static int solve(realtype t, N_Vector yv, N_Vector fyv, N_Vector rv, N_Vector zv, realtype gamma,
                 realtype delta, int lr, void *data, N_Vector tmp) {
    sc_work *s = (sc_work *)data;
    double *r = N_VGetArrayPointer(rv), *z = N_VGetArrayPointer(zv);
    (void)t; (void)yv; (void)fyv; (void)gamma; (void)delta; (void)lr; (void)tmp;
    if (z != r) memcpy(z, r, s->n * sizeof(double));
    solve_newton(s->LU, s->piv, s->n, z);
    return 0;
}

static int jtimes(N_Vector vv, N_Vector Jvv, realtype t, N_Vector y, N_Vector fy, void *data,
                  N_Vector tmp) {
    sc_work *s = (sc_work *)data;
    (void)t; (void)y; (void)fy; (void)tmp;
    times_jacobian(s->J, N_VGetArrayPointer(vv), s->n, N_VGetArrayPointer(Jvv));
    return 0;
}

/* CVODES with Newton's method on a Newton matrix of callbacks (setup, solve, jtimes) for
 * x' = f; max_order 0: CVODES's own. */
void *create_with(int lmm, double t0, N_Vector y, CVRhsFn f, CVPrecSetupFn setup_fn,
                         CVPrecSolveFn solve_fn, CVJacTimesFn jtimes_fn, void *data,
                         double rtol, double atol, long max_steps, int max_order) {
    void *mem = CVodeCreate(lmm, CV_NEWTON);
    if (mem == NULL) return NULL;
    if (CVodeInit(mem, f, t0, y) || CVodeSStolerances(mem, rtol, atol) ||
        CVodeSetUserData(mem, data) || CVodeSetMaxNumSteps(mem, max_steps) ||
        CVodeSetErrHandlerFn(mem, quiet, NULL) || CVSpgmr(mem, PREC_LEFT, GMRES_DIMENSION) ||
        CVSpilsSetPreconditioner(mem, setup_fn, solve_fn) ||
        CVSpilsSetJacTimesVecFn(mem, jtimes_fn) ||
        (max_order > 0 && CVodeSetMaxOrd(mem, lmm == CV_BDF && max_order > 5 ? 5 : max_order))) {
        CVodeFree(&mem);
        return NULL;
    }
    return mem;
}

/* The same on the callbacks above (f's data starts with the sc_work they read). */
void *create(int lmm, double t0, N_Vector y, CVRhsFn f, void *data, double rtol,
                    double atol, long max_steps, int max_order) {
    return create_with(lmm, t0, y, f, setup, solve, jtimes, data, rtol, atol, max_steps,
                       max_order);
}

/* driver_internal.h */
int outside(sc_work *s, const double *x, int width, const double *p) {
    const sc_function *fn = s->fn;
    double inside = 0.0;
    int i;
    for (i = 0; i < width; ++i)
        if (!isfinite(x[i])) return 1;
    if (fn->domain == NULL || p == NULL) return 0;
    s->c.arg[0] = x;
    s->c.arg[1] = p;
    s->c.res[0] = &inside;
    return fn->domain(s->c.arg, s->c.res, s->c.iw, s->c.w, 0) != 0 || inside == 0.0;
}
