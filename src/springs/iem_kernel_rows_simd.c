/* The force kernel's copies between the state and a chunk's node rows (iem_kernel_rows):
 * two values a node out of the state's columns of 4 into two rows (gather), and the corner
 * forces of a chunk's cells added to its two node rows' forces (scatter), written with AVX2
 * vectors: the interleaving of the rows' x and y values done with in-lane unpacks and one
 * lane exchange a vector, where gfortran's vectorised loops use lane-crossing permutations.
 * The gather copies; the scatter does each node's additions in the Fortran loop's order,
 * (f + first corner force) + second, so the results are bit for bit the loops'
 * (test_iem_cell_kernel checks it). Where the CPU has AVX-512, the scatter takes eight nodes
 * a step (add8; 1 to 2 % of the force's time on the development machine, twenty-third
 * session). Both ask for the memory of the next m + 1 nodes as they
 * go (a cache hint, no value changed): on consecutively numbered node rows, the next chunk's
 * top row, or the next node row's start after a row's last chunk, so that the kernel's sweep
 * does not wait on memory where the state has left the core's caches (docs/architecture.md,
 * "The force kernel"). Built without AVX2, iem_kernel_rows_simd() is 0 and the Fortran loops
 * run. Arrays are Fortran's column-major: y(4, 0:m), w(0:ld-1, 2), f(2, 0:m), fx(ldf, 4). */
#include "iem_cache_hint.h"

#if defined(__AVX2__)
#include <immintrin.h>
#define IEM_SIMD 1
#else
#define IEM_SIMD 0
#endif

/* Whether the copies here are built (1) or the Fortran loops run (0). */
int iem_kernel_rows_simd(void) { return IEM_SIMD; }

/* w(i, 1) = y(r0 + 1, i), w(i, 2) = y(r0 + 2, i) for the nodes i = 0..m of a block of
 * consecutive nodes (4 state values a node); ld: w's leading dimension. The next m + 1
 * nodes' values are asked for, two cache lines (four nodes) at a time. */
void iem_gather_row4(int m, const double *y, int r0, int ld, double *w) {
#if IEM_SIMD
  const double *ahead = y; /* the next m + 1 nodes start 4 (m + 1) values on */
  int i = 0;
  y += r0;
  for (; i + 3 <= m; i += 4) {
    IEM_HINT(ahead, 8 * (4 * (m + 1) + 4 * i), 0);
    IEM_HINT(ahead, 8 * (4 * (m + 1) + 4 * i + 8), 0);
    __m256d ac = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(y + 4 * i)),
                                      _mm_loadu_pd(y + 4 * i + 8), 1);
    __m256d bd = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(y + 4 * i + 4)),
                                      _mm_loadu_pd(y + 4 * i + 12), 1);
    _mm256_storeu_pd(w + i, _mm256_unpacklo_pd(ac, bd));
    _mm256_storeu_pd(w + ld + i, _mm256_unpackhi_pd(ac, bd));
  }
  for (; i <= m; i++) {
    IEM_HINT(ahead, 8 * (4 * (m + 1) + 4 * i), 0);
    w[i] = y[4 * i];
    w[ld + i] = y[4 * i + 1];
  }
#else
  (void)m; (void)y; (void)r0; (void)ld; (void)w;
#endif
}

#if IEM_SIMD
/* f(:, j..j+3) = (f + (a, b)) + (c, d) with a, b, c, d holding the x and y terms of the four
 * nodes. */
static inline void add4(double *f, __m256d a, __m256d b, __m256d c, __m256d d) {
  __m256d lo = _mm256_unpacklo_pd(a, b), hi = _mm256_unpackhi_pd(a, b);
  __m256d p0 = _mm256_permute2f128_pd(lo, hi, 0x20), p1 = _mm256_permute2f128_pd(lo, hi, 0x31);
  lo = _mm256_unpacklo_pd(c, d);
  hi = _mm256_unpackhi_pd(c, d);
  __m256d q0 = _mm256_permute2f128_pd(lo, hi, 0x20), q1 = _mm256_permute2f128_pd(lo, hi, 0x31);
  _mm256_storeu_pd(f, _mm256_add_pd(_mm256_add_pd(_mm256_loadu_pd(f), p0), q0));
  _mm256_storeu_pd(f + 4, _mm256_add_pd(_mm256_add_pd(_mm256_loadu_pd(f + 4), p1), q1));
}
#endif

