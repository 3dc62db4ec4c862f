/* The node passes of iem_node_pass (RK4's stage updates, velocity Verlet's kicks and drift)
 * written with AVX2 vectors a node wide: a node's state (u1, u2, v1, v2) is one 4-wide
 * vector, its force or acceleration a 2-wide one, two nodes' accelerations one 4-wide
 * division. Each value is formed by the same operations as iem_node_pass's Fortran loops
 * form it when gfortran contracts a product and a sum into one fused multiply-add (its
 * default with FMA hardware): a = -fma(alpha m, v, f)/m, y + w k = fma(w, k, y); so the
 * results are bit for bit the Fortran loops' (test_iem_node_pass checks it). gfortran
 * vectorises those loops across nodes instead, with many shuffles and single-value stores,
 * about twice as slow (docs/architecture.md, "The node passes").
 *
 * Built without AVX2 and FMA, the passes here do nothing and iem_node_pass_simd() is 0: the
 * Fortran loops run instead. n nodes, Fortran's column-major arrays y(4, n), f(2, n). */
#include <stdint.h>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#define IEM_SIMD 1
#else
#define IEM_SIMD 0
#endif

/* Whether the passes here are built (1) or the Fortran loops run (0). */
int iem_node_pass_simd(void) { return IEM_SIMD; }

#if IEM_SIMD
/* The rates k = (v, a) of two nodes l, l+1 from their states s0, s1 (u, v), their forces
 * f(2, l:l+1) at fp and their masses at mp: a = -fma(alpha m, v, f)/m. */
static inline void rates2(__m256d s0, __m256d s1, const double *fp, const double *mp,
                          __m256d al, __m256d *k0, __m256d *k1) {
  const __m256d sign = _mm256_set1_pd(-0.0);
  __m256d m = _mm256_set_pd(mp[1], mp[1], mp[0], mp[0]);
  __m256d v = _mm256_permute2f128_pd(s0, s1, 0x31);
  __m256d a = _mm256_xor_pd(
      _mm256_div_pd(_mm256_fmadd_pd(_mm256_mul_pd(al, m), v, _mm256_loadu_pd(fp)), m), sign);
  *k0 = _mm256_permute2f128_pd(v, a, 0x20);
  *k1 = _mm256_permute2f128_pd(v, a, 0x31);
}

/* rates2 for one node. */
static inline __m256d rates1(__m256d s, const double *fp, double m, double alpha) {
  __m128d mm = _mm_set1_pd(m);
  __m128d v = _mm256_extractf128_pd(s, 1);
  __m128d a = _mm_xor_pd(
      _mm_div_pd(_mm_fmadd_pd(_mm_set1_pd(alpha * m), v, _mm_loadu_pd(fp)), mm),
      _mm_set1_pd(-0.0));
  return _mm256_insertf128_pd(_mm256_castpd128_pd256(v), a, 1);
}
#endif

#if IEM_SIMD
/* One RK4 stage's pass over n nodes: the rates k at the states in state (and the forces f,
 * cleared), ynew = sum + wdt k, ys = base + h k (ys may be state: each node's values are read
 * before they are written). */
static void stage_pass(int n, double alpha, const double *mass, double wdt, double h,
                       const double *state, const double *sum, const double *base, double *f,
                       double *ynew, double *ys) {
  const __m256d w4 = _mm256_set1_pd(wdt), h4 = _mm256_set1_pd(h), al = _mm256_set1_pd(alpha);
  int l = 0;
  for (; l + 1 < n; l += 2) {
    __m256d k0, k1;
    rates2(_mm256_loadu_pd(state + 4 * l), _mm256_loadu_pd(state + 4 * l + 4), f + 2 * l,
           mass + l, al, &k0, &k1);
    _mm256_storeu_pd(f + 2 * l, _mm256_setzero_pd());
    _mm256_storeu_pd(ynew + 4 * l, _mm256_fmadd_pd(w4, k0, _mm256_loadu_pd(sum + 4 * l)));
    _mm256_storeu_pd(ynew + 4 * l + 4, _mm256_fmadd_pd(w4, k1, _mm256_loadu_pd(sum + 4 * l + 4)));
    _mm256_storeu_pd(ys + 4 * l, _mm256_fmadd_pd(h4, k0, _mm256_loadu_pd(base + 4 * l)));
    _mm256_storeu_pd(ys + 4 * l + 4, _mm256_fmadd_pd(h4, k1, _mm256_loadu_pd(base + 4 * l + 4)));
  }
  for (; l < n; l++) {
    __m256d k = rates1(_mm256_loadu_pd(state + 4 * l), f + 2 * l, mass[l], alpha);
    _mm_storeu_pd(f + 2 * l, _mm_setzero_pd());
    _mm256_storeu_pd(ynew + 4 * l, _mm256_fmadd_pd(w4, k, _mm256_loadu_pd(sum + 4 * l)));
    _mm256_storeu_pd(ys + 4 * l, _mm256_fmadd_pd(h4, k, _mm256_loadu_pd(base + 4 * l)));
  }
}
#endif

