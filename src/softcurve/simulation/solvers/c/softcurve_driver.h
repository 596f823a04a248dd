/* softcurve's driver of SUNDIALS CVODES: what Python sees of it. Python derives its ctypes
 * declarations from this file (softcurve.compiled.read_header), so the header is written
 * in the restricted form that parser reads:
 *   - comments are C block comments; preprocessor lines are ignored;
 *   - constants are `enum { NAME = INTEGER, ... };`;
 *   - a function-pointer type is `typedef RET (*NAME)(...);` on its own (a pointer);
 *   - a struct is `typedef struct { ... } NAME;`, one `TYPE NAME;` field per line;
 *   - an exported function is `SC_EXPORT RET NAME(TYPE NAME, ...);` (lines may wrap);
 *   - TYPE is `int`, `long`, `long long` or `double`, optionally `const`, or any of them,
 *     `void`, a struct or a function-pointer type followed by one `*` (a pointer; to a
 *     struct of this header: a pointer to its ctypes Structure), or a function-pointer
 *     type alone. */
#ifndef SOFTCURVE_DRIVER_H
#define SOFTCURVE_DRIVER_H

#define SC_EXPORT __attribute__((visibility("default")))

/* CasADi's generated function: f(arg, res, iw, w, mem). */
typedef int (*casadi_fn)(const double **arg, double **res, long long *iw, double *w, int mem);

/* The state derivative over `width` members at once (lanes_derivative of softcurve.simulation.solvers):
 * x, u, p and xdot hold entry j of member l at [j width + l], aligned to 64 bytes; w has
 * sz_lanes_w such rows. */
typedef int (*lanes_fn)(const double *x, const double *u, const double *p, double *xdot,
                        double *w);

/* A model described to the driver: its generated right-hand side f(x, tau, p) (nx states,
 * nu forces, np parameters) with its work sizes (the largest over f, force, domain and
 * jacobian),
 * optionally an actuator's force(q, v) -> tau = H(q) v with m inputs: the member's input
 * is then v (m) or, with lag, the command of v, whose m states follow x with the rate
 * (clip(command, lower, upper) - v) / time_constant; the model's generated
 * domain(q, p) -> 1 inside, 0 outside (the elements' rule, written once in Python; NULL:
 * no configuration is outside); optionally the same state derivative over lanes; and
 * optionally the model's exact Jacobian jacobian(x, tau, p) -> (J_x (nx x nx), D (nu x nu))
 * (softcurve.symbolic.derivatives; NULL: forward differences of f), with it the force's
 * force_jacobian(q, v) -> (d tau / d q (nu x nu), H(q) (nu x m)) (NULL: forward
 * differences of force). */
typedef struct {
    casadi_fn f;
    casadi_fn force;
    casadi_fn domain;
    casadi_fn jacobian;
    casadi_fn force_jacobian;
    int nx;
    int nu;
    int np;
    int m;
    int lag;
    long long sz_arg;
    long long sz_res;
    long long sz_iw;
    long long sz_w;
    const double *lower;
    const double *upper;
    double time_constant;
    lanes_fn lanes;
    int width;
    long long sz_lanes_w;
} sc_function;

/* The settings of a call (not its arrays), filled by Python in one place
 * (softcurve.simulation.solvers.driver_options). */
typedef struct {
    double rtol;          /* relative tolerance */
    double atol;          /* absolute tolerance of the integrated state */
    long max_steps;       /* steps allowed per output */
    int max_order;        /* the largest order of the method; 0: CVODES's own */
    int family;           /* softcurve_sensitivities: a FAMILY_* below */
    double settled_ratio; /* softcurve_integrate: settled when max |xdot| ratio < fastest */
    int columns_tested;   /* softcurve_sensitivities: the columns in the error test too */
    int helper;           /* softcurve_sensitivities: HELPER_NONE or HELPER_SHARED */
    const double *radau;  /* FAMILY_RADAU: the method's RADAU_CONSTANTS constants */
} sc_options;

/* The families of softcurve_integrate: CVODES's Adams and BDF (SUNDIALS's CV_ADAMS and
 * CV_BDF), and the driver's own Radau IIA of order 5 (radau.c). */
enum { FAMILY_ADAMS = 1, FAMILY_BDF = 2, FAMILY_RADAU = 3 };

