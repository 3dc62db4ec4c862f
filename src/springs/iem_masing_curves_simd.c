/* The vectorised part of iem_nonlinear_springs' commit and stress for springs that keep their
 * curves (RK4 and the static solvers: iem_masing's masing_curve, docs/nonlinear.md section
 * 6a) written with AVX2 vectors four springs wide: iem_masing_fast's fast_stresses and
 * fast_commit in one pass that moves the state and the curves in place (no work columns
 * copied back), the reversals pushed stored from a lane mask; and fast_stresses. Both list
 * the springs whose move leaves its curve, ask for the top of their stacks as they go, and
 * take them through the state machine in C (iem_masing_simd.h) once the vector loop is done,
 * when the stacks have come. Every value is the same IEEE operations on the same operands as
 * the Fortran loops and the state machine (no fused multiply-add: this file is built with
 * -ffp-contract=off), so the results are bit for bit theirs (test_iem_masing checks it). Built without AVX2, the Fortran loops run instead (iem_masing_simd.f90's
 * masing_simd() is false: iem_masing_block_simd() is 0); the one-spring code here is the
 * vector loops' remainder. Fortran's column-major e_rev(depth, n), s_rev(depth, n). */
#include <stdint.h>

#include "iem_masing_simd.h"

#if defined(__AVX2__)
#include <immintrin.h>
#define IEM_SIMD 1
#else
#define IEM_SIMD 0
#endif

/* fast_stresses of spring i (constants pp[i], pn[i], pb[i]; committed strain and stress e_c[i],
 * s_c[i]; curves ps[i] .. hi[i]) at the strain e[i]: its stress on the curve the move starts
 * on in *sk, the move's direction in *mr (+-1, or 0), whether it pushes a reversal in *push;
 * 1 when the move ends on that curve or does not move, else 0 (*sk is then not its stress). */
static inline int stress1(int i, const double *e, const double *pp, const double *pn,
                          const double *pb, const double *e_c, const double *s_c,
                          const double *ps, const double *e0, const double *s0, const double *hk,
                          const double *lo, const double *hi, double *sk, double *mr, int *push) {
  double ek = e[i], ec = e_c[i], sc = s_c[i];
  int gt = ek > ec, lt = ek < ec;
  *mr = (gt ? 1.0 : 0.0) - (lt ? 1.0 : 0.0);
  *push = *mr != 0.0 && *mr == ps[i];
  double e0p = *push ? ec : e0[i], s0p = *push ? sc : s0[i];
  int skel = !*push && hk[i] == 1.0;
  double x = skel ? ek : 0.5 * (ek - e0p);
  double r = skel ? (ek >= 0.0 ? pp[i] : pn[i]) : pb[i];
  double y = x / (1.0 + __builtin_fabs(x) / r);
  *sk = ek == ec ? sc : (skel ? y : s0p + 2.0 * y);
  return (gt && ek < hi[i]) || (lt && ek > lo[i]) || ek == ec;
}

/* One spring of iem_curve_commit (its remainder): 1 when it is left to the state machine
 * (nothing changed but its work, + 0), else 0. */
