/* The harness of the test program that softcurve.export_c writes (test_<prefix>.c):
 * run() calls one exported function on its sample inputs, prints every output and
 * compares it with the value the Python model gave, to TOLERANCE relative to the largest.
 * export_c writes before this file the include of <prefix>.h (CasADi's casadi_real and
 * casadi_int) and TOLERANCE, after it the samples and main(). Alone (the test of the
 * shipped C files), CasADi's default types stand in and nothing is compared. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#ifndef casadi_real
#define casadi_real double
#endif
#ifndef casadi_int
#define casadi_int long long int
#endif
#ifndef TOLERANCE
#define TOLERANCE 0.0
#endif

int run(const char *name,
        int (*work)(casadi_int *, casadi_int *, casadi_int *, casadi_int *),
        int (*eval)(const casadi_real **, casadi_real **, casadi_int *, casadi_real *, int),
        const casadi_real **inputs, int n_in, const casadi_real *expected, int n_out) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w, i;
  int status, failed = 0;
  double scale = 0.0;
  if (work(&sz_arg, &sz_res, &sz_iw, &sz_w)) return 1;
  const casadi_real **arg = calloc(sz_arg > 0 ? sz_arg : 1, sizeof *arg);
  casadi_real **res = calloc(sz_res > 0 ? sz_res : 1, sizeof *res);
  casadi_int *iw = malloc((sz_iw > 0 ? sz_iw : 1) * sizeof *iw);
  casadi_real *w = malloc((sz_w > 0 ? sz_w : 1) * sizeof *w);
  casadi_real *out = malloc(n_out * sizeof *out);
  for (i = 0; i < n_in; ++i) arg[i] = inputs[i];
  res[0] = out;
  status = eval(arg, res, iw, w, 0);
  for (i = 0; i < n_out; ++i) scale = fmax(scale, fabs(expected[i]));
  for (i = 0; i < n_out; ++i) {
    printf("%s %ld %.17g\n", name, (long)i, out[i]);
    if (!(fabs(out[i] - expected[i]) <= TOLERANCE * scale)) failed = 1;
  }
  if (status || failed) fprintf(stderr, "%s: status %d, mismatch %d\n", name, status, failed);
  free(arg); free(res); free(iw); free(w); free(out);
  return status || failed;
}
