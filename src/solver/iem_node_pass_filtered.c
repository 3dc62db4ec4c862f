/* RK4's passes over the owned nodes for states of 6 values a node (u1, u2, v1, v2, w1, w2: w is
 * capped stiffness damping's filtered velocity, docs/model.md), for iem_node_pass_filtered.f90.
 * The rates of a node are k = (v, a, r): a = -fma(alpha m, v, f)/m from its summed force f
 * (cleared for the next evaluation) and r = omega_cap (v - w); a state plus w times a rate is
 * fma(w, k, y). Written in C so that every value is formed by exactly these operations
 * (compiled with -ffp-contract=off: no other product and sum is fused), whether the rates are
 * formed in the pass (the fused stages) or were formed before it (the passes one after the
 * other), so the two are bit for bit the same (test_iem_integrator). Fortran's column-major
 * arrays: y(6, n), f(2, n), acc(4, n). */
#include <math.h>

/* The rates k of node l of the state s (6 values a node), its force at f (then cleared). */
static inline void rates(int l, double alpha, double omega, const double *mass, const double *s,
                         double *f, double k[6]) {
  const double *sl = s + 6 * l;
  double m = mass[l];
  k[0] = sl[2];
  k[1] = sl[3];
  k[2] = -(fma(alpha * m, sl[2], f[2 * l]) / m);
  k[3] = -(fma(alpha * m, sl[3], f[2 * l + 1]) / m);
  k[4] = omega * (sl[2] - sl[4]);
  k[5] = omega * (sl[3] - sl[5]);
  f[2 * l] = 0.0;
  f[2 * l + 1] = 0.0;
}

/* One stage's pass: the rates k at the states in state (their forces f cleared),
 * ynew = sum + wdt k and ys = base + h k (ys may be state, ynew may be sum: each node's values
 * are read before they are written). */
static void stage_pass(int n, double alpha, double omega, const double *mass, double wdt,
                       double h, const double *state, const double *sum, const double *base,
                       double *f, double *ynew, double *ys) {
  for (int l = 0; l < n; l++) {
    double k[6];
    rates(l, alpha, omega, mass, state, f, k);
    for (int j = 0; j < 6; j++) {
      ynew[6 * l + j] = fma(wdt, k[j], sum[6 * l + j]);
      ys[6 * l + j] = fma(h, k[j], base[6 * l + j]);
    }
  }
}

/* Stage 1 at the state y: ynew = y + wdt k1, ys = y + h k1. */
void iem_rk4_filtered_first(int n, double alpha, double omega, const double *mass, double wdt,
                            double h, const double *y, double *f, double *ynew, double *ys) {
  stage_pass(n, alpha, omega, mass, wdt, h, y, y, y, f, ynew, ys);
}

/* Stage 2 or 3 at the stage state ys: ynew = ynew + wdt k, then ys = y0 + h k. */
void iem_rk4_filtered_mid(int n, double alpha, double omega, const double *mass, double wdt,
                          double h, const double *y0, double *f, double *ynew, double *ys) {
  stage_pass(n, alpha, omega, mass, wdt, h, ys, ynew, y0, f, ynew, ys);
}

/* Stage 4 at the stage state ys: ynew = ynew + wdt k, with the sum of the new values in
 * total (which only says whether they are all finite). */
void iem_rk4_filtered_last(int n, double alpha, double omega, const double *mass, double wdt,
                           const double *ys, double *f, double *ynew, double *total) {
  double sum = 0.0;
  for (int l = 0; l < n; l++) {
    double k[6];
    rates(l, alpha, omega, mass, ys, f, k);
    for (int j = 0; j < 6; j++) {
      ynew[6 * l + j] = fma(wdt, k[j], ynew[6 * l + j]);
      sum += ynew[6 * l + j];
    }
  }
  *total = sum;
}

/* The rates k of node l from those formed before the pass: the velocities yk(3:4) and
 * acc(4, n) (a, r). */
static inline void rates_of(int l, const double *yk, const double *acc, double k[6]) {
  k[0] = yk[6 * l + 2];
  k[1] = yk[6 * l + 3];
  for (int j = 0; j < 4; j++) k[2 + j] = acc[4 * l + j];
}

/* A stage's update (not the last) from rates formed before it, as the passes above form it:
 * ynew = (first: y, else ynew) + wdt k, ys = y + h k (ys may be yk: each node's values are
 * read before they are written). */
void iem_rk4_filtered_update(int n, int first, double wdt, double h, const double *y,
                             const double *yk, const double *acc, double *ynew, double *ys) {
  for (int l = 0; l < n; l++) {
    double k[6];
    rates_of(l, yk, acc, k);
    for (int j = 0; j < 6; j++) {
      ynew[6 * l + j] = fma(wdt, k[j], first ? y[6 * l + j] : ynew[6 * l + j]);
      ys[6 * l + j] = fma(h, k[j], y[6 * l + j]);
    }
  }
}

/* The last stage's update from rates formed before it: ynew = ynew + wdt k, with the sum of
 * the new values in total. */
void iem_rk4_filtered_last_update(int n, double wdt, const double *ys, const double *acc,
                                  double *ynew, double *total) {
  double sum = 0.0;
  for (int l = 0; l < n; l++) {
    double k[6];
    rates_of(l, ys, acc, k);
    for (int j = 0; j < 6; j++) {
      ynew[6 * l + j] = fma(wdt, k[j], ynew[6 * l + j]);
      sum += ynew[6 * l + j];
    }
  }
  *total = sum;
}