/* RK4 stage 1 (iem_node_pass's rk4_first_pass): ynew = y + wdt k, ys = y + h k, f cleared. */
void iem_rk4_first_pass(int n, double alpha, const double *mass, double wdt, double h,
                        const double *y, double *f, double *ynew, double *ys) {
#if IEM_SIMD
  stage_pass(n, alpha, mass, wdt, h, y, y, y, f, ynew, ys);
#else
  (void)n; (void)alpha; (void)mass; (void)wdt; (void)h; (void)y; (void)f; (void)ynew; (void)ys;
#endif
}

/* RK4 stage 2 or 3 (rk4_mid_pass): ynew += wdt k, ys = y0 + h k, f cleared. */
void iem_rk4_mid_pass(int n, double alpha, const double *mass, double wdt, double h,
                      const double *y0, double *f, double *ynew, double *ys) {
#if IEM_SIMD
  stage_pass(n, alpha, mass, wdt, h, ys, ynew, y0, f, ynew, ys);
#else
  (void)n; (void)alpha; (void)mass; (void)wdt; (void)h; (void)y0; (void)f; (void)ynew; (void)ys;
#endif
}

/* RK4 stage 4 (rk4_last_pass): ynew += wdt k, f cleared, and in *total a sum of the new
 * values (finite exactly when they all are, barring overflow; not the Fortran loop's bits). */
void iem_rk4_last_pass(int n, double alpha, const double *mass, double wdt, const double *ys,
                      double *f, double *ynew, double *total) {
#if IEM_SIMD
  const __m256d w4 = _mm256_set1_pd(wdt), al = _mm256_set1_pd(alpha);
  __m256d t0 = _mm256_setzero_pd(), t1 = _mm256_setzero_pd();
  int l = 0;
  for (; l + 1 < n; l += 2) {
    __m256d k0, k1;
    rates2(_mm256_loadu_pd(ys + 4 * l), _mm256_loadu_pd(ys + 4 * l + 4), f + 2 * l, mass + l,
           al, &k0, &k1);
    _mm256_storeu_pd(f + 2 * l, _mm256_setzero_pd());
    __m256d n0 = _mm256_fmadd_pd(w4, k0, _mm256_loadu_pd(ynew + 4 * l));
    __m256d n1 = _mm256_fmadd_pd(w4, k1, _mm256_loadu_pd(ynew + 4 * l + 4));
    _mm256_storeu_pd(ynew + 4 * l, n0);
    _mm256_storeu_pd(ynew + 4 * l + 4, n1);
    t0 = _mm256_add_pd(t0, n0);
    t1 = _mm256_add_pd(t1, n1);
  }
  for (; l < n; l++) {
    __m256d k = rates1(_mm256_loadu_pd(ys + 4 * l), f + 2 * l, mass[l], alpha);
    _mm_storeu_pd(f + 2 * l, _mm_setzero_pd());
    __m256d n0 = _mm256_fmadd_pd(w4, k, _mm256_loadu_pd(ynew + 4 * l));
    _mm256_storeu_pd(ynew + 4 * l, n0);
    t0 = _mm256_add_pd(t0, n0);
  }
  double part[4];
  _mm256_storeu_pd(part, _mm256_add_pd(t0, t1));
  *total = (part[0] + part[1]) + (part[2] + part[3]);
#else
  (void)n; (void)alpha; (void)mass; (void)wdt; (void)ys; (void)f; (void)ynew; (void)total;
#endif
}

#if IEM_SIMD
/* The guarded half kick of two nodes l, l+1 (states s0, s1; rates at fa = fa + 2 l): their
 * half-step velocities w, accelerations a = -fma(alpha m, w, f)/m, kicked velocities
 * v = fma(h, a, w), and pair, all bits set in both lanes of a node whose two new velocities
 * are finite. */
