/* The branch-free part of iem_masing_fast's masing_springs (the Masing law of many springs
 * read from the top of their stacks, for runs that commit every evaluation) written with
 * AVX2 vectors four springs wide: each spring's level, move and stress as the first loop of
 * masing_springs forms them, one more step of the state machine's walk for the moves past
 * the end of their curve, with accept the commit of the moves that end on a curve so (and
 * the reversals they push), and the state machine's walk and commit for the others. Every
 * value is the same IEEE operations on the same operands as the Fortran loops and
 * iem_masing's masing_walk (no fused multiply-add: this file is built with
 * -ffp-contract=off), so the results are bit for bit theirs (test_iem_masing checks it).
 * gfortran vectorises masing_springs' loops with masked loads and stores, emulated gathers
 * and conversions between its integer and real selections, and leaves the pushes and the
 * choice of the slow springs to branchy scalar loops (docs/nonlinear.md, section 6a).
 *
 * Built without AVX2, iem_masing_block_simd() is 0 and the Fortran loops run instead (the
 * block here would take the springs one by one). Fortran's column-major e_rev(depth, n),
 * s_rev(depth, n). */
#include <stdint.h>

#include "iem_cache_hint.h"
#include "iem_masing_simd.h"

#if defined(__AVX2__)
#include <immintrin.h>
#define IEM_SIMD 1
#else
#define IEM_SIMD 0
#endif

/* How many springs ahead iem_masing_block asks for the stacks (docs/nonlinear.md, 6a). */
enum { stack_ahead = 32 };

/* Whether the block here is built (1) or the Fortran loops run (0). */
int iem_masing_block_simd(void) { return IEM_SIMD; }

/* One spring of the block (the vector loop's remainder), as the vector loop does it: 1 when
 * it is left to the state machine, else 0. */
static int spring1(int i, int depth, int accept, const double *e, const double *pp,
                   const double *pn, const double *pb, const double *mp, const double *mn,
                   double *e_c, double *s_c, int32_t *dir, int32_t *count, double *e_rev,
                   double *s_rev, double *e_max_pos, double *e_max_neg, double *s,
                   double *e_was, double *s_was) {
  double ek = e[i], ec = e_c[i], sc = s_c[i];
  int32_t n0 = count[i], d0 = dir[i];
  double *er = e_rev + (int64_t)i * depth, *sr = s_rev + (int64_t)i * depth;
  double et = er[(n0 > 1 ? n0 : 1) - 1], st = sr[(n0 > 1 ? n0 : 1) - 1];
  double eb = er[(n0 - 1 > 1 ? n0 - 1 : 1) - 1];
  int32_t m = (ek > ec) - (ek < ec);
  int32_t push = (d0 != 0 && m == -d0 && n0 < depth);
  int32_t lev = n0 + push;
  double e0 = push ? ec : et, s0 = push ? sc : st;
  double mirror = -e0 * (e0 >= 0.0 ? mp[i] : mn[i]);
  double aim = lev >= 2 ? (push ? et : eb) : mirror;
  double d = lev >= 2 ? (aim > e0 ? 1.0 : -1.0) : (e0 > 0.0 ? -1.0 : 1.0);
  int32_t shrt = ((double)m == d) ? (d * (ek - aim) < 0.0) : (d * (ek - e0) > 0.0);
  int32_t fast = (ek == ec) || (m != 0 && (lev == 0 || shrt));
  double x = lev == 0 ? ek : 0.5 * (ek - e0);
  double r = lev == 0 ? (ek >= 0.0 ? pp[i] : pn[i]) : pb[i];
  double y = x / (1.0 + __builtin_fabs(x) / r);
  s[i] = m == 0 ? sc : (lev == 0 ? y : s0 + 2.0 * y);
  e_was[i] = ec;
  s_was[i] = sc;
  if (!fast) return 1;
  if (accept && m != 0) {
    count[i] = lev;
    dir[i] = m;
    e_c[i] = ek;
    s_c[i] = s[i];
    e_max_pos[i] = ek > e_max_pos[i] ? ek : e_max_pos[i];
    e_max_neg[i] = ek < e_max_neg[i] ? ek : e_max_neg[i];
    if (push) {
      er[lev - 1] = ec;
      sr[lev - 1] = sc;
    }
  }
  return 0;
}

