"""Tests of iem_post.fibre_beam: the hyperbolic law and its primitives, the section
(closed form against quadrature, N = 0, symmetry, monotonicity, ultimate moment) and the
unit-load deflections (elastic limit, small-load expansion, quadrature convergence)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from iem_post import fibre_beam as fb
from iem_post import references as ref

D = fb.FIBRE_DEFAULTS
E, NU, FT, FC, L, H, T = (D[k] for k in ("E", "nu", "f_t", "f_c", "L", "h", "t"))
I = T * H**3 / 12.0  # 8.333e-6 m^4
M_U_HAND = 0.1 * 0.1**2 * 3e6 * 30e6 / (2.0 * 33e6)  # 1363.636... N m


def test_hyperbolic_stress_hand_values() -> None:
    """sigma(f/E) = f/2 on both sides; initial tangent E; asymptotes f_t and -f_c."""
    assert fb.hyperbolic_stress(FT / E) == pytest.approx(FT / 2.0, rel=1e-15)
    assert fb.hyperbolic_stress(-FC / E) == pytest.approx(-FC / 2.0, rel=1e-15)
    assert fb.hyperbolic_stress(1e-12) == pytest.approx(E * 1e-12, rel=1e-5)
    assert fb.hyperbolic_stress(0.0) == 0.0
    big = np.asarray(fb.hyperbolic_stress(np.array([1e3, -1e3])))
    assert big[0] == pytest.approx(FT, rel=1e-6)  # f_t (1 - f_t / (E eps))
    assert big[1] == pytest.approx(-FC, rel=2e-6)


@pytest.mark.parametrize("eps", [3e-9, -3e-9, 2e-6, -2e-6, 1.1e-5, 1.2e-4, -1.2e-3, 5e-2, -0.3])
def test_stress_primitives_against_quadrature(eps: float) -> None:
    """F1 = int_0^eps sigma, F2 = int_0^eps sigma e: closed form (with the small-x series)
    against 30-point Gauss-Legendre on 30 panels of [0, eps] graded geometrically towards
    0 (the law is analytic on [0, eps] but bends over a strain ~ f / E)."""
    xi, w = np.polynomial.legendre.leggauss(30)
    bp = eps * np.concatenate([[0.0], 0.5 ** np.arange(29, -1, -1, dtype=float)])
    a, b = bp[:-1, None], bp[1:, None]
    e = 0.5 * (a + b) + 0.5 * (b - a) * xi
    s = np.asarray(fb.hyperbolic_stress(e))
    F1q = np.sum(0.5 * (b - a) * w * s)
    F2q = np.sum(0.5 * (b - a) * w * s * e)
    F1, F2 = fb.stress_primitives(eps)
    assert F1 == pytest.approx(F1q, rel=1e-13)
    assert F2 == pytest.approx(F2q, rel=1e-13)
    assert F1 >= 0.0 and math.copysign(1.0, F2) == math.copysign(1.0, eps)


def test_stress_primitives_series_branch_is_continuous() -> None:
    """The series (x < 0.25) and the log form agree at the switch, x = E eps / f_t = 0.25."""
    eps = 0.25 * FT / E
    lo, hi = fb.stress_primitives(np.array([eps * (1.0 - 1e-12), eps * (1.0 + 1e-12)]))
    assert lo[0] == pytest.approx(lo[1], rel=1e-11)
    assert hi[0] == pytest.approx(hi[1], rel=1e-11)


def test_section_closed_form_against_quadrature() -> None:
    """N and M of arbitrary (not balanced) strain fields, closed form against graded
    Gauss-Legendre over the depth, including mixed-sign fields and the small-k fallback."""
    rng = np.random.default_rng(7)
    eps0 = np.concatenate([rng.uniform(-1e-3, 1e-3, 30), [1e-4, -1e-4, 2e-4, 0.0]])
    k = np.concatenate([rng.uniform(-2e-2, 2e-2, 30), [1e-7, 1e-7, 0.0, 0.0]])
    Nc, Mc = fb.section_forces(eps0, k)
    Nq, Mq = fb.section_forces(eps0, k, method="quadrature", n_gauss=32, n_panels=16)
    N_scale = T * H * FC
    assert np.max(np.abs(np.asarray(Nc) - np.asarray(Nq))) < 1e-12 * N_scale
    assert np.max(np.abs(np.asarray(Mc) - np.asarray(Mq))) < 1e-12 * M_U_HAND
    # uniform strain (k = 0): N = t h sigma(eps0), M = 0
    N0, M0 = fb.section_forces(2e-4, 0.0)
    assert N0 == pytest.approx(T * H * fb.hyperbolic_stress(2e-4), rel=1e-14)
    assert abs(M0) < 1e-12


@pytest.mark.parametrize("k", [1e-7, 1e-5, 1e-3, 0.1, 10.0, 1e3])
def test_axial_force_vanishes_at_solution(k: float) -> None:
    """N = 0 (by quadrature, independent of the closed form) at eps0(k), and the closed-form
    M agrees with the quadrature M; both signs of k (mirror symmetry)."""
    eps0 = fb.neutral_axis_strain(k)
    M = fb.section_moment(k)
    N, Mq = fb.section_forces(eps0, k, method="quadrature", n_gauss=32, n_panels=24)
    assert abs(N) < 1e-12 * T * H * FT
    assert Mq == pytest.approx(M, rel=1e-12)
    assert fb.neutral_axis_strain(-k) == pytest.approx(eps0, rel=1e-14)
    assert fb.section_moment(-k) == pytest.approx(-M, rel=1e-14)
    N_neg, _ = fb.section_forces(eps0, -k, method="quadrature", n_gauss=32, n_panels=24)
    assert abs(N_neg) < 1e-12 * T * H * FT
    assert eps0 > 0.0  # f_t < f_c: the neutral axis rises towards the compression side


def test_symmetric_strengths_give_zero_centroid_strain() -> None:
    """f_t = f_c: the neutral axis stays at mid-depth (eps0 = 0) and M_u = t h^2 f / 4."""
    f = 10e6
    k = np.logspace(-6, 2, 17)
    eps0 = np.asarray(fb.neutral_axis_strain(k, f_t=f, f_c=f))
    assert np.max(np.abs(eps0) / (k * H)) < 1e-14
    assert fb.ultimate_moment(f, f) == pytest.approx(T * H**2 * f / 4.0, rel=1e-15)


def test_hand_checkable_symmetric_section() -> None:
    """f_t = f_c = f and E k h / (2 f) = 1 (outer fibres at eps = f/E, sigma = f/2):
    M = 2 t f^3 / (E^2 k^2) (1/2 - 1 + ln 2) = t f h^2 (ln 2 - 1/2) / 2
    = 0.1 * 3e6 * 0.01 * 0.0965736 = 289.72 N m for f = 3 MPa; and back."""
    f = 3e6
    k = 2.0 * f / (E * H)  # 2.4e-3 1/m
    M_hand = T * f * H**2 * (math.log(2.0) - 0.5) / 2.0
    assert M_hand == pytest.approx(289.7208, rel=1e-6)
    assert fb.section_moment(k, f_t=f, f_c=f) == pytest.approx(M_hand, rel=1e-14)
    assert fb.curvature_for_moment(M_hand, f_t=f, f_c=f) == pytest.approx(k, rel=1e-13)


def test_ultimate_moment_hand_value() -> None:
    """M_u = t h^2 f_t f_c / (2 (f_t + f_c)) = 1363.64 N m; P_u = M_u / L and 4 M_u / L."""
    assert fb.ultimate_moment() == pytest.approx(M_U_HAND, rel=1e-15)
    assert fb.ultimate_load("cantilever") == pytest.approx(M_U_HAND, rel=1e-15)
    assert fb.ultimate_load("simply_supported") == pytest.approx(4.0 * M_U_HAND, rel=1e-15)
    with pytest.raises(ValueError):
        fb.ultimate_load("fixed-fixed")


def test_moment_curvature_monotone_and_approaches_ultimate() -> None:
    """M(k) increases strictly, stays below M_u, and M_u - M(k) -> t h f_t f_c / (E k)
    (the stress deficit f^2 / (E |eps|) next to the neutral axis)."""
    k = np.logspace(-8, 6, 281)
    M = np.asarray(fb.section_moment(k))
    assert np.all(np.diff(M) > 0.0)
    assert np.all(M < M_U_HAND)
    assert M[-1] > (1.0 - 1e-7) * M_U_HAND
    for kk, tol in ((1e4, 1e-3), (1e6, 3e-5)):
        gap = M_U_HAND - fb.section_moment(kk)
        assert gap * kk * E / (T * H * FT * FC) == pytest.approx(1.0, abs=tol)
    # secant stiffness decreases from E I
    secant = M / (E * I * k)
    assert secant[0] == pytest.approx(1.0, abs=2e-6)  # 1 - 1.7e-6 at k = 1e-8 1/m
    assert np.all(np.diff(secant) < 0.0)


def test_small_curvature_expansion() -> None:
    """M(k) = E I k - t E^2 h^4 (1/f_t + 1/f_c) k^2 / 64 + O(k^3) (hand derivation from
    sigma ~ E eps - E^2 eps |eps| / f)."""
    c2 = T * E**2 * H**4 * (1.0 / FT + 1.0 / FC) / 64.0
    for k in (1e-7, 1e-6):
        M = fb.section_moment(k)
        assert (E * I * k - M) / (c2 * k**2) == pytest.approx(1.0, rel=2e-2 * k / 1e-6)


def test_curvature_for_moment_inverts_section_moment() -> None:
    """k(M(k)) = k over 12 decades, odd in M, and M >= M_u is refused.  Near M_u the
    inversion is ill-conditioned (d ln k / d ln M ~ M_u / (M_u - M) = 4e5 at k = 1e4), so
    the curvature is checked to 1e-12 up to k = 1 and the moment residual everywhere."""
    k = np.logspace(-8, 4, 49)
    M = np.asarray(fb.section_moment(k))
    back = np.asarray(fb.curvature_for_moment(M))
    assert np.max(np.abs(back / k - 1.0)[k <= 1.0]) < 1e-12
    assert np.max(np.abs(back / k - 1.0)) < 1e-9
    assert np.max(np.abs(np.asarray(fb.section_moment(back)) / M - 1.0)) < 1e-14
    assert fb.curvature_for_moment(-M[20]) == pytest.approx(-k[20], rel=1e-11)
    assert fb.curvature_for_moment(0.0) == 0.0
    with pytest.raises(ValueError):
        fb.curvature_for_moment(M_U_HAND)


def test_elastic_limit_matches_beam_formulas() -> None:
    """Tiny loads: the Euler-Bernoulli and Timoshenko values of iem_post.references to 1e-6."""
    P = 1e-4  # N: peak strain 3e-11, E eps / f_t = 2e-7
    cases = (
        (fb.cantilever_tip_deflection, ref.cantilever_tip_deflection_euler_bernoulli,
         ref.cantilever_tip_deflection_timoshenko),
        (fb.simply_supported_midspan_deflection, ref.simply_supported_midspan_deflection_euler_bernoulli,
         ref.simply_supported_midspan_deflection_timoshenko),
    )
    for fn, eb, ti in cases:
        assert fn(P) == pytest.approx(eb(P, L, E, H, T), rel=1e-6)
        assert fn(P, shear=True) == pytest.approx(ti(P, L, E, NU, H, T), rel=1e-6)
        assert fn(-P) == pytest.approx(-fn(P), rel=1e-14)
    # hand values per newton: P L^3 / (3 E I) = 1.6e-6 m/N, P L^3 / (48 E I) = 1e-7 m/N
    assert fb.cantilever_tip_deflection(P) / P == pytest.approx(1.6e-6, rel=1e-6)
    assert fb.simply_supported_midspan_deflection(P) / P == pytest.approx(1e-7, rel=1e-6)
    assert fb.cantilever_tip_deflection(0.0) == 0.0


def test_small_load_deflection_expansion() -> None:
    """k(mu) = mu / EI + c2 mu^2 / EI^3 gives delta / delta_el = 1 + (3/4) c2 M_max / EI^2
    for both scenes (M_max = P L and P L / 4)."""
    c2 = T * E**2 * H**4 * (1.0 / FT + 1.0 / FC) / 64.0
    EI = E * I
    for scene, M_max in (("cantilever", 0.5), ("simply_supported", 0.5)):
        P = M_max / L if scene == "cantilever" else 4.0 * M_max / L
        c = fb.load_deflection_curve(scene, [P])
        expected = 0.75 * c2 * M_max / EI**2  # 1.6e-4
        assert (c["ratio_bending"][0] - 1.0) / expected == pytest.approx(1.0, rel=2e-3)


def test_deflection_quadrature_converged() -> None:
    """At 0.9 P_u (steepest curvature near the peak moment): adaptive rules at rtol 1e-7 and
    1e-13 agree, the error estimate is below 1e-6 relative, and a direct dense Gauss
    quadrature along x (graded towards the clamp) of int k(M(x)) m(x) dx agrees to 1e-10."""
    P = 0.9 * fb.ultimate_load("cantilever")
    fine, err = fb.bending_deflection("cantilever", P, rtol=1e-13)
    coarse, err_c = fb.bending_deflection("cantilever", P, rtol=1e-7)
    assert err < 1e-6 * fine and err_c < 1e-6 * coarse
    assert coarse == pytest.approx(fine, rel=1e-7)
    # along x: panels [0, 2^-40], ..., [1/4, 1/2], [1/2, 1] (times L), 30 points each
    xi, w = np.polynomial.legendre.leggauss(30)
    bp = np.concatenate([[0.0], 0.5 ** np.arange(40, -1, -1, dtype=float)]) * L
    a, b = bp[:-1, None], bp[1:, None]
    x = 0.5 * (a + b) + 0.5 * (b - a) * xi
    kx = np.asarray(fb.curvature_for_moment(P * (L - x)))  # |k| of the hogging section
    direct = float(np.sum(0.5 * (b - a) * w * kx * (L - x)))
    assert direct == pytest.approx(fine, rel=1e-10)
    # simply supported, along x on [0, L/2] graded towards mid-span, doubled by symmetry
    P = 0.9 * fb.ultimate_load("simply_supported")
    fine, err = fb.bending_deflection("simply_supported", P, rtol=1e-13)
    x = 0.5 * L - 0.5 * (0.5 * (a + b) + 0.5 * (b - a) * xi)
    kx = np.asarray(fb.curvature_for_moment(P * x / 2.0))
    direct = 2.0 * float(np.sum(0.25 * (b - a) * w * kx * x / 2.0))
    assert direct == pytest.approx(fine, rel=1e-10)


def test_load_deflection_curve_scenes_consistent() -> None:
    """delta_b / delta_el depends on M_max / M_u only, so both scenes give the same bending
    ratio at the same P / P_u; deflection grows monotonically and softens (ratio > 1)."""
    frac = np.array([0.1, 0.3, 0.5, 0.7, 0.9])
    cant = fb.load_deflection_curve("cantilever", frac * fb.ultimate_load("cantilever"))
    ss = fb.load_deflection_curve("simply_supported", frac * fb.ultimate_load("simply_supported"))
    assert np.allclose(cant["ratio_bending"], ss["ratio_bending"], rtol=1e-10, atol=0.0)
    assert np.allclose(cant["P_over_Pu"], frac, rtol=1e-14)
    for c in (cant, ss):
        assert np.all(np.diff(c["deflection"]) > 0.0)
        assert np.all(np.diff(c["ratio_bending"]) > 0.0) and c["ratio_bending"][0] > 1.0
        assert np.allclose(c["deflection"], c["bending"] + c["shear"], rtol=1e-15)
        assert np.all(c["quadrature_error"] < 1e-6 * c["bending"])
    with pytest.raises(ValueError):
        fb.load_deflection_curve("cantilever", [1.01 * fb.ultimate_load("cantilever")])