static inline void kick2(__m256d s0, __m256d s1, const double *mp, const double *fa,
                         __m256d al, __m256d h4, __m256d *w, __m256d *a, __m256d *v,
                         __m256d *pair) {
  const __m256d sign = _mm256_set1_pd(-0.0);
  __m256d m = _mm256_set_pd(mp[1], mp[1], mp[0], mp[0]);
  *w = _mm256_permute2f128_pd(s0, s1, 0x31);
  *a = _mm256_xor_pd(_mm256_div_pd(_mm256_fmadd_pd(_mm256_mul_pd(al, m), *w,
                                                   _mm256_loadu_pd(fa)), m), sign);
  *v = _mm256_fmadd_pd(h4, *a, *w);
  /* v - v is 0 for a finite v, NaN otherwise: both of a node finite or neither kept */
  __m256d fin = _mm256_cmp_pd(_mm256_sub_pd(*v, *v), _mm256_setzero_pd(), _CMP_EQ_OQ);
  *pair = _mm256_and_pd(fin, _mm256_permute_pd(fin, 0x5));
}

/* kick2 for one node l (velocities w from y + 4 l + 2, rates at fa = fa + 2 l). */
static inline void kick1(const double *yl, double m, const double *fa, double alpha, double h,
                         __m128d *w, __m128d *a, __m128d *v, __m128d *pair) {
  *w = _mm_loadu_pd(yl + 2);
  *a = _mm_xor_pd(_mm_div_pd(_mm_fmadd_pd(_mm_set1_pd(alpha * m), *w, _mm_loadu_pd(fa)),
                             _mm_set1_pd(m)), _mm_set1_pd(-0.0));
  *v = _mm_fmadd_pd(_mm_set1_pd(h), *a, *w);
  __m128d fin = _mm_cmp_pd(_mm_sub_pd(*v, *v), _mm_setzero_pd(), _CMP_EQ_OQ);
  *pair = _mm_and_pd(fin, _mm_permute_pd(fin, 0x1));
}

/* The first bad node of a pair l, l+1 from pair's mask (first: 0 until one is found). */
static inline int first_of2(int first, int l, __m256d pair) {
  int ok = _mm256_movemask_pd(pair);
  if (ok != 0xF && first == 0) first = (ok & 0x3) != 0x3 ? l + 1 : l + 2;
  return first;
}
#endif

/* Velocity Verlet's accelerations in place with the guarded kick (accelerations_in_place
 * with kick): a = -fma(alpha m, v, fa)/m, v_new = v + h a; fa = a where both new velocities
 * are finite, else the velocities before the kick; *first_bad: the first node (from 1) where
 * they are not, 0 if none. */
void iem_kick_in_place(int n, double alpha, const double *mass, double h, double *y, double *fa,
                      int *first_bad) {
#if IEM_SIMD
  const __m256d h4 = _mm256_set1_pd(h), al = _mm256_set1_pd(alpha);
  int l = 0, first = 0;
  for (; l + 1 < n; l += 2) {
    __m256d s0 = _mm256_loadu_pd(y + 4 * l), s1 = _mm256_loadu_pd(y + 4 * l + 4);
    __m256d w, a, v, pair;
    kick2(s0, s1, mass + l, fa + 2 * l, al, h4, &w, &a, &v, &pair);
    _mm256_storeu_pd(fa + 2 * l, _mm256_blendv_pd(w, a, pair));
    _mm256_storeu_pd(y + 4 * l, _mm256_permute2f128_pd(s0, v, 0x20));
    _mm256_storeu_pd(y + 4 * l + 4, _mm256_permute2f128_pd(s1, v, 0x30));
    first = first_of2(first, l, pair);
  }
  for (; l < n; l++) {
    __m128d w, a, v, pair;
    kick1(y + 4 * l, mass[l], fa + 2 * l, alpha, h, &w, &a, &v, &pair);
    _mm_storeu_pd(fa + 2 * l, _mm_blendv_pd(w, a, pair));
    _mm_storeu_pd(y + 4 * l + 2, v);
    if (_mm_movemask_pd(pair) != 0x3 && first == 0) first = l + 1;
  }
  *first_bad = first;
#else
  (void)n; (void)alpha; (void)mass; (void)h; (void)y; (void)fa; (void)first_bad;
#endif
}

/* accelerations_in_place with kick and drift: the kick of iem_kick_in_place and, at a node
 * whose kicked velocities are both finite, the next step's first kick and drift in the same
 * pass (v += h a, u += dt v, as iem_kick_drift) and the rates cleared there; elsewhere what
 * the guarded kick alone leaves (u, the kicked v; the rates the velocities before it). */