/* masing_walk of spring i (Emax = 1, constants pp[i] .. mn[i]) from its committed state to
 * the strain ek, without the tangent: the stress there, the level reached and whether the
 * committed point is pushed. Bit for bit iem_masing's masing_walk (the same operations in
 * the same order); an unchanged strain keeps the committed stress. */
double iem_masing_walk_slow(int i, int depth, double ek, const double *pp, const double *pn,
                            const double *pb, const double *mp, const double *mn,
                            const double *e_c, const double *s_c, const int32_t *dir,
                            const int32_t *count, const double *e_rev, const double *s_rev,
                            int32_t *level_out, int32_t *push_out) {
  double ec = e_c[i], sc = s_c[i], e0 = 0.0, s0 = 0.0, aim, st;
  int32_t n0 = count[i], d0 = dir[i], m, push, level, d = 0;
  const double *er = e_rev + (int64_t)i * depth, *sr = s_rev + (int64_t)i * depth;
  m = (ek > ec) - (ek < ec);
  /* a reversal is recorded only while the stack has room */
  push = d0 != 0 && m == -d0 && n0 < depth;
  level = n0 + push;
/* start e0, s0, direction d and aim of the branch of level k (k = n0 + 1: the pushed one) */
#define LEVEL_PARAMS(k)                                                                    \
  do {                                                                                     \
    if (push && (k) == n0 + 1) {                                                           \
      e0 = ec;                                                                             \
      s0 = sc;                                                                             \
    } else {                                                                               \
      e0 = er[(k) - 1];                                                                    \
      s0 = sr[(k) - 1];                                                                    \
    }                                                                                      \
    if ((k) >= 2) {                                                                        \
      aim = er[(k) - 2];                                                                   \
      d = aim > e0 ? 1 : -1;                                                               \
    } else {                                                                               \
      aim = -e0 * (e0 >= 0.0 ? mp[i] : mn[i]);                                             \
      d = e0 > 0.0 ? -1 : 1;                                                               \
    }                                                                                      \
  } while (0)
  if (m != 0) {
    while (level > 0) {
      LEVEL_PARAMS(level);
      if (m == d) {
        /* forward: at or past its aim the branch has rejoined the curve it interrupted */
        if ((double)d * (ek - aim) < 0.0) break;
        level = level - 2 > 0 ? level - 2 : 0;
      } else {
        /* backward on the innermost branch (overflow retrace): past its start */
        if ((double)d * (ek - e0) > 0.0) break;
        level = level - 1;
      }
    }
  }
  if (level == 0) {
    double r = ek >= 0.0 ? pp[i] : pn[i];
    st = ek / (1.0 + __builtin_fabs(ek) / r);
  } else if (m == 0 && level == n0) {
    st = sc;
  } else {
    LEVEL_PARAMS(level);
    double x = 0.5 * (ek - e0);
    st = s0 + 2.0 * (x / (1.0 + __builtin_fabs(x) / pb[i]));
  }
#undef LEVEL_PARAMS
  if (level == 0 && m == 0) st = sc;
  *level_out = level;
  *push_out = push;
  return st;
}

/* masing_commit of spring i (as iem_masing_walk_slow) to the strain ek, its stress in s[i].
 * Bit for bit iem_masing's masing_commit. */
void iem_masing_commit_slow(int i, int depth, double ek, const double *pp, const double *pn,
                            const double *pb, const double *mp, const double *mn, double *e_c,
                            double *s_c, int32_t *dir, int32_t *count, double *e_rev,
                            double *s_rev, double *e_max_pos, double *e_max_neg, double *s) {
  double ec = e_c[i], sc = s_c[i], st;
  int32_t n0 = count[i], level, push;
  if (ek == ec) {
    s[i] = sc;
    return;
  }
  st = iem_masing_walk_slow(i, depth, ek, pp, pn, pb, mp, mn, e_c, s_c, dir, count, e_rev, s_rev,
                            &level, &push);
  if (push && level == n0 + 1) {
    e_rev[(int64_t)i * depth + level - 1] = ec;
    s_rev[(int64_t)i * depth + level - 1] = sc;
  }
  count[i] = level;
  dir[i] = ek > ec ? 1 : -1;
  e_c[i] = ek;
  s_c[i] = st;
  e_max_pos[i] = ek > e_max_pos[i] ? ek : e_max_pos[i];
  e_max_neg[i] = ek < e_max_neg[i] ? ek : e_max_neg[i];
  s[i] = st;
}

