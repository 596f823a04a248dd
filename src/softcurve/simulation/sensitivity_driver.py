"""The C source of the CVODES driver's forward-sensitivity entry, compiled with
``DRIVER_SOURCE`` of ``softcurve.simulation.cvodes_driver`` into one library by
:mod:`softcurve.simulation.native` (it uses that source's declarations, work struct and
Newton-matrix callbacks).

Kept as a Python string so that it ships with the package like any module.
"""

SENSITIVITY_SOURCE = r"""
/* Forward sensitivities of an experiment (softcurve.simulation.sensitivity): the state
 * x' = f(x, u(t), d) by CVODES with Newton's method on its own Newton matrix (the
 * callbacks above), the m sensitivity columns S' = f_x S + f_d by CVODES's staggered
 * corrector. By default only the state is in the error test (CVODES's default): with
 * the columns in it too (columns_tested), the paper robot's 300 s trial takes 1.6 times
 * the steps for columns more accurate than a fit needs (docs/validation.md, "Speed").
 * f_x S + f_d comes from the compiled function fs(x;vec(S), u, d;scale) -> f;vec(S') of
 * the identification. */
typedef int (*CVSensRhsFn)(int Ns, realtype t, N_Vector y, N_Vector ydot, N_Vector *yS,
                           N_Vector *ySdot, void *data, N_Vector tmp1, N_Vector tmp2);
extern int CVodeSensInit(void *mem, int Ns, int ism, CVSensRhsFn fS, N_Vector *yS0);
extern int CVodeSensReInit(void *mem, int ism, N_Vector *yS0);
extern int CVodeSensEEtolerances(void *mem);
extern int CVodeSetSensErrCon(void *mem, int errconS);
extern int CVodeGetSens(void *mem, realtype *tret, N_Vector *yS);
extern N_Vector *N_VCloneVectorArray_Serial(int count, N_Vector w);
extern void N_VDestroyVectorArray_Serial(N_Vector *vs, int count);
#define CV_STAGGERED 2
#define SENSITIVITY_STATS 6

typedef struct {
    sc_work s; /* first member: the Newton-matrix callbacks read the data as an sc_work */
    casadi_fn fs;
    const double **arg;
    double **res;
    long long *iw;
    double *w, *xs, *out, *u;
    const double *dsc, *table, *times;
    int m, nu, count, linear, row;
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
    int n = z->s.n, i, j;
    size_t bytes = n * sizeof(double);
    (void)ydot; (void)tmp1; (void)tmp2;
    if (z->linear) inputs_at(z, t);
    memcpy(z->xs, N_VGetArrayPointer(y), bytes);
    for (j = 0; j < m; ++j) memcpy(z->xs + n * (1 + j), N_VGetArrayPointer(yS[j]), bytes);
    z->arg[0] = z->xs;
    z->arg[1] = z->u;
    z->arg[2] = z->dsc;
    z->res[0] = z->out;
    if (z->fs(z->arg, z->res, z->iw, z->w, 0)) return -1;
    z->sensitivity_evaluations++;
    for (j = 0; j < m; ++j) {
        double *column = N_VGetArrayPointer(ySdot[j]);
        memcpy(column, z->out + n * (1 + j), bytes);
        for (i = 0; i < n; ++i)
            if (!isfinite(column[i])) return 1;
    }
    return 0;
}

/* Integrate from out[0, :] = (x0, vec(S0)) (physical units) over times[0..count) and
 * write out[i, :] = (x, vec(S)) at times[i]. fn describes f(x, u, d) (nx states, nu
 * inputs); fs_sizes are fs's sz_arg, sz_res, sz_iw, sz_w; d feeds f, dsc = (d, scale) fs.
 * table (count rows): per interval the inputs (linear = 0: a jump at every sample, where
 * CVODES restarts) or the line (a, b) (linear = 1: integrated through). lmm: 1 Adams,
 * 2 BDF; columns_tested: the sensitivities in the error test too. Returns 0, CVODES's
 * negative flag, or -100 when the solver could not be set up; adds to stats (zeroed by
 * the caller): steps, right-hand sides, Jacobians, linear-solver setups, error-test
 * failures, sensitivity evaluations; *reached: outputs filled (x0 included). */
__attribute__((visibility("default"))) int softcurve_sensitivities(
    const sc_function *fn, casadi_fn fs, const long long *fs_sizes, int m, const double *d,
    const double *dsc, const double *times, int count, const double *table, int linear,
    int lmm, double rtol, double atol, long max_steps, int columns_tested, double *out,
    long *stats, int *reached) {
    int n = fn->nx, width = fn->nx * (1 + m), i, j, flag = 0, counted = 0;
    size_t bytes = n * sizeof(double);
    sc_sensitivity z;
    void *mem = NULL;
    N_Vector y = N_VNew_Serial(n), *yS = NULL;
    double *ones = (double *)malloc(n * sizeof(double)), tret;
    memset(&z, 0, sizeof(z));
    *reached = 1;
    flag = work_open(&z.s, fn, n) ? -100 : 0;
    z.s.p = d;
    z.arg = (const double **)calloc(fs_sizes[0] > 3 ? fs_sizes[0] : 3, sizeof(double *));
    z.res = (double **)calloc(fs_sizes[1] > 1 ? fs_sizes[1] : 1, sizeof(double *));
    z.iw = (long long *)calloc(fs_sizes[2] + 1, sizeof(long long));
    z.w = (double *)calloc(fs_sizes[3] + 1 + 2 * width + fn->nu, sizeof(double));
    if (flag || !y || !ones || !z.arg || !z.res || !z.iw || !z.w ||
        (m > 0 && !(yS = N_VCloneVectorArray_Serial(m, y)))) {
        flag = -100;
        goto done;
    }
    if (count < 2) goto done;
    for (i = 0; i < n; ++i) ones[i] = 1.0;
    z.s.nominal = ones; /* unscaled: the absolute tolerance is in the state's units */
    z.fs = fs;
    z.m = m;
    z.nu = fn->nu;
    z.count = count;
    z.linear = linear;
    z.row = 1;
    z.dsc = dsc;
    z.table = table;
    z.times = times;
    z.xs = z.w + fs_sizes[3] + 1;
    z.out = z.xs + width;
    z.u = z.out + width;
    z.s.u = z.u;
    memcpy(N_VGetArrayPointer(y), out, bytes);
    for (j = 0; j < m; ++j) memcpy(N_VGetArrayPointer(yS[j]), out + n * (1 + j), bytes);
    inputs_at(&z, times[1]);
    mem = create(lmm == CV_BDF ? CV_BDF : CV_ADAMS, times[0], y, state_rhs, &z, rtol, atol,
                 max_steps, 0);
    if (!mem || (m > 0 && (CVodeSensInit(mem, m, CV_STAGGERED, sensitivity_rhs, yS) ||
                   CVodeSensEEtolerances(mem) || CVodeSetSensErrCon(mem, columns_tested != 0)))) {
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
    work_close(&z.s);
    free(z.arg);
    free(z.res);
    free(z.iw);
    free(z.w);
    return flag;
}
"""
