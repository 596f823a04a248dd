/* What every lanes function needs, once per source (softcurve.compiled.lanes_prelude): the vector
 * type sc_v of SC_W doubles and its mask type, broadcast, select, and every elementary
 * function lane by lane (sc_sin, ...). Python defines SC_W (lanes per vector) and, for
 * glibc's vector math library (libmvec: sine, cosine and hyperbolic tangent of four
 * doubles, accurate to 4 ulp, tanh since glibc 2.35), SC_VECTOR_MATH; its functions are
 * taken where compiled for AVX2 on x86-64, each lane's C library call elsewhere. */
#ifndef SOFTCURVE_LANES_PRELUDE_H
#define SOFTCURVE_LANES_PRELUDE_H

#include <math.h>

/* Vectors are passed between static functions of one translation unit only (and to
 * libmvec only where compiled for AVX2): GCC's note that their ABI differs without AVX
 * concerns calls across units, which there are none of. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

#ifndef SC_W
#define SC_W 4
#endif

typedef double sc_v __attribute__((vector_size(8 * SC_W)));
typedef long long sc_m __attribute__((vector_size(8 * SC_W)));

static inline sc_v sc_broadcast(double s) {
  sc_v r; for (int l = 0; l < SC_W; l++) r[l] = s; return r;
}

static inline sc_v sc_select(sc_m m, sc_v a, sc_v b) {
  return (sc_v)(((sc_m)a & m) | ((sc_m)b & ~m));
}

/* The C library's function of one or two arguments, lane by lane. */
#define SC_LANEWISE(name) \
  static inline sc_v sc_##name(sc_v x) { \
    sc_v r; for (int l = 0; l < SC_W; l++) r[l] = name(x[l]); return r; \
  }
#define SC_LANEWISE2(name) \
  static inline sc_v sc_##name(sc_v x, sc_v y) { \
    sc_v r; for (int l = 0; l < SC_W; l++) r[l] = name(x[l], y[l]); return r; \
  }

SC_LANEWISE(acos)
SC_LANEWISE(acosh)
SC_LANEWISE(asin)
SC_LANEWISE(asinh)
SC_LANEWISE(atan)
SC_LANEWISE(atanh)
SC_LANEWISE(ceil)
SC_LANEWISE(cosh)
SC_LANEWISE(erf)
SC_LANEWISE(exp)
SC_LANEWISE(expm1)
SC_LANEWISE(fabs)
SC_LANEWISE(floor)
SC_LANEWISE(log)
SC_LANEWISE(log1p)
SC_LANEWISE(sinh)
SC_LANEWISE(sqrt)
SC_LANEWISE(tan)

#if defined(SC_VECTOR_MATH) && SC_W == 4 && defined(__AVX2__) && defined(__x86_64__)
sc_v _ZGVdN4v_sin(sc_v);
sc_v _ZGVdN4v_cos(sc_v);
sc_v _ZGVdN4v_tanh(sc_v);
#define sc_sin _ZGVdN4v_sin
#define sc_cos _ZGVdN4v_cos
#define sc_tanh _ZGVdN4v_tanh
#else
SC_LANEWISE(sin)
SC_LANEWISE(cos)
SC_LANEWISE(tanh)
#endif

SC_LANEWISE2(atan2)
SC_LANEWISE2(copysign)
SC_LANEWISE2(fmax)
SC_LANEWISE2(fmin)
SC_LANEWISE2(fmod)
SC_LANEWISE2(hypot)
SC_LANEWISE2(pow)

#endif