/* Where Radau IIA's constants lie in sc_options.radau (RADAU_CONSTANTS doubles, computed
 * by softcurve.simulation.solvers.radau_constants): the nodes c (3); T and T^-1 (3 x 3,
 * row-major), with T^-1 A^-1 T = [[gamma, 0, 0], [0, alpha, -beta], [0, beta, alpha]] for
 * the method's matrix A; gamma, alpha, beta; the error estimate's weights E (3); the dense
 * output's P (3 x 3, row-major: the collocation polynomial is y + sum_k x^(k+1) sum_i
 * P[k][i] Z_i at t + x h, for the stage increments Z_i). */
enum {
    RADAU_C = 0,
    RADAU_T = 3,
    RADAU_TI = 12,
    RADAU_GAMMA = 21,
    RADAU_ALPHA = 22,
    RADAU_BETA = 23,
    RADAU_E = 24,
    RADAU_P = 27,
    RADAU_CONSTANTS = 36
};

/* Who evaluates the second of two parts of the columns' right-hand side: the driver's
 * own thread, or whichever of it and a helper thread claims it first. */
enum { HELPER_NONE = 0, HELPER_SHARED = 1 };

/* softcurve_sensitivities' flag where Radau IIA's columns do not converge on a fresh
 * Jacobian either (the state's step did): not a CVODES flag. */
enum { COLUMNS_FAILURE = -101 };

/* softcurve_adjoint_forward's flag where the tape is full (call again with more room),
 * and the layout of a taped step: TAPE_HEAD doubles (where the step began, its size, the
 * row of its input, its Jacobian's index among the taped ones), then the state at its
 * start and its three stage increments (4 n doubles in all after the head). */
enum { TAPE_FULL = -102 };
enum { TAPE_T = 0, TAPE_H = 1, TAPE_ROW = 2, TAPE_JACOBIAN = 3, TAPE_HEAD = 4 };

/* Integrate `count` members over the grid `times[0..k)` from out[b, 0, :] (physical, at
 * times[0]), in segments ending at the output indices ends[0..n_ends) (the last is k - 1),
 * each with the member's input of that segment u[b, s, :]. Member b is integrated with the
 * family lmm[b] (FAMILY_ADAMS, FAMILY_BDF or FAMILY_RADAU). CVODES starts afresh at every
 * segment; where restart[s] and fastest[b] > 0, segment s is integrated with BDF if the
 * member has settled (max |xdot / nominal| * settled_ratio < fastest[b]) and with lmm[b]
 * otherwise. Radau IIA keeps its step size and Jacobian over segments, and its steps go on
 * through a segment whose input is the last one's. A member stops at its first output
 * outside the domain (an entry not finite, or, with check_domain, the configuration
 * outside by fn->domain with the member's parameters p[b, :]) or at a failure of its
 * method. Writes out[b, i, :], reached[b] (outputs filled, the one outside the domain
 * included), flag[b] (0, 1 outside the domain, CVODES's negative flag, or Radau IIA's
 * failure as the CVODES flag of the same meaning, -100 when it could not be set up),
 * used_bdf[b], and adds to stats[b, :]: steps, right-hand sides, Jacobians, linear-solver
 * setups (Radau IIA: factorizations of its pair of Newton matrices), error-test failures,
 * Newton failures. Where fn has lanes, members b .. b + width - 1 of one multistep family
 * (b a multiple of fn->width) go in a group, the others alone: a group switches to BDF at
 * a restart where all have settled, and its counters are every member's; a group that
 * fails is integrated again member by member (outputs beyond what a member then reaches
 * are NaN). Returns 0. */
SC_EXPORT int softcurve_integrate(const sc_function *fn, const sc_options *options, int count,
                                  const int *lmm, const double *fastest, const double *u,
                                  const double *p, const double *nominal, int check_domain,
                                  const double *times, int k, const int *ends,
                                  const int *restart, int n_ends, double *out, int *reached,
                                  int *flag, int *used_bdf, long *stats);

/* Integrate from out[0, :] = (x0, vec(S0)) (physical units) over times[0..count) and
 * write out[i, :] = (x, vec(S)) at times[i]. fn describes f(x, u, d) (nx states, nu
 * inputs); fs holds `parts` functions (x;vec(S), u, d;scale) whose outputs, after
 * `leading` entries, sum to vec(f_x S + f_d), with work sizes fs_sizes[4 k..4 k+3]
 * (sz_arg, sz_res, sz_iw, sz_w); options->helper: who evaluates the second part. d
 * feeds f, dsc = (d, scale) the parts.
 * table (count rows): per interval the inputs (linear = 0: a jump at every sample, where
 * CVODES restarts) or the line (a, b) (linear = 1: integrated through). options->family:
 * FAMILY_ADAMS, FAMILY_BDF (CVODES's staggered corrector for the columns) or FAMILY_RADAU
 * (Radau IIA, the columns the derivative of its discrete scheme);
 * options->columns_tested: CVODES's sensitivities in the error test too.
 * Returns 0, CVODES's negative flag, or -100 when the solver could not be set up; adds to
 * stats (zeroed by the caller): steps, right-hand sides, Jacobians, linear-solver setups,
 * error-test failures, sensitivity evaluations, second parts the helper thread
 * evaluated; *reached: outputs filled (x0 included). */