void iem_kick_ahead(int n, double alpha, const double *mass, double h, double dt, double *y,
                    double *fa, int *first_bad) {
#if IEM_SIMD
  const __m256d h4 = _mm256_set1_pd(h), d4 = _mm256_set1_pd(dt), al = _mm256_set1_pd(alpha);
  int l = 0, first = 0;
  for (; l + 1 < n; l += 2) {
    __m256d s0 = _mm256_loadu_pd(y + 4 * l), s1 = _mm256_loadu_pd(y + 4 * l + 4);
    __m256d u = _mm256_permute2f128_pd(s0, s1, 0x20), w, a, v, pair;
    kick2(s0, s1, mass + l, fa + 2 * l, al, h4, &w, &a, &v, &pair);
    __m256d v2 = _mm256_fmadd_pd(h4, a, v);
    __m256d u2 = _mm256_fmadd_pd(d4, v2, u);
    v = _mm256_blendv_pd(v, v2, pair);
    u = _mm256_blendv_pd(u, u2, pair);
    _mm256_storeu_pd(fa + 2 * l, _mm256_andnot_pd(pair, w));
    _mm256_storeu_pd(y + 4 * l, _mm256_permute2f128_pd(u, v, 0x20));
    _mm256_storeu_pd(y + 4 * l + 4, _mm256_permute2f128_pd(u, v, 0x31));
    first = first_of2(first, l, pair);
  }
  for (; l < n; l++) {
    __m128d u = _mm_loadu_pd(y + 4 * l), w, a, v, pair;
    kick1(y + 4 * l, mass[l], fa + 2 * l, alpha, h, &w, &a, &v, &pair);
    __m128d v2 = _mm_fmadd_pd(_mm_set1_pd(h), a, v);
    __m128d u2 = _mm_fmadd_pd(_mm_set1_pd(dt), v2, u);
    _mm_storeu_pd(fa + 2 * l, _mm_andnot_pd(pair, w));
    _mm_storeu_pd(y + 4 * l, _mm_blendv_pd(u, u2, pair));
    _mm_storeu_pd(y + 4 * l + 2, _mm_blendv_pd(v, v2, pair));
    if (_mm_movemask_pd(pair) != 0x3 && first == 0) first = l + 1;
  }
  *first_bad = first;
#else
  (void)n; (void)alpha; (void)mass; (void)h; (void)dt; (void)y; (void)fa; (void)first_bad;
#endif
}

/* Velocity Verlet's first kick and drift (kick_drift): v = v + h acc, then u = u + dt v;
 * with clear, acc zeroed. */
void iem_kick_drift(int n, double h, double dt, double *acc, double *y, int clear) {
#if IEM_SIMD
  const __m256d h4 = _mm256_set1_pd(h), d4 = _mm256_set1_pd(dt);
  int l = 0;
  for (; l + 1 < n; l += 2) {
    __m256d s0 = _mm256_loadu_pd(y + 4 * l), s1 = _mm256_loadu_pd(y + 4 * l + 4);
    __m256d u = _mm256_permute2f128_pd(s0, s1, 0x20);
    __m256d v = _mm256_fmadd_pd(h4, _mm256_loadu_pd(acc + 2 * l),
                                _mm256_permute2f128_pd(s0, s1, 0x31));
    u = _mm256_fmadd_pd(d4, v, u);
    if (clear) _mm256_storeu_pd(acc + 2 * l, _mm256_setzero_pd());
    _mm256_storeu_pd(y + 4 * l, _mm256_permute2f128_pd(u, v, 0x20));
    _mm256_storeu_pd(y + 4 * l + 4, _mm256_permute2f128_pd(u, v, 0x31));
  }
  for (; l < n; l++) {
    __m128d v = _mm_fmadd_pd(_mm_set1_pd(h), _mm_loadu_pd(acc + 2 * l),
                             _mm_loadu_pd(y + 4 * l + 2));
    __m128d u = _mm_fmadd_pd(_mm_set1_pd(dt), v, _mm_loadu_pd(y + 4 * l));
    if (clear) _mm_storeu_pd(acc + 2 * l, _mm_setzero_pd());
    _mm_storeu_pd(y + 4 * l, u);
    _mm_storeu_pd(y + 4 * l + 2, v);
  }
#else
  (void)n; (void)h; (void)dt; (void)acc; (void)y; (void)clear;
#endif
}