static int curve_commit1(int i, int depth, const double *e, const double *pp, const double *pn,
                         const double *pb, const double *mp, const double *mn,
                         const double *hq, double *e_c, double *s_c, int32_t *dir,
                         int32_t *count, double *e_rev, double *s_rev, double *e_max_pos,
                         double *e_max_neg, double *ps, double *e0, double *s0, double *hk,
                         double *lo, double *hi, double *work, double *s) {
  double ek = e[i], ec = e_c[i], sc = s_c[i], e0k = e0[i];
  double hkk = hk[i], lok = lo[i], hik = hi[i], mpk = mp[i], mnk = mn[i], sk, mr;
  int32_t n0 = count[i];
  int push;
  int fast = stress1(i, e, pp, pn, pb, e_c, s_c, ps, e0, s0, hk, lo, hi, &sk, &mr, &push);
  /* fast_commit: the curves */
  int moved = ek != ec && fast, pc = fast && push;
  int branch = hkk == 0.5;
  double aim = branch ? e0k : -ek * (ek >= 0.0 ? mpk : mnk);
  double d = branch ? (aim > ek ? 1.0 : -1.0) : (ek > 0.0 ? -1.0 : 1.0);
  double b = -mr == d ? aim : ek;
  double pushed_end = branch ? e0k : -ec * (ec >= 0.0 ? mpk : mnk);
  double ps_new = (pc ? 1.0 : 0.0) <= (double)(depth - n0 - 1) ? -mr : 0.0;
  double hi_new = mr > 0.0 ? (pc ? pushed_end : hik) : (pc ? ec : (ps_new != 0.0 ? b : hik));
  double lo_new = mr < 0.0 ? (pc ? pushed_end : lok) : (pc ? ec : (ps_new != 0.0 ? b : lok));
  double dw = hq[i] * (sc + sk) * (ek - ec);
  work[i] = work[i] + (fast ? dw : 0.0);
  s[i] = sk;
  if (!moved) return !fast;
  hi[i] = hi_new;
  lo[i] = lo_new;
  ps[i] = ps_new;
  if (pc) {
    e0[i] = ec;
    s0[i] = sc;
    hk[i] = 0.5;
    e_rev[(int64_t)i * depth + n0] = ec;
    s_rev[(int64_t)i * depth + n0] = sc;
  }
  e_c[i] = ek;
  s_c[i] = sk;
  e_max_pos[i] = ek > e_max_pos[i] ? ek : e_max_pos[i];
  e_max_neg[i] = ek < e_max_neg[i] ? ek : e_max_neg[i];
  count[i] = n0 + pc;
  dir[i] = (int32_t)mr;
  return 0;
}

/* The springs i + k of the set bits k of others (a lane mask) listed in slow[ns ..] (numbered
 * from 1, in order), and the top of their stacks (R_n and below: the state machine's first
 * reads) asked for, a cache hint that changes no value; the new length of the list. */
static inline int list_slow(int others, int i, int depth, const int32_t *count,
                            const double *e_rev, const double *s_rev, int32_t *slow, int ns) {
  while (others) {
    int j = i + __builtin_ctz(others);
    int64_t top = (int64_t)j * depth + (count[j] > 1 ? count[j] - 1 : 0);
    __builtin_prefetch(e_rev + top, 0, 3);
    __builtin_prefetch(s_rev + top, 0, 3);
    slow[ns++] = j + 1;
    others &= others - 1;
  }
  return ns;
}

#if IEM_SIMD
/* stress1 of the four springs i .. i + 3: their stresses (returned), the lanes whose move ends
 * on its curve or does not move in *fast, the directions in *mr, the pushes in *push. */
static inline __m256d stress4(int i, const double *e, const double *pp, const double *pn,
                              const double *pb, const double *e_c, const double *s_c,
                              const double *ps, const double *e0, const double *s0,
                              const double *hk, const double *lo, const double *hi,
                              __m256d *fast, __m256d *mr, __m256d *push) {
  const __m256d one = _mm256_set1_pd(1.0), zero = _mm256_setzero_pd(),
                two = _mm256_set1_pd(2.0), half = _mm256_set1_pd(0.5),
                sign = _mm256_set1_pd(-0.0);
  __m256d ek = _mm256_loadu_pd(e + i), ec = _mm256_loadu_pd(e_c + i),
          sc = _mm256_loadu_pd(s_c + i);
  __m256d gt = _mm256_cmp_pd(ek, ec, _CMP_GT_OQ), lt = _mm256_cmp_pd(ek, ec, _CMP_LT_OQ),
          eq = _mm256_cmp_pd(ek, ec, _CMP_EQ_OQ);
  *mr = _mm256_sub_pd(_mm256_and_pd(gt, one), _mm256_and_pd(lt, one));
  *push = _mm256_and_pd(_mm256_cmp_pd(*mr, zero, _CMP_NEQ_OQ),
                        _mm256_cmp_pd(*mr, _mm256_loadu_pd(ps + i), _CMP_EQ_OQ));
  __m256d e0p = _mm256_blendv_pd(_mm256_loadu_pd(e0 + i), ec, *push),
          s0p = _mm256_blendv_pd(_mm256_loadu_pd(s0 + i), sc, *push);
  __m256d skel =
      _mm256_andnot_pd(*push, _mm256_cmp_pd(_mm256_loadu_pd(hk + i), one, _CMP_EQ_OQ));
  __m256d x = _mm256_blendv_pd(_mm256_mul_pd(half, _mm256_sub_pd(ek, e0p)), ek, skel);
  __m256d r = _mm256_blendv_pd(_mm256_loadu_pd(pb + i),
                               _mm256_blendv_pd(_mm256_loadu_pd(pn + i), _mm256_loadu_pd(pp + i),
                                                _mm256_cmp_pd(ek, zero, _CMP_GE_OQ)),
                               skel);
  __m256d y = _mm256_div_pd(x, _mm256_add_pd(one, _mm256_div_pd(_mm256_andnot_pd(sign, x), r)));
  *fast = _mm256_or_pd(
      _mm256_or_pd(_mm256_and_pd(gt, _mm256_cmp_pd(ek, _mm256_loadu_pd(hi + i), _CMP_LT_OQ)),
                   _mm256_and_pd(lt, _mm256_cmp_pd(ek, _mm256_loadu_pd(lo + i), _CMP_GT_OQ))),
      eq);
  return _mm256_blendv_pd(_mm256_blendv_pd(_mm256_add_pd(s0p, _mm256_mul_pd(two, y)), y, skel),
                          sc, eq);
}

