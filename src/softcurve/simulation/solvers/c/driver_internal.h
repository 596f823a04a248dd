/* The driver's own declarations, shared by its C files (not seen by Python): the work of
 * one member, the Newton-matrix callbacks' helpers and the domain test (driver.c), Radau
 * IIA (radau.c), the
 * parts of the columns' right-hand side (parts.c). */
#ifndef SOFTCURVE_DRIVER_INTERNAL_H
#define SOFTCURVE_DRIVER_INTERNAL_H

#include <complex.h>
#include <pthread.h>

#include "softcurve_driver.h"
#include "sundials2.h"

#define GMRES_DIMENSION 2 /* one iteration converges (exact preconditioner); one spare */
#define STATS 6

/* The arrays of one call of a generated function: arguments, results, integer and real
 * work. */
typedef struct {
    const double **arg;
    double **res;
    long long *iw;
    double *w;
} sc_arrays;

/* One member's work: its inputs, parameters and scales, the arrays of f, the state and its
 * derivative, the Jacobian and the Newton matrix's factors. */
typedef struct {
    const sc_function *fn;
    const double *u, *p, *nominal;
    sc_arrays c;
    double *x, *xdot, *tau, *J, *LU, *ftmp;
    double *Jx, *mass, *dtau; /* with an exact Jacobian: its outputs, a force's column */
    double *dforce; /* with the force's exact derivatives: d tau / d q, then H(q) */
    int n; /* states integrated: nx, plus m lagging inputs */
    int *piv;
    long jacobians;
} sc_work;

/* The arrays for a function of work sizes sz_arg, sz_res, sz_iw, sz_w (at least the
 * three arguments and one result every function here takes), with `extra` doubles after
 * w's own, from w + sz_w + 1; 0, or 1 when out of memory (arrays_close frees what was
 * allocated). */
int arrays_open(sc_arrays *c, long long sz_arg, long long sz_res, long long sz_iw,
                long long sz_w, long extra);
void arrays_close(sc_arrays *c);
/* Work arrays of f for n states (x, xdot, tau, ftmp, J, LU and, with an exact Jacobian,
 * its outputs in one block after f's own work); 0, or 1 when out of memory (work_close
 * frees what was allocated). */
int work_open(sc_work *s, const sc_function *fn, int n);
void work_close(sc_work *s);
/* CVODES's counters since its last (re)start: steps, right-hand sides, linear-solver
 * setups, error-test failures, Newton failures. */
void read_counters(void *mem, long counters[5]);
/* Adds counters in read_counters' order to stats[0], [1], [3], [4] and, with
 * newton_failures, [5] (softcurve_integrate's order; the sensitivities keep [5] for
 * their own count). */
void add_counters(const long counters[5], long *stats, int newton_failures);
/* The states of f: nx and the lagging inputs; a member's inputs: the actuator's m, or
 * the nu forces. */
int states_of(const sc_function *fn);
int inputs_of(const sc_function *fn);
/* ydot = f(nominal * y, u, p) / nominal; 1 (recoverable) on a non-finite value */
int evaluate(sc_work *s, const double *y, double *ydot);
/* evaluate() as CVODES's right-hand side (data: an sc_work). */
int rhs(realtype t, N_Vector y, N_Vector ydot, void *data);
/* Forward-difference step of a state entry's value v: the square root of the machine
 * epsilon, relative where |v| > 1. */
double difference_step(double v);
/* s->J (column-major, the integrated scaled state's) at y, where fy = f(y): the model's
 * exact Jacobian where the problem has one, else forward differences of f; 0, or the
 * failing call's nonzero. */
int newton_jacobian(sc_work *s, double *y, const double *fy);
/* A = I - gamma J (n x n, column-major) as its LU factors (partial pivoting, row swaps in
 * piv); 1 where singular. */
int factor_newton(const double *J, double gamma, int n, double *A, int *piv);
/* z = A^-1 z with the factors of factor_newton: the row swaps, then L, then U. */
void solve_newton(const double *A, const int *piv, int n, double *z);
/* The same two for A = I - mu J with a complex mu (Radau IIA's complex Newton matrix). */
int factor_complex(const double *J, double complex mu, int n, double complex *A, int *piv);
void solve_complex(const double complex *A, const int *piv, int n, double complex *z);
/* Jv = J v (n x n, column-major). */
void times_jacobian(const double *J, const double *v, int n, double *Jv);
/* CVODES with Newton's method on a Newton matrix of callbacks (setup, solve, jtimes) for
 * x' = f; max_order 0: CVODES's own. */
void *create_with(int lmm, double t0, N_Vector y, CVRhsFn f, CVPrecSetupFn setup_fn,
                  CVPrecSolveFn solve_fn, CVJacTimesFn jtimes_fn, void *data, double rtol,
                  double atol, long max_steps, int max_order);
/* The same on the callbacks above (f's data starts with the sc_work they read). */
void *create(int lmm, double t0, N_Vector y, CVRhsFn f, void *data, double rtol, double atol,
             long max_steps, int max_order);
/* Whether the state x (width entries, the configuration first) lies outside the model's
 * domain: an entry not finite, or, with parameters p (NULL: no such check), the
 * configuration outside by the model's domain(q, p) (s's function's, on s's work arrays;
 * the rule of softcurve.description.elements, whose Python side words the message). */
int outside(sc_work *s, const double *x, int width, const double *p);