#if defined(__AVX512F__)
/* add4 for eight nodes with AVX-512: one two-source permutation (lo: the first four nodes,
 * hi: the last four) interleaves four nodes' x and y terms, where add4 takes four shuffles
 * (two unpacks, two lane exchanges). */
static inline void add8(double *f, __m512i lo, __m512i hi, __m512d a, __m512d b, __m512d c,
                        __m512d d) {
  _mm512_storeu_pd(f, _mm512_add_pd(_mm512_add_pd(_mm512_loadu_pd(f),
                                                  _mm512_permutex2var_pd(a, lo, b)),
                                    _mm512_permutex2var_pd(c, lo, d)));
  _mm512_storeu_pd(f + 8, _mm512_add_pd(_mm512_add_pd(_mm512_loadu_pd(f + 8),
                                                      _mm512_permutex2var_pd(a, hi, b)),
                                        _mm512_permutex2var_pd(c, hi, d)));
}
#endif

/* The corner forces fx, fy(cell, corner) of a chunk's m cells added to its bottom and top
 * node rows' forces fb, ft(2, 0:m) (iem_kernel_rows' add_block_forces): bottom node j gets
 * corner 2 of cell j, then corner 1 of cell j + 1; top node j corner 3 of cell j, then
 * corner 4 of cell j + 1. The forces of the top row's next m + 1 nodes are asked for (to be
 * written), a cache line (four nodes) at a time. */
void iem_scatter_rows(int m, double *fb, double *ft, const double *fx, const double *fy,
                      int ldf) {
#if IEM_SIMD
  const double *x1 = fx, *x2 = fx + ldf, *x3 = fx + 2 * ldf, *x4 = fx + 3 * ldf;
  const double *y1 = fy, *y2 = fy + ldf, *y3 = fy + 2 * ldf, *y4 = fy + 3 * ldf;
  int j;
  /* cells are 1..m: cell c's values at index c - 1 */
  fb[0] += x1[0];
  fb[1] += y1[0];
  ft[0] += x4[0];
  ft[1] += y4[0];
  j = 1;
#if defined(__AVX512F__)
  {
    /* 8 nodes a step (the interleaving permutations of add8) */
    const __m512i lo = _mm512_set_epi64(11, 3, 10, 2, 9, 1, 8, 0);
    const __m512i hi = _mm512_set_epi64(15, 7, 14, 6, 13, 5, 12, 4);
    for (; j + 7 <= m - 1; j += 8) {
      IEM_HINT(ft, 8 * (2 * (m + 1) + 2 * j), 1);
      IEM_HINT(ft, 8 * (2 * (m + 1) + 2 * j + 8), 1);
      add8(fb + 2 * j, lo, hi, _mm512_loadu_pd(x2 + j - 1), _mm512_loadu_pd(y2 + j - 1),
           _mm512_loadu_pd(x1 + j), _mm512_loadu_pd(y1 + j));
      add8(ft + 2 * j, lo, hi, _mm512_loadu_pd(x3 + j - 1), _mm512_loadu_pd(y3 + j - 1),
           _mm512_loadu_pd(x4 + j), _mm512_loadu_pd(y4 + j));
    }
  }
#endif
  for (; j + 3 <= m - 1; j += 4) {
    IEM_HINT(ft, 8 * (2 * (m + 1) + 2 * j), 1);
    add4(fb + 2 * j, _mm256_loadu_pd(x2 + j - 1), _mm256_loadu_pd(y2 + j - 1),
         _mm256_loadu_pd(x1 + j), _mm256_loadu_pd(y1 + j));
    add4(ft + 2 * j, _mm256_loadu_pd(x3 + j - 1), _mm256_loadu_pd(y3 + j - 1),
         _mm256_loadu_pd(x4 + j), _mm256_loadu_pd(y4 + j));
  }
  for (; j <= m - 1; j++) {
    fb[2 * j] = (fb[2 * j] + x2[j - 1]) + x1[j];
    fb[2 * j + 1] = (fb[2 * j + 1] + y2[j - 1]) + y1[j];
    ft[2 * j] = (ft[2 * j] + x3[j - 1]) + x4[j];
    ft[2 * j + 1] = (ft[2 * j + 1] + y3[j - 1]) + y4[j];
  }
  fb[2 * m] += x2[m - 1];
  fb[2 * m + 1] += y2[m - 1];
  ft[2 * m] += x3[m - 1];
  ft[2 * m + 1] += y3[m - 1];
#else
  (void)m; (void)fb; (void)ft; (void)fx; (void)fy; (void)ldf;
#endif
}
