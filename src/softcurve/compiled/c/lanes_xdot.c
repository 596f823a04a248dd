/* The state derivative over lanes for CVODES's driver (lanes_derivative of softcurve.simulation.solvers):
 * SC_ENTRY(x, u, p, xdot, w) -> 0, every array lanes-interleaved (entry j of member l at
 * [j * SC_W + l]) and aligned to 64 bytes. Python writes before this file the lanes
 * prelude, the lanes function sc_xdot of the model's expressions, SC_ENTRY and
 * SC_GENERATED; without them the file compiles alone, on a stand-in (the test of the
 * shipped C files). */
#ifndef SC_GENERATED
#include "lanes_prelude.h"
#define SC_ENTRY softcurve_lanes_xdot
static void sc_xdot(const sc_v *in0, const sc_v *in1, const sc_v *in2, sc_v *out0,
                    sc_v *restrict w) {
    (void)w;
    out0[0] = in0[0] + in1[0] * in2[0];
}
#endif

__attribute__((visibility("default"))) int SC_ENTRY(
    const double* x, const double* u, const double* p, double* xdot, double* w) {
  sc_xdot((const sc_v*)x, (const sc_v*)u, (const sc_v*)p, (sc_v*)xdot, (sc_v*)w);
  return 0;
}