SC_EXPORT int softcurve_sensitivities(const sc_function *fn, const sc_options *options,
                                      const casadi_fn *fs, const long long *fs_sizes, int parts,
                                      int leading, int m, const double *d, const double *dsc,
                                      const double *times, int count, const double *table,
                                      int linear, double *out, long *stats, int *reached);

/* The forward pass of the discrete adjoint of Radau IIA (adjoint.c): one member of fn
 * integrated by Radau IIA (options: tolerances, steps per output, the constants) from
 * out[0, :] (physical, at times[0]) over the output times times[1..count), with the input
 * u[i, :] held over [times[i], times[i + 1]), parameters p and state scales nominal. The
 * steps end at the output times i where stops[i] is nonzero (an input changes there, or
 * the derivative along it is asked; the last always) and pass through the others, whose
 * states come from the collocation polynomial. Writes out[i, :], owner[i] (the taped step
 * whose end or polynomial gave output i; -1 for the start) and abscissa[i] (where in that
 * step, as a fraction of it: 1 its end); tapes every accepted step into tape (capacity
 * steps of TAPE_HEAD + 4 n doubles) and the Jacobians its Newton iteration took into
 * jacobians (jacobian_capacity of n x n); used[0], used[1]: steps and Jacobians taped.
 * Returns 0, TAPE_FULL, -100 when it could not be set up, or Radau IIA's failure as the
 * CVODES flag of the same meaning; adds to stats the counters of softcurve_integrate;
 * *reached: outputs filled (out[0] included). */
SC_EXPORT int softcurve_adjoint_forward(const sc_function *fn, const sc_options *options,
                                        const double *u, const double *p,
                                        const double *nominal, const double *times, int count,
                                        const int *stops, double *out, long *owner,
                                        double *abscissa, double *tape, long capacity,
                                        double *jacobians, long jacobian_capacity, long *used,
                                        long *stats, int *reached);

/* The backward pass over the `steps` taped by softcurve_adjoint_forward (the same fn,
 * options, u, p, nominal, count, owner and abscissa; fn's f the whole right-hand side, no
 * force or lag beside it): with seeds[i, :] the derivative of a scalar along the physical
 * state out[i, :], writes its derivative along the initial state into lambda (n) and adds
 * those along the inputs into d_u (the row each step held, count rows of the inputs) and
 * the parameters into d_p (np). vjp(x, u, p, v) -> (f_x^T v, f_u^T v, f_p^T v) is f's
 * reverse mode, of work sizes vjp_sizes (4). Returns 0, -100 when it could not be set up,
 * CV_CONV_FAILURE where a step's multipliers do not converge on a fresh Jacobian either,
 * CV_LSETUP_FAIL where its Newton matrices are singular, CV_RHSFUNC_FAIL where the vjp
 * fails or a step's results along u or p are not finite (the caller checks the sums);
 * adds to stats: vjp evaluations,
 * iterations, factorizations, fresh Jacobians. */
SC_EXPORT int softcurve_adjoint_backward(const sc_function *fn, const sc_options *options,
                                         casadi_fn vjp, const long long *vjp_sizes,
                                         const double *u, const double *p,
                                         const double *nominal, int count, const long *owner,
                                         const double *abscissa, const double *tape,
                                         long steps, const double *jacobians,
                                         const double *seeds, double *lambda, double *d_u,
                                         double *d_p, long *stats);

/* The layout of a point taped by softcurve_adams_forward: ADAMS_HEAD doubles (its time,
 * the row of its segment's input, the order q of its polynomial), then the Taylor
 * coefficients y^(k) / k!, k = 0 .. q, of the scaled state there ((max_order + 1) n
 * doubles after the head): CVODES's interpolant over the step that ended there, or at a
 * start (order 0) the state alone. */