/* The aim of a branch that starts at x: R_n (r) on a branch (the lanes of branch), the mirror
 * -x mp (x >= 0) or -x mn of x on the skeleton. */
static inline __m256d aim4(__m256d x, __m256d r, __m256d mp, __m256d mn, __m256d branch) {
  const __m256d zero = _mm256_setzero_pd(), sign = _mm256_set1_pd(-0.0);
  __m256d mirror = _mm256_xor_pd(
      _mm256_mul_pd(x, _mm256_blendv_pd(mn, mp, _mm256_cmp_pd(x, zero, _CMP_GE_OQ))), sign);
  return _mm256_blendv_pd(mirror, r, branch);
}
#endif

/* Spring i committed by the state machine to the strain e[i] (its stress in s[i]) and its
 * work increment (trapezoidal from the committed state; hq[i] half the energy coefficient)
 * added, as iem_nonlinear_springs' commit does it after masing_commit. */
static void commit_slow_work(int i, int depth, const double *e, const double *pp,
                             const double *pn, const double *pb, const double *mp,
                             const double *mn, const double *hq, double *e_c, double *s_c,
                             int32_t *dir, int32_t *count, double *e_rev, double *s_rev,
                             double *e_max_pos, double *e_max_neg, double *work, double *s) {
  double ec = e_c[i], sc = s_c[i];
  iem_masing_commit_slow(i, depth, e[i], pp, pn, pb, mp, mn, e_c, s_c, dir, count, e_rev, s_rev,
                         e_max_pos, e_max_neg, s);
  work[i] = work[i] + hq[i] * (sc + s[i]) * (e[i] - ec);
}

/* Commit n springs with their curves (constants pp[i] .. mn[i] as iem_masing_block's, hq[i]
 * half the energy coefficient) to the strains e, in place: the stresses s, the work
 * increments (trapezoidal from the committed state) added to work, the state and the curves
 * moved, bit for bit iem_masing_fast's fast_stresses and fast_commit with the reversals
 * pushed; the springs whose move leaves the curve it starts on take the state machine
 * (iem_masing_commit_slow, their work increment added after fast_commit's + 0, as
 * iem_nonlinear_springs adds it) and are listed in slow[0 .. *n_slow - 1] (numbered from 1,
 * in order): their curves are to be made again. */