/* Radau IIA of order 5 on one member's work (radau.c). */
#define NEWTON_ITERATIONS 7 /* the most simplified Newton iterations in one step */
#define FACTOR_MAX 8.0      /* the largest growth of the step size from one to the next */
enum { JACOBIAN_NONE = 0, JACOBIAN_KEPT = 1, JACOBIAN_FRESH = 2 }; /* s->J: none, of an
                                                earlier state, of this step's start */
typedef struct {
    sc_work *s;
    const double *k; /* the method's constants, RADAU_* */
    int n;
    double rtol, atol, newton_tolerance;
    double t, t_stop, h;         /* the time, where steps stop, the next step size */
    double t_last, h_last;       /* the last accepted step (h_last 0: none since the start) */
    double h_factored;           /* the step size of the factors (0: none) */
    double eta, error_last;      /* the last Newton contraction factor and error norm */
    int jacobian, continues, predict, rejected, first;
    double *block, *y, *fy, *y_last, *scale, *v, *e, *ze, *z, *w, *dw, *f, *g, *q;
    double complex *lu; /* the complex factors (n x n), then n complex for a solve */
    int *piv;
    long counters[5]; /* since the start, as read_counters orders them */
    void (*inputs)(void *data, double t); /* sets s->u at t (NULL: constant) */
    void *inputs_data;
} sc_radau;

/* 0, or 1 when out of memory or without constants (radau_close frees what was
 * allocated). */
int radau_open(sc_radau *r, sc_work *s, const sc_options *o);
void radau_close(sc_radau *r);
/* A new member: no step size, no Jacobian. */
void radau_reset(sc_radau *r);
/* Start at t0 from the scaled state y, stepping up to t_stop at most (where the input
 * changes next); with same_input the steps go on from where they reached, at t0 or beyond
 * (y unread), and with a new input from where the last one ended if that is t0. 0, or
 * CV_FIRST_RHSFUNC_ERR. */
int radau_start(sc_radau *r, double t0, const double *y, double t_stop, int same_input);
/* One accepted step (*tret: where it ends); 0, or the CVODES flag of the failure's
 * meaning. */
int radau_step(sc_radau *r, double *tret);
/* The state at t within the last accepted step, by its collocation polynomial. */
void radau_interpolate(const sc_radau *r, double t, double *out);
/* The same for any n values that moved over the last accepted step from `last` to `now`
 * along the collocation polynomial of coefficients q (3 blocks of n): now itself at the
 * step's end or before any step. */
void radau_value(const sc_radau *r, double t, const double *last, const double *q,
                 const double *now, double *out);
/* The starting stages z (3 blocks of n) of a step of size h: the polynomial (coefficients
 * q) of the last step, of size h_last, from `last` to `now`, extrapolated to the nodes and
 * taken from now; zero without a last step (h_last 0) or where h exceeds what the
 * controller grows a step to. */
void radau_predict(const sc_radau *r, const double *last, const double *q, const double *now,
                   double h_last, double h, double *z);
/* The collocation polynomial with coefficients q (3 blocks of n) at x, entry j:
 * sum_k x^(k+1) q_k[j] (the state or a column at t_last + x h_last, minus its value at
 * t_last). */
double radau_polynomial(const double *q, int n, double x, int j);
/* A fresh Jacobian at the last step's start (y_last at t_last) and the factors at its
 * size h_last, for a linear system of that step that the kept ones do not solve (the
 * columns' of sensitivity.c); 0, or 1 where f, the Jacobian or the factors fail. */
int radau_refresh(sc_radau *r);
/* out_i = sum_m M[3 i + m] in_m for three blocks of n entries (M 3 x 3, row-major, of the
 * constants: T, T^-1, P): stages transformed, or the collocation polynomial's
 * coefficients. */
void radau_mix(const double *M, const double *in, int n, double *out);
/* The simplified Newton correction dw (3 n) of transformed stages w (3 n) at step size h
 * from the stage derivatives f (3 n), on the factors of the last step (r->h_factored ==
 * h). */
void radau_correction(sc_radau *r, double h, const double *f, const double *w, double *dw);

/* One part of the columns' right-hand side: its function, arrays and output. */
typedef struct {
    casadi_fn fn;
    sc_arrays c;
    double *out;
    int status;
} sc_part;

typedef struct {
    sc_part part[2];
    int count;          /* parts: 1 or 2 */
    int helped;         /* a helper thread runs */
    pthread_t helper;
    unsigned posted, claimed, done; /* generations (atomics; wrap around by definition) */
    int stop;                       /* the helper's stop request (atomic) */
    unsigned generation;
    long helper_evaluations; /* second parts the helper evaluated (read after the join) */
} sc_parts;

/* count parts, 1 or 2 (functions fns, work sizes sizes[4 k..4 k+3], each writing
 * `outputs` doubles) on the arguments args; a helper thread for the second part unless
 * helper is HELPER_NONE (without one where it cannot be started). 0, or 1 when out of
 * memory or given another count. */
int parts_open(sc_parts *z, int count, const casadi_fn *fns, const long long *sizes,
               const double **args, long outputs, int helper);
/* Every part at the arguments already in place (set before this call: the helper reads
 * them after the post); 0, or the first nonzero status of a part. */
int evaluate_parts(sc_parts *z);
void parts_close(sc_parts *z);

#endif
