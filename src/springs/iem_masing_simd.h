/* The state machine of one spring in C (iem_masing_simd.c), shared by the AVX2 loops of
 * iem_masing_simd.c and iem_masing_curves_simd.c: bit for bit iem_masing's masing_walk
 * (without the tangent) and masing_commit, Emax = 1, spring i's constants pp[i] .. mn[i]
 * (k_pos, k_neg, k_branch, k_mirror_pos, k_mirror_neg), its stack column i of e_rev, s_rev
 * (depth values each, Fortran's column-major order). */
#ifndef IEM_MASING_SIMD_H
#define IEM_MASING_SIMD_H
#include <stdint.h>

/* The stress of spring i at the strain ek, walked from its committed state; the level
 * reached and whether the committed point is pushed in *level_out, *push_out. */
double iem_masing_walk_slow(int i, int depth, double ek, const double *pp, const double *pn,
                            const double *pb, const double *mp, const double *mn,
                            const double *e_c, const double *s_c, const int32_t *dir,
                            const int32_t *count, const double *e_rev, const double *s_rev,
                            int32_t *level_out, int32_t *push_out);

/* Spring i's state committed to the strain ek (a reversal pushed, loops closed on the way),
 * its stress in s[i]. */
void iem_masing_commit_slow(int i, int depth, double ek, const double *pp, const double *pn,
                            const double *pb, const double *mp, const double *mn, double *e_c,
                            double *s_c, int32_t *dir, int32_t *count, double *e_rev,
                            double *s_rev, double *e_max_pos, double *e_max_neg, double *s);
#endif