#if IEM_SIMD
/* Of the four stacks from er, sr (columns of depth values) at the levels l[0..3]: R_l's
 * strain and stress and R_(l-1)'s strain, each read as R_1 where there is none. */
static inline void stack_tops(const double *er, const double *sr, const int32_t *l, int depth,
                              __m256d *e_top, __m256d *s_top, __m256d *e_below) {
  int64_t t[4], b[4];
  for (int j = 0; j < 4; j++) {
    t[j] = (int64_t)j * depth + (l[j] > 1 ? l[j] : 1) - 1;
    b[j] = (int64_t)j * depth + (l[j] - 1 > 1 ? l[j] - 1 : 1) - 1;
  }
  *e_top = _mm256_set_pd(er[t[3]], er[t[2]], er[t[1]], er[t[0]]);
  *s_top = _mm256_set_pd(sr[t[3]], sr[t[2]], sr[t[1]], sr[t[0]]);
  *e_below = _mm256_set_pd(er[b[3]], er[b[2]], er[b[1]], er[b[0]]);
}

/* Whether moves of direction mr (+-1) at the strains ek end on the curve of a level (lev0:
 * level 0, the skeleton, where every move does; deep2: level 2 or more) that starts at e0 and
 * aims at below (R_(level-1)), or at the mirror of e0 on level 1 (mirror factors mp, mn):
 * forward short of its aim, or backward short of its start (masing_walk's test); d the
 * curve's direction. */
static inline __m256d on_curve(__m256d ek, __m256d mr, __m256d e0, __m256d below,
                               __m256d deep2, __m256d lev0, __m256d mp, __m256d mn,
                               __m256d *d) {
  const __m256d one = _mm256_set1_pd(1.0), mone = _mm256_set1_pd(-1.0),
                zero = _mm256_setzero_pd(), sign = _mm256_set1_pd(-0.0);
  __m256d mirror = _mm256_mul_pd(_mm256_xor_pd(e0, sign),
                                 _mm256_blendv_pd(mn, mp, _mm256_cmp_pd(e0, zero, _CMP_GE_OQ)));
  __m256d aim = _mm256_blendv_pd(mirror, below, deep2);
  *d = _mm256_blendv_pd(_mm256_blendv_pd(one, mone, _mm256_cmp_pd(e0, zero, _CMP_GT_OQ)),
                        _mm256_blendv_pd(mone, one, _mm256_cmp_pd(aim, e0, _CMP_GT_OQ)), deep2);
  __m256d fwd = _mm256_cmp_pd(_mm256_mul_pd(*d, _mm256_sub_pd(ek, aim)), zero, _CMP_LT_OQ);
  __m256d back = _mm256_cmp_pd(_mm256_mul_pd(*d, _mm256_sub_pd(ek, e0)), zero, _CMP_GT_OQ);
  return _mm256_or_pd(lev0, _mm256_blendv_pd(back, fwd, _mm256_cmp_pd(mr, *d, _CMP_EQ_OQ)));
}

/* The stress at the strains ek on the skeleton (lev0; strengths pp, pn by sign) or on the
 * branch from (e0, s0) (strength pb): the skeleton's and the branches' hyperbolas are one
 * function of (x, strength). */
static inline __m256d curve_stress(__m256d ek, __m256d e0, __m256d s0, __m256d lev0,
                                   __m256d pp, __m256d pn, __m256d pb) {
  const __m256d one = _mm256_set1_pd(1.0), zero = _mm256_setzero_pd(),
                sign = _mm256_set1_pd(-0.0);
  __m256d x = _mm256_blendv_pd(_mm256_mul_pd(_mm256_set1_pd(0.5), _mm256_sub_pd(ek, e0)), ek,
                               lev0);
  __m256d r = _mm256_blendv_pd(pb, _mm256_blendv_pd(pn, pp, _mm256_cmp_pd(ek, zero, _CMP_GE_OQ)),
                               lev0);
  __m256d y = _mm256_div_pd(x, _mm256_add_pd(one, _mm256_div_pd(_mm256_andnot_pd(sign, x), r)));
  return _mm256_blendv_pd(_mm256_add_pd(s0, _mm256_mul_pd(_mm256_set1_pd(2.0), y)), y, lev0);
}
#endif