enum { ADAMS_T = 0, ADAMS_ROW = 1, ADAMS_ORDER = 2, ADAMS_HEAD = 3 };

/* The forward pass of the continuous adjoint (adams_adjoint.c): one member of fn (f the
 * whole right-hand side, no force or lag beside it) integrated by CVODES (options->family:
 * FAMILY_ADAMS or FAMILY_BDF; tolerances, steps per output, largest order, at least 1) from
 * out[0, :]
 * (physical, at times[0]) over the output times times[1..count), with the input u[i, :]
 * held over [times[i], times[i + 1]), parameters p and state scales nominal, restarting
 * at the output times i where stops[i] is nonzero (the last is a stop anyway) and after
 * every restart_interval of time in between (at a step's end, where the order climbs
 * down again: softcurve.simulation.solvers.RESTART_INTERVAL says why). Writes
 * out[i, :] and tapes every start and the end of every internal step into
 * tape (capacity points of ADAMS_HEAD + (max_order + 1) n doubles); *used: points taped.
 * Returns 0,
 * TAPE_FULL, -100 when it could not be set up, or CVODES's negative flag; adds to stats
 * the counters of softcurve_integrate; *reached: outputs filled (out[0] included). */
SC_EXPORT int softcurve_adams_forward(const sc_function *fn, const sc_options *options,
                                      double restart_interval, const double *u,
                                      const double *p, const double *nominal,
                                      const double *times, int count, const int *stops,
                                      double *out, double *tape, long capacity, long *used,
                                      long *stats, int *reached);

/* The backward pass over the `points` taped by softcurve_adams_forward (the same fn, u, p,
 * nominal, times, count and stops, and options but for atol, the adjoint's absolute
 * tolerance in the units of the largest seed, max |nominal seed|): with seeds[i, :] the
 * derivative of a scalar along the physical state out[i, :], integrates the adjoint
 * equations backward by the same method and writes the scalar's derivative along the
 * initial state into lambda (n), and adds those along the inputs into d_u (row i: along
 * the input held over [times[i], times[i + 1]], count rows) and the parameters into d_p
 * (np).
 * vjp(x, u, p, v) -> (f_x^T v, f_u^T v, f_p^T v) is f's reverse mode, of work sizes
 * vjp_sizes (4). Returns 0, -100 when it could not be set up, or CVODES's negative flag
 * (CV_RHSFUNC_FAIL where the vjp fails or is not finite); adds to stats: steps, vjp
 * evaluations, Jacobians, linear-solver setups, error-test failures, starts (CVODES
 * starts afresh at every segment's end, every output time with a nonzero seed, and
 * after every restart_interval of time without one). */
SC_EXPORT int softcurve_adams_backward(const sc_function *fn, const sc_options *options,
                                       double restart_interval, casadi_fn vjp,
                                       const long long *vjp_sizes, const double *u,
                                       const double *p, const double *nominal,
                                       const double *times, int count, const int *stops,
                                       const double *tape, long points, const double *seeds,
                                       double *lambda, double *d_u, double *d_p, long *stats);

/* f at `count` states x[b, :] (physical, nx + lagging inputs) with inputs u[b, :] and
 * parameters p (shared): xdot[b, :]. Returns 0, or -100 when out of memory. */
SC_EXPORT int softcurve_rhs(const sc_function *fn, int count, const double *x, const double *u,
                            const double *p, double *xdot);

/* The Jacobian of the integrated scaled state's derivative, J (n x n, column-major, n = nx
 * plus the lagging inputs), that the Newton matrix takes at the physical state x with
 * inputs u, parameters p and state scales nominal: the problem's exact one, or forward
 * differences. Returns 0, -1 when a function fails, or -100 when out of memory. */
SC_EXPORT int softcurve_newton_jacobian(const sc_function *fn, const double *x, const double *u,
                                        const double *p, const double *nominal, double *J);

/* The Newton matrices of `from` states and more factored and solved by LAPACK's dgetf2
 * and dgetrs, the complex ones of Radau IIA by zgetf2 and zgetrs, at these addresses
 * (SciPy's; NULL: by the driver's own loops, as below `from`). Called once, when the
 * library is loaded. */
SC_EXPORT void softcurve_use_lapack(void *getf2, void *getrs, void *zgetf2, void *zgetrs,
                                    int from);

/* sizeof of the structs above, for the check that Python's declarations match. */
SC_EXPORT long softcurve_sizeof_sc_function(void);
SC_EXPORT long softcurve_sizeof_sc_options(void);

#endif
