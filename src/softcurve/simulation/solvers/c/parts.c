
/* The parts of the columns' right-hand side (driver_internal.h), evaluated by compiled
 * functions of the same arguments (x;vec(S), u, d;scale). With two parts and a helper thread, the driver posts
 * each evaluation as a generation number; whichever thread claims the second part first
 * (an atomic exchange from the previous generation) evaluates it. The driver claims it
 * itself when it finishes the first part before the helper has started, so a helper that
 * is not scheduled (a busy machine) does not hold the driver up; only a helper preempted
 * after its claim does, until it runs again. Whichever thread evaluates it, the sum is
 * the same (same function, inputs and order of the sum). Waiters spin, then yield.
 * Which thread wins depends on the scheduler: a test that must run the helper's path
 * builds its own library with SOFTCURVE_TEST_HELPER_TAKES_ALL defined, where the driver
 * never claims the second part (it waits); the product's library never has it. */
#define _POSIX_C_SOURCE 200809L /* pthreads and sched_yield under -std=c99 */
#include <pthread.h>
#include <sched.h>
#include <stdlib.h>
#include <string.h>

#include "driver_internal.h"

#define SPINS_BEFORE_YIELD 4096 /* pauses, about 0.1-0.5 ms, before the waiter yields */

#ifdef SOFTCURVE_TEST_HELPER_TAKES_ALL
#define DRIVER_CLAIMS 0
#else
#define DRIVER_CLAIMS 1 /* the driver claims a second part the helper has not started */
#endif

static void relax(long *spins) {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
    if (++*spins > SPINS_BEFORE_YIELD) sched_yield();
}

static void run_part(sc_part *p) {
    p->status = p->fn(p->c.arg, p->c.res, p->c.iw, p->c.w, 0);
}

/* 1 when the calling thread claimed the second part of generation g. */
static int claim(sc_parts *z, unsigned g) {
    unsigned expected = g - 1;
    return __atomic_compare_exchange_n(&z->claimed, &expected, g, 0, __ATOMIC_ACQ_REL,
                                       __ATOMIC_ACQUIRE);
}

static void *help(void *data) {
    sc_parts *z = (sc_parts *)data;
    unsigned seen = 0;
    long spins = 0;
    while (!__atomic_load_n(&z->stop, __ATOMIC_ACQUIRE)) {
        unsigned g = __atomic_load_n(&z->posted, __ATOMIC_ACQUIRE);
        if (g == seen) {
            relax(&spins);
            continue;
        }
        seen = g;
        spins = 0;
        if (claim(z, g)) {
            run_part(&z->part[1]);
            z->helper_evaluations++;
            __atomic_store_n(&z->done, g, __ATOMIC_RELEASE);
        }
    }
    return NULL;
}

/* Every part at the arguments already in place (set before this call: the helper reads
 * them after the post); 0, or the first nonzero status of a part. */
int evaluate_parts(sc_parts *z) {
    unsigned g = ++z->generation;
    long spins = 0;
    if (z->count == 1) {
        run_part(&z->part[0]);
        return z->part[0].status;
    }
    if (z->helped) __atomic_store_n(&z->posted, g, __ATOMIC_RELEASE);
    run_part(&z->part[0]);
    if ((DRIVER_CLAIMS || !z->helped) && claim(z, g))
        run_part(&z->part[1]);
    else
        while (__atomic_load_n(&z->done, __ATOMIC_ACQUIRE) != g) relax(&spins);
    return z->part[0].status ? z->part[0].status : z->part[1].status;
}

/* Part k's work arrays for the function fn of work sizes sizes[0..3] (arg, res, iw, w),
 * reading args[0..2] and writing `outputs` doubles; 0, or 1 when out of memory. */
static int part_open(sc_part *p, casadi_fn fn, const long long *sizes, const double **args,
                     long outputs) {
    int i;
    memset(p, 0, sizeof(*p));
    p->fn = fn;
    p->out = (double *)calloc(outputs, sizeof(double));
    if (arrays_open(&p->c, sizes[0], sizes[1], sizes[2], sizes[3], 0) || !p->out) return 1;
    for (i = 0; i < 3; ++i) p->c.arg[i] = args[i];
    p->c.res[0] = p->out;
    return 0;
}

static void part_close(sc_part *p) {
    arrays_close(&p->c);
    free(p->out);
}

/* count parts, 1 or 2 (functions fns, work sizes sizes[4 k..4 k+3], each writing
 * `outputs` doubles) on the arguments args; a helper thread for the second part unless
 * helper is HELPER_NONE (without one where it cannot be started). 0, or 1 when out of
 * memory or given another count. */
int parts_open(sc_parts *z, int count, const casadi_fn *fns, const long long *sizes,
                      const double **args, long outputs, int helper) {
    int k;
    memset(z, 0, sizeof(*z));
    if (count < 1 || count > 2) return 1;
    z->count = count;
    for (k = 0; k < count; ++k)
        if (part_open(&z->part[k], fns[k], sizes + 4 * k, args, outputs)) return 1;
    if (count == 2 && helper != HELPER_NONE)
        z->helped = pthread_create(&z->helper, NULL, help, z) == 0;
    return 0;
}

void parts_close(sc_parts *z) {
    int k;
    if (z->helped) {
        __atomic_store_n(&z->stop, 1, __ATOMIC_RELEASE);
        pthread_join(z->helper, NULL);
    }
    for (k = 0; k < z->count; ++k) part_close(&z->part[k]);
}