void iem_curve_commit(int n, int depth, const double *e, const double *pp, const double *pn,
                      const double *pb, const double *mp, const double *mn, const double *hq,
                      double *e_c, double *s_c, int32_t *dir, int32_t *count, double *e_rev,
                      double *s_rev, double *e_max_pos, double *e_max_neg, double *ps,
                      double *e0, double *s0, double *hk, double *lo, double *hi, double *work,
                      double *s, int32_t *slow, int32_t *n_slow) {
  int i = 0, ns = 0;
#if IEM_SIMD
  const __m256d one = _mm256_set1_pd(1.0), mone = _mm256_set1_pd(-1.0),
                zero = _mm256_setzero_pd(), half = _mm256_set1_pd(0.5),
                sign = _mm256_set1_pd(-0.0);
  for (; i + 3 < n; i += 4) {
    __m256d fast, mr, push;
    __m256d sk = stress4(i, e, pp, pn, pb, e_c, s_c, ps, e0, s0, hk, lo, hi, &fast, &mr, &push);
    __m256d ek = _mm256_loadu_pd(e + i), ec = _mm256_loadu_pd(e_c + i),
            sc = _mm256_loadu_pd(s_c + i), psk = _mm256_loadu_pd(ps + i),
            e0k = _mm256_loadu_pd(e0 + i), s0k = _mm256_loadu_pd(s0 + i),
            hkk = _mm256_loadu_pd(hk + i), lok = _mm256_loadu_pd(lo + i),
            hik = _mm256_loadu_pd(hi + i), mpk = _mm256_loadu_pd(mp + i),
            mnk = _mm256_loadu_pd(mn + i);
    __m128i n0 = _mm_loadu_si128((const __m128i *)(count + i)),
            d0 = _mm_loadu_si128((const __m128i *)(dir + i));
    /* fast_commit: the curves */
    __m256d moved = _mm256_and_pd(_mm256_cmp_pd(ek, ec, _CMP_NEQ_UQ), fast),
            pc = _mm256_and_pd(fast, push);
    __m256d branch = _mm256_cmp_pd(hkk, half, _CMP_EQ_OQ);
    __m256d aim = aim4(ek, e0k, mpk, mnk, branch);
    __m256d d = _mm256_blendv_pd(
        _mm256_blendv_pd(one, mone, _mm256_cmp_pd(ek, zero, _CMP_GT_OQ)),
        _mm256_blendv_pd(mone, one, _mm256_cmp_pd(aim, ek, _CMP_GT_OQ)), branch);
    __m256d b = _mm256_blendv_pd(ek, aim, _mm256_cmp_pd(_mm256_xor_pd(mr, sign), d, _CMP_EQ_OQ));
    __m256d pushed_end = aim4(ec, e0k, mpk, mnk, branch);
    __m256d room = _mm256_cvtepi32_pd(
        _mm_sub_epi32(_mm_sub_epi32(_mm_set1_epi32(depth), n0), _mm_set1_epi32(1)));
    __m256d ps_new = _mm256_and_pd(_mm256_cmp_pd(_mm256_and_pd(pc, one), room, _CMP_LE_OQ),
                                   _mm256_xor_pd(mr, sign));
    __m256d has_end = _mm256_cmp_pd(ps_new, zero, _CMP_NEQ_OQ);
    __m256d up = _mm256_cmp_pd(mr, zero, _CMP_GT_OQ), dn = _mm256_cmp_pd(mr, zero, _CMP_LT_OQ);
    __m256d hi_new = _mm256_blendv_pd(
        _mm256_blendv_pd(_mm256_blendv_pd(hik, b, has_end), ec, pc),
        _mm256_blendv_pd(hik, pushed_end, pc), up);
    __m256d lo_new = _mm256_blendv_pd(
        _mm256_blendv_pd(_mm256_blendv_pd(lok, b, has_end), ec, pc),
        _mm256_blendv_pd(lok, pushed_end, pc), dn);
    _mm256_storeu_pd(hi + i, _mm256_blendv_pd(hik, hi_new, moved));
    _mm256_storeu_pd(lo + i, _mm256_blendv_pd(lok, lo_new, moved));
    _mm256_storeu_pd(ps + i, _mm256_blendv_pd(psk, ps_new, moved));
    _mm256_storeu_pd(e0 + i, _mm256_blendv_pd(e0k, ec, pc));
    _mm256_storeu_pd(s0 + i, _mm256_blendv_pd(s0k, sc, pc));
    _mm256_storeu_pd(hk + i, _mm256_blendv_pd(hkk, half, pc));
    /* the state */
    __m256d dw = _mm256_mul_pd(_mm256_mul_pd(_mm256_loadu_pd(hq + i), _mm256_add_pd(sc, sk)),
                               _mm256_sub_pd(ek, ec));
    _mm256_storeu_pd(work + i, _mm256_add_pd(_mm256_loadu_pd(work + i), _mm256_and_pd(fast, dw)));
    _mm256_storeu_pd(s + i, sk);
    _mm256_storeu_pd(e_c + i, _mm256_blendv_pd(ec, ek, moved));
    _mm256_storeu_pd(s_c + i, _mm256_blendv_pd(sc, sk, moved));
    __m256d emp = _mm256_loadu_pd(e_max_pos + i), emn = _mm256_loadu_pd(e_max_neg + i);
    _mm256_storeu_pd(e_max_pos + i, _mm256_blendv_pd(emp, _mm256_max_pd(ek, emp), moved));
    _mm256_storeu_pd(e_max_neg + i, _mm256_blendv_pd(emn, _mm256_min_pd(ek, emn), moved));
    __m128i movedi = _mm_sub_epi32(_mm_setzero_si128(),
                                   _mm256_cvtpd_epi32(_mm256_and_pd(moved, one)));
    __m128i pci = _mm256_cvtpd_epi32(_mm256_and_pd(pc, one));
    _mm_storeu_si128((__m128i *)(count + i),
                     _mm_blendv_epi8(n0, _mm_add_epi32(n0, pci), movedi));
    _mm_storeu_si128((__m128i *)(dir + i), _mm_blendv_epi8(d0, _mm256_cvtpd_epi32(mr), movedi));
    /* the reversals pushed: R_(n0 + 1) = the committed point before */
    int pushed = _mm256_movemask_pd(pc);
    if (pushed) {
      double ecl[4], scl[4];
      _mm256_storeu_pd(ecl, ec);
      _mm256_storeu_pd(scl, sc);
      while (pushed) {
        int j = __builtin_ctz(pushed), l = count[i + j];
        e_rev[(int64_t)(i + j) * depth + l - 1] = ecl[j];
        s_rev[(int64_t)(i + j) * depth + l - 1] = scl[j];
        pushed &= pushed - 1;
      }
    }
    /* the others take the state machine once the loop is done */
    ns = list_slow(_mm256_movemask_pd(fast) ^ 15, i, depth, count, e_rev, s_rev, slow, ns);
  }
#endif
  for (; i < n; i++)
    if (curve_commit1(i, depth, e, pp, pn, pb, mp, mn, hq, e_c, s_c, dir, count, e_rev, s_rev,
                      e_max_pos, e_max_neg, ps, e0, s0, hk, lo, hi, work, s))
      slow[ns++] = i + 1;
  for (int k = 0; k < ns; k++)
    commit_slow_work(slow[k] - 1, depth, e, pp, pn, pb, mp, mn, hq, e_c, s_c, dir, count, e_rev,
                     s_rev, e_max_pos, e_max_neg, work, s);
  *n_slow = ns;
}

