/* The stepper's period over lanes (period_source of softcurve.simulation.stepper):
 * SC_SUBSTEPS steps of the method, then the observation, for rows start:stop of x
 * (N, SC_NX) and u (N, SC_NU) into out (N, SC_NX + SC_NOBS), all row-major float64, with p
 * and period shared; a last share shorter than a vector repeats its last member in the
 * unused lanes.
 *
 * Python writes before this file what it computes from the model and the method: the
 * lanes prelude and functions (sc_xdot, sc_observe, and sc_passes with sc_tangent_q,
 * sc_tangent_qd and sc_tangent_qdd where the step takes the exact Jacobian), the entry's
 * name
 * SC_ENTRY, the sizes (SC_NX states, the first SC_NQ of them the coordinates q whose
 * rates qd are the next SC_NQ, SC_NU, SC_NOBS, SC_SUBSTEPS; SC_WORK vectors of work of the
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
#define SC_NQ 0
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

/* The Rosenbrock steps' Newton matrix M = I - gh J of the states x = (q, qd, r) with
 * q' = qd, in loops: the same work for every member of a vector, whatever its matrix, and
 * code whose size does not grow with the states (a QR written out as straight-line code
 * grows as their cube: 250,000 instructions for the 72 states of eight segments with
 * creep, minutes of the compiler).
 *
 * The rows of q' = qd are known, (I, -gh I, 0): M k = b gives k_q = b_q + gh k_qd, and
 * the other SC_NR states solve S k_R = b_R - P b_q with P = M_Rq and
 * S = M_RR + gh (P, 0), by Householder QR without pivoting (Q is orthogonal whatever S).
 * a holds the rows R of M column by column (SC_NR entries per column): first the SC_NQ
 * columns of P, then the SC_NR of M_RR, which sc_newton_factor turns into S's factors. */
#define SC_NR (SC_NX - SC_NQ)

/* Householder QR of the SC_NR x SC_NR matrix s in place: R above the diagonal, its
 * diagonal in rdiag; reflection k's vector v_k on and below the diagonal of column k, and
 * beta[k] = 2 / (v_k' v_k) (0 where v_k = 0: a zero column, a singular matrix whose
 * solve gives non-finite states, which the stepper reports). */
static inline void sc_qr_factor(sc_v *restrict s, sc_v *restrict beta, sc_v *restrict rdiag) {
  const sc_v zero = sc_broadcast(0.0), two = sc_broadcast(2.0);
  for (int k = 0; k < SC_NR; k++) {
    sc_v *sk = s + k * SC_NR;
    sc_v below = zero;
    for (int i = k + 1; i < SC_NR; i++) below += sk[i] * sk[i];
    /* the sign opposite the diagonal's: v_k[k] = s_kk - alpha without cancellation */
    const sc_v alpha = -sc_copysign(sc_sqrt(sk[k] * sk[k] + below), sk[k]);
    sk[k] -= alpha;
    const sc_v vv = sk[k] * sk[k] + below;
    beta[k] = sc_select(vv > zero, two / vv, zero);
    rdiag[k] = alpha;
    for (int c = k + 1; c < SC_NR; c++) {
      sc_v *sc = s + c * SC_NR;
      sc_v t = zero;
      for (int i = k; i < SC_NR; i++) t += sk[i] * sc[i];
      t *= beta[k];
      for (int i = k; i < SC_NR; i++) sc[i] -= t * sk[i];
    }
  }
}

/* x = S^-1 b from sc_qr_factor's factors: Q' b by the reflections, then R's back
 * substitution. */
static inline void sc_qr_solve(const sc_v *restrict s, const sc_v *restrict beta,
                               const sc_v *restrict rdiag, const sc_v *restrict b,
                               sc_v *restrict x) {
  for (int j = 0; j < SC_NR; j++) x[j] = b[j];
  for (int k = 0; k < SC_NR; k++) {
    const sc_v *sk = s + k * SC_NR;
    sc_v t = sc_broadcast(0.0);
    for (int i = k; i < SC_NR; i++) t += sk[i] * x[i];
    t *= beta[k];
    for (int i = k; i < SC_NR; i++) x[i] -= t * sk[i];
  }
  for (int k = SC_NR - 1; k >= 0; k--) {
    sc_v t = x[k];
    for (int c = k + 1; c < SC_NR; c++) t -= s[c * SC_NR + k] * x[c];
    x[k] = t / rdiag[k];
  }
}

/* a holds (P, M_RR): S = M_RR + gh (P, 0), factored in place. */
static inline void sc_newton_factor(sc_v *restrict a, sc_v gh, sc_v *restrict beta,
                                    sc_v *restrict rdiag) {
  sc_v *s = a + SC_NQ * SC_NR;
  for (int j = 0; j < SC_NQ; j++)
    for (int i = 0; i < SC_NR; i++) s[j * SC_NR + i] += gh * a[j * SC_NR + i];
  sc_qr_factor(s, beta, rdiag);
}

/* k = M^-1 b from sc_newton_factor's a. */
static inline void sc_newton_solve(const sc_v *restrict a, sc_v gh, const sc_v *restrict beta,
                                   const sc_v *restrict rdiag, const sc_v *restrict b,
                                   sc_v *restrict k) {
  sc_v r[SC_NR];
  for (int i = 0; i < SC_NR; i++) r[i] = b[SC_NQ + i];
  for (int j = 0; j < SC_NQ; j++)
    for (int i = 0; i < SC_NR; i++) r[i] -= a[j * SC_NR + i] * b[j];
  sc_qr_solve(a + SC_NQ * SC_NR, beta, rdiag, r, k + SC_NQ);
  for (int j = 0; j < SC_NQ; j++) k[j] = b[j] + gh * k[SC_NQ + j];
}

/* The exact Jacobian's solve (a step writer's choice): the rows of qdd in J are
 * D^-1 G, with D the SC_NQ x SC_NQ mass matrix, symmetric positive definite. d, column
 * major, becomes its Cholesky factor L (lower triangle, L L' = D); the loops are those of
 * any Cholesky factorization, on vectors of members. A matrix that is not positive
 * definite gives non-finite entries, whose states the stepper reports. */
static inline void sc_cholesky(sc_v *restrict d) {
  for (int k = 0; k < SC_NQ; k++) {
    sc_v *dk = d + k * SC_NQ;
    sc_v t = dk[k];
    for (int j = 0; j < k; j++) t -= d[j * SC_NQ + k] * d[j * SC_NQ + k];
    dk[k] = sc_sqrt(t);
    for (int i = k + 1; i < SC_NQ; i++) {
      sc_v u = dk[i];
      for (int j = 0; j < k; j++) u -= d[j * SC_NQ + i] * d[j * SC_NQ + k];
      dk[i] = u / dk[k];
    }
  }
}

/* x = D^-1 b from sc_cholesky's factor l: L z = b forward, L' x = z back. */
static inline void sc_cholesky_solve(const sc_v *restrict l, const sc_v *restrict b,
                                     sc_v *restrict x) {
  for (int i = 0; i < SC_NQ; i++) {
    sc_v t = b[i];
    for (int j = 0; j < i; j++) t -= l[j * SC_NQ + i] * x[j];
    x[i] = t / l[i * SC_NQ + i];
  }
  for (int i = SC_NQ - 1; i >= 0; i--) {
    sc_v t = x[i];
    for (int j = i + 1; j < SC_NQ; j++) t -= l[i * SC_NQ + j] * x[j];
    x[i] = t / l[i * SC_NQ + i];
  }
}

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
