/* The stepper's period over lanes (period_source of softcurve.simulation.stepper):
 * SC_SUBSTEPS steps of the method, then the observation, for rows start:stop of x
 * (N, SC_NX) and u (N, SC_NU) into out (N, SC_NX + SC_NOBS), all row-major float64, with p
 * and period shared; a last share shorter than a vector repeats its last member in the
 * unused lanes.
 *
 * Python writes before this file what it computes from the model and the method: the
 * lanes prelude and functions (sc_xdot, sc_observe and the step's), the entry's name
 * SC_ENTRY, the sizes (SC_NX, SC_NU, SC_NOBS, SC_SUBSTEPS; SC_WORK vectors of work of the
 * lanes functions, SC_SCRATCH of the step), the step's declarations and statements
 * (SC_STEP_DECLARATIONS, SC_STEP_LINES, from the stepper's step writers)
 * and SC_GENERATED. Without them the file compiles alone, on stand-ins (the test of the
 * shipped C files). */
#ifndef _ISOC11_SOURCE
#define _ISOC11_SOURCE /* aligned_alloc under -std=c99 */
#endif
#include <stdlib.h>

#ifndef SC_GENERATED
#include "lanes_prelude.h"
#define SC_ENTRY softcurve_lanes_period
#define SC_NX 1
#define SC_NU 1
#define SC_NOBS 1
#define SC_SUBSTEPS 1
#define SC_WORK 1
#define SC_SCRATCH 0
#define SC_STEP_DECLARATIONS
#define SC_STEP_LINES sc_xdot(y, U, p, y, w);
static void sc_xdot(const sc_v *in0, const sc_v *in1, const double *in2, sc_v *out0,
                    sc_v *restrict w) {
    (void)w;
    out0[0] = in0[0] + in1[0] * sc_broadcast(in2[0]);
}
static void sc_observe(const sc_v *in0, const double *in1, sc_v *out0, sc_v *restrict w) {
    (void)w;
    out0[0] = in0[0] * sc_broadcast(in1[0]);
}
#endif

__attribute__((visibility("default"))) int SC_ENTRY(
    const double* x, const double* u, const double* p,
    const double* period, double* out, long start, long stop) {
  sc_v* w = aligned_alloc(sizeof(sc_v), sizeof(sc_v) * (SC_WORK + SC_SCRATCH));
  if (w == NULL) return 1;
  sc_v* scratch = w + SC_WORK;
  const sc_v h = sc_broadcast(period[0] / SC_SUBSTEPS);
  sc_v y[SC_NX], U[SC_NU > 0 ? SC_NU : 1], o[SC_NOBS];
  SC_STEP_DECLARATIONS
  (void)scratch;
  (void)h;
  for (long i = start; i < stop; i += SC_W) {
    for (int l = 0; l < SC_W; l++) {
      long r = i + l < stop ? i + l : stop - 1;
      for (int j = 0; j < SC_NX; j++) y[j][l] = x[r * SC_NX + j];
      for (int j = 0; j < SC_NU; j++) U[j][l] = u[r * SC_NU + j];
    }
    for (int s = 0; s < SC_SUBSTEPS; s++) {
      SC_STEP_LINES
    }
    sc_observe(y, p, o, w); /* reads the model's states, the first of y */
    for (int l = 0; l < SC_W && i + l < stop; l++) {
      for (int j = 0; j < SC_NX; j++) out[(i + l) * (SC_NX + SC_NOBS) + j] = y[j][l];
      for (int j = 0; j < SC_NOBS; j++)
        out[(i + l) * (SC_NX + SC_NOBS) + SC_NX + j] = o[j][l];
    }
  }
  free(w);
  return 0;
}