/* The stresses of n springs with their curves (as iem_curve_commit's) at the strains e, the
 * state unchanged: bit for bit iem_masing_fast's fast_stresses, with the kind of each move
 * in mv (0 on its curve or none, 1 a push on to a new branch, 2 past the end of its curve),
 * and for those of kind 2 masing_trial's (iem_masing_walk_slow), listed in slow[0 ..
 * *n_slow - 1] (numbered from 1, in order). */
void iem_curve_stress(int n, int depth, const double *e, const double *pp, const double *pn,
                      const double *pb, const double *mp, const double *mn, const double *e_c,
                      const double *s_c, const int32_t *dir, const int32_t *count,
                      const double *e_rev, const double *s_rev, const double *ps,
                      const double *e0, const double *s0, const double *hk, const double *lo,
                      const double *hi, double *s, double *mv, int32_t *slow, int32_t *n_slow) {
  int i = 0, ns = 0;
  int32_t lv, pu; /* (the walk's level and push, not used) */
#if IEM_SIMD
  const __m256d one = _mm256_set1_pd(1.0), two = _mm256_set1_pd(2.0);
  for (; i + 3 < n; i += 4) {
    __m256d fast, mr, push;
    _mm256_storeu_pd(s + i, stress4(i, e, pp, pn, pb, e_c, s_c, ps, e0, s0, hk, lo, hi, &fast,
                                    &mr, &push));
    _mm256_storeu_pd(mv + i, _mm256_blendv_pd(two, _mm256_and_pd(push, one), fast));
    ns = list_slow(_mm256_movemask_pd(fast) ^ 15, i, depth, count, e_rev, s_rev, slow, ns);
  }
#endif
  for (; i < n; i++) {
    double mr;
    int push, fast = stress1(i, e, pp, pn, pb, e_c, s_c, ps, e0, s0, hk, lo, hi, &s[i], &mr,
                             &push);
    mv[i] = fast ? (push ? 1.0 : 0.0) : 2.0;
    if (!fast) slow[ns++] = i + 1;
  }
  for (int k = 0; k < ns; k++) {
    int j = slow[k] - 1;
    s[j] = iem_masing_walk_slow(j, depth, e[j], pp, pn, pb, mp, mn, e_c, s_c, dir, count, e_rev,
                                s_rev, &lv, &pu);
  }
  *n_slow = ns;
}