/* masing_springs' first loop over n springs (strains e, constants of spring i pp[i] ..
 * mn[i]: k_pos, k_neg, k_branch, k_mirror_pos, k_mirror_neg) and with accept (non-zero) the
 * commit of every move (the fast ones in vectors, with the reversals they push, the others
 * by iem_masing_commit_slow): the stresses s, the committed strain and stress before (e_was,
 * s_was); without accept, the springs left to the state machine in slow[0 .. *n_slow - 1]
 * (numbered from 1, in order; their stresses s are then their committed ones), else
 * *n_slow = 0. */
void iem_masing_block(int n, int depth, int accept, const double *e, const double *pp,
                      const double *pn, const double *pb, const double *mp, const double *mn,
                      double *e_c, double *s_c, int32_t *dir, int32_t *count, double *e_rev,
                      double *s_rev, double *e_max_pos, double *e_max_neg, double *s,
                      double *e_was, double *s_was, int32_t *slow, int32_t *n_slow) {
  int i = 0, ns = 0;
#if IEM_SIMD
  const __m256d one = _mm256_set1_pd(1.0), zero = _mm256_setzero_pd(),
                two = _mm256_set1_pd(2.0), sign = _mm256_set1_pd(-0.0),
                deep = _mm256_set1_pd((double)depth);
  for (; i + 3 < n; i += 4) {
    __m256d ek = _mm256_loadu_pd(e + i), ec = _mm256_loadu_pd(e_c + i),
            sc = _mm256_loadu_pd(s_c + i);
    __m128i n0 = _mm_loadu_si128((const __m128i *)(count + i)),
            d0 = _mm_loadu_si128((const __m128i *)(dir + i));
    /* the top of each stack, R_n and R_(n-1), read as R_1 where there is none */
    const double *er = e_rev + (int64_t)i * depth, *sr = s_rev + (int64_t)i * depth;
    /* the stacks of the springs 32 ahead asked for (a cache hint, no value changed): where
     * the springs' state has left the caches, their tops are the loads the loop waits on */
    for (int q = 0; q < 4; q++) {
      IEM_HINT(er, 8 * (int64_t)(stack_ahead + q) * depth, 0);
      IEM_HINT(sr, 8 * (int64_t)(stack_ahead + q) * depth, 0);
    }
    __m256d et, st, eb;
    stack_tops(er, sr, count + i, depth, &et, &st, &eb);
    __m256d gt = _mm256_cmp_pd(ek, ec, _CMP_GT_OQ), lt = _mm256_cmp_pd(ek, ec, _CMP_LT_OQ);
    __m256d mr = _mm256_sub_pd(_mm256_and_pd(gt, one), _mm256_and_pd(lt, one));
    __m256d n0d = _mm256_cvtepi32_pd(n0), d0d = _mm256_cvtepi32_pd(d0);
    __m256d push = _mm256_and_pd(
        _mm256_and_pd(_mm256_cmp_pd(d0d, zero, _CMP_NEQ_OQ),
                      _mm256_cmp_pd(mr, _mm256_xor_pd(d0d, sign), _CMP_EQ_OQ)),
        _mm256_cmp_pd(n0d, deep, _CMP_LT_OQ));
    __m256d lev = _mm256_add_pd(n0d, _mm256_and_pd(push, one));
    __m256d e0 = _mm256_blendv_pd(et, ec, push), s0 = _mm256_blendv_pd(st, sc, push);
    __m256d lev0 = _mm256_cmp_pd(lev, zero, _CMP_EQ_OQ);
    __m256d mpk = _mm256_loadu_pd(mp + i), mnk = _mm256_loadu_pd(mn + i),
            ppk = _mm256_loadu_pd(pp + i), pnk = _mm256_loadu_pd(pn + i),
            pbk = _mm256_loadu_pd(pb + i), d;
    __m256d shrt = on_curve(ek, mr, e0, _mm256_blendv_pd(eb, et, push),
                            _mm256_cmp_pd(lev, two, _CMP_GE_OQ), lev0, mpk, mnk, &d);
    __m256d moving = _mm256_cmp_pd(mr, zero, _CMP_NEQ_OQ);
    __m256d fast = _mm256_or_pd(_mm256_cmp_pd(ek, ec, _CMP_EQ_OQ), _mm256_and_pd(moving, shrt));
    __m256d sk = _mm256_blendv_pd(sc, curve_stress(ek, e0, s0, lev0, ppk, pnk, pbk), moving);
    /* one step further down masing_walk's loop for the moves past the end of their curve: a
     * branch past its aim has closed (two levels down), an overflow retrace past its start
     * is back on the branch below (one level); the moves that end on that curve are done
     * here too (no reversal pushed), the others take the state machine */
    __m256d past = _mm256_andnot_pd(fast, moving);
    if (_mm256_movemask_pd(past)) {
      __m256d lv = _mm256_blendv_pd(_mm256_sub_pd(lev, one),
                                    _mm256_max_pd(_mm256_sub_pd(lev, two), zero),
                                    _mm256_cmp_pd(mr, d, _CMP_EQ_OQ));
      int32_t l4[4];
      _mm_storeu_si128((__m128i *)l4, _mm256_cvtpd_epi32(lv));
      /* R_lv and R_(lv-1), read as R_1 where there is none */
      __m256d e0b, s0b, ebb;
      stack_tops(er, sr, l4, depth, &e0b, &s0b, &ebb);
      __m256d lvm0 = _mm256_cmp_pd(lv, zero, _CMP_EQ_OQ), db;
      __m256d fast2 = _mm256_and_pd(
          past, on_curve(ek, mr, e0b, ebb, _mm256_cmp_pd(lv, two, _CMP_GE_OQ), lvm0, mpk, mnk,
                         &db));
      __m256d sb = curve_stress(ek, e0b, s0b, lvm0, ppk, pnk, pbk);
      sk = _mm256_blendv_pd(sk, sb, fast2);
      lev = _mm256_blendv_pd(lev, lv, fast2);
      push = _mm256_andnot_pd(fast2, push);
      fast = _mm256_or_pd(fast, fast2);
    }
    _mm256_storeu_pd(s + i, sk);
    _mm256_storeu_pd(e_was + i, ec);
    _mm256_storeu_pd(s_was + i, sc);
    if (accept) {
      /* what masing_commit does for a fast move (nothing for an unchanged strain) */
      __m256d moved = _mm256_and_pd(fast, moving);
      __m128i movedi = _mm256_cvtpd_epi32(_mm256_and_pd(moved, one));
      movedi = _mm_sub_epi32(_mm_setzero_si128(), movedi);
      _mm_storeu_si128((__m128i *)(count + i),
                       _mm_blendv_epi8(n0, _mm256_cvtpd_epi32(lev), movedi));
      _mm_storeu_si128((__m128i *)(dir + i),
                       _mm_blendv_epi8(d0, _mm256_cvtpd_epi32(mr), movedi));
      _mm256_storeu_pd(e_c + i, _mm256_blendv_pd(ec, ek, moved));
      _mm256_storeu_pd(s_c + i, _mm256_blendv_pd(sc, sk, moved));
      __m256d emp = _mm256_loadu_pd(e_max_pos + i), emn = _mm256_loadu_pd(e_max_neg + i);
      _mm256_storeu_pd(e_max_pos + i, _mm256_blendv_pd(emp, _mm256_max_pd(ek, emp), moved));
      _mm256_storeu_pd(e_max_neg + i, _mm256_blendv_pd(emn, _mm256_min_pd(ek, emn), moved));
      /* the reversals pushed: R_lev = the committed point before */
      int pushed = _mm256_movemask_pd(_mm256_and_pd(moved, push));
      while (pushed) {
        int j = __builtin_ctz(pushed), l = count[i + j];
        e_rev[(int64_t)(i + j) * depth + l - 1] = e_was[i + j];
        s_rev[(int64_t)(i + j) * depth + l - 1] = s_was[i + j];
        pushed &= pushed - 1;
      }
    }
    /* the others take the state machine: committed here, or listed */
    int others = _mm256_movemask_pd(fast) ^ 15;
    while (others) {
      int j = __builtin_ctz(others);
      if (accept)
        iem_masing_commit_slow(i + j, depth, e[i + j], pp, pn, pb, mp, mn, e_c, s_c, dir, count,
                               e_rev, s_rev, e_max_pos, e_max_neg, s);
      else
        slow[ns++] = i + j + 1;
      others &= others - 1;
    }
  }
#endif
  for (; i < n; i++)
    if (spring1(i, depth, accept, e, pp, pn, pb, mp, mn, e_c, s_c, dir, count, e_rev, s_rev,
                e_max_pos, e_max_neg, s, e_was, s_was))
    {
      if (accept)
        iem_masing_commit_slow(i, depth, e[i], pp, pn, pb, mp, mn, e_c, s_c, dir, count, e_rev,
                               s_rev, e_max_pos, e_max_neg, s);
      else
        slow[ns++] = i + 1;
    }
  *n_slow = ns;
}
