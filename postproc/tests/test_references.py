"""Tests of iem_post.references: beam formulas against hand values and limiting cases,
and the committed finite-element references."""

from __future__ import annotations

import math

import numpy as np
import pytest

from iem_post import references as ref

P = ref.ISSUE3
E, NU, RHO, L, H, T, LOAD = (P[k] for k in ("E", "nu", "rho", "L", "h", "t", "P"))
I_HAND = 0.1 * 0.1**3 / 12.0  # t h^3 / 12 = 8.333e-6 m^4
A_HAND = 0.1 * 0.1
G_HAND = 25e9 / 2.4


def test_section_and_moduli() -> None:
    """A, I, G and Cowper's kappa by hand."""
    A, I = ref.section(H, T)
    assert A == pytest.approx(A_HAND, rel=1e-15)
    assert I == pytest.approx(I_HAND, rel=1e-15)
    assert ref.shear_modulus(E, NU) == pytest.approx(G_HAND, rel=1e-15)
    assert ref.KAPPA_RECTANGLE == pytest.approx(5.0 / 6.0)
    assert ref.kappa_cowper(0.2) == pytest.approx(12.0 / 14.2, rel=1e-15)


def test_cantilever_deflection_hand_values() -> None:
    """P L^3 / (3 E I) = 1000 / (3 * 25e9 * 8.333e-6) = 1.6e-3 m; shear term
    P L / (5/6 G A) = 1000 / (5/6 * 25e9/2.4 * 0.01) = 1.152e-5 m."""
    eb = ref.cantilever_tip_deflection_euler_bernoulli(LOAD, L, E, H, T)
    ti = ref.cantilever_tip_deflection_timoshenko(LOAD, L, E, NU, H, T)
    assert eb == pytest.approx(1.6e-3, rel=1e-13)
    assert ti - eb == pytest.approx(1.152e-5, rel=1e-12)
    cowper = ref.cantilever_tip_deflection_timoshenko(LOAD, L, E, NU, H, T, kappa=ref.kappa_cowper(NU))
    assert cowper - eb == pytest.approx(1.152e-5 * (5.0 / 6.0) / ref.kappa_cowper(NU), rel=1e-12)


def test_simply_supported_deflection_hand_values() -> None:
    """P L^3 / (48 E I) = 1e-4 m; shear term P L / (4 * 5/6 G A) = 2.88e-6 m."""
    eb = ref.simply_supported_midspan_deflection_euler_bernoulli(LOAD, L, E, H, T)
    ti = ref.simply_supported_midspan_deflection_timoshenko(LOAD, L, E, NU, H, T)
    assert eb == pytest.approx(1e-4, rel=1e-13)
    assert ti - eb == pytest.approx(2.88e-6, rel=1e-12)


def test_deflection_shear_term_vanishes_for_slender_beams() -> None:
    """Timoshenko / Euler-Bernoulli - 1 is proportional to (h/L)^2."""
    for fn_t, fn_e, c in (
        (ref.cantilever_tip_deflection_timoshenko, ref.cantilever_tip_deflection_euler_bernoulli, 1.0 / 4.0),
        (
            ref.simply_supported_midspan_deflection_timoshenko,
            ref.simply_supported_midspan_deflection_euler_bernoulli,
            1.0,
        ),
    ):
        for h in (0.1, 0.01, 0.001):
            ratio = fn_t(LOAD, L, E, NU, h, T) / fn_e(LOAD, L, E, h, T) - 1.0
            # cantilever: 3 E I / (kappa G A L^2) = (E/(kappa G)) (h/L)^2 / 4; SS: 12 E I/(kappa G A L^2)
            expected = c * (E / ((5.0 / 6.0) * G_HAND)) * (h / L) ** 2
            assert ratio == pytest.approx(expected, rel=1e-10)


def test_beta1l_constants_are_roots() -> None:
    """beta_1 L: first roots of 1 + cos x cosh x (clamped-free) and sin x (pinned)."""
    x = ref.BETA1L_CLAMPED_FREE
    assert 1.0 + math.cos(x) * math.cosh(x) == pytest.approx(0.0, abs=1e-14)
    assert x == pytest.approx(1.8751040687, abs=1e-10)
    assert ref.BETA1L_PINNED_PINNED == math.pi


def test_euler_bernoulli_frequency_hand_values() -> None:
    """omega = (beta L)^2 sqrt(E I / (rho A L^4)); sqrt(EI/(rho A)) = sqrt(208333.3/24)."""
    c = math.sqrt(25e9 * I_HAND / (2400.0 * A_HAND))  # 93.169 m^2/s
    f_cf = ref.euler_bernoulli_frequency(L, E, RHO, H, T, "clamped-free")
    f_pp = ref.euler_bernoulli_frequency(L, E, RHO, H, T, "pinned-pinned")
    assert f_cf == pytest.approx(1.8751040687**2 * c / (2 * math.pi), rel=1e-10)
    assert f_pp == pytest.approx(math.pi**2 * c / (2 * math.pi), rel=1e-14)
    assert f_cf == pytest.approx(52.1368, abs=1e-4)
    assert f_pp == pytest.approx(146.3503, abs=1e-4)
    with pytest.raises(ValueError):
        ref.euler_bernoulli_frequency(L, E, RHO, H, T, "clamped-clamped")


@pytest.mark.parametrize("support", ["clamped-free", "pinned-pinned"])
def test_timoshenko_frequency_reduces_to_euler_bernoulli(support: str) -> None:
    """Without shear deformation and rotary inertia the Timoshenko equation is Euler-Bernoulli."""
    f_eb = ref.euler_bernoulli_frequency(L, E, RHO, H, T, support)
    f = ref.timoshenko_frequency(L, E, NU, RHO, H, T, support, kappa=math.inf, rotary_inertia=False)
    assert f == pytest.approx(f_eb, rel=1e-12)


@pytest.mark.parametrize("support", ["clamped-free", "pinned-pinned"])
def test_timoshenko_frequency_tends_to_euler_bernoulli_as_h_over_l_vanishes(support: str) -> None:
    """f_T / f_EB -> 1 from below as h/L -> 0, with 1 - f_T/f_EB ~ (h/L)^2."""
    defects = []
    for h in (0.1, 0.05, 0.025, 0.0125, 0.00625):
        f_t = ref.timoshenko_frequency(L, E, NU, RHO, h, T, support)
        f_eb = ref.euler_bernoulli_frequency(L, E, RHO, h, T, support)
        assert f_t < f_eb
        defects.append(1.0 - f_t / f_eb)
    defects = np.array(defects)
    assert np.all(np.diff(defects) < 0)
    assert defects[-1] < 1e-4
    # second order in h/L: halving h divides the defect by about 4
    assert np.allclose(defects[:-1] / defects[1:], 4.0, rtol=0.03)


def test_timoshenko_pinned_pinned_leading_order_correction() -> None:
    """Slender limit of the pinned-pinned quadratic: f_T/f_EB ~ 1 - (k r)^2 (1 + E/(kappa G)) / 2,
    k = pi/L, r^2 = I/A (Timoshenko's classical first-order correction)."""
    h = 0.01
    r2 = h**2 / 12.0
    k = math.pi / L
    expected = 1.0 - 0.5 * k**2 * r2 * (1.0 + E / ((5.0 / 6.0) * G_HAND))
    f_t = ref.timoshenko_frequency(L, E, NU, RHO, h, T, "pinned-pinned")
    f_eb = ref.euler_bernoulli_frequency(L, E, RHO, h, T, "pinned-pinned")
    assert f_t / f_eb == pytest.approx(expected, abs=5e-8)


def test_pinned_pinned_closed_form_matches_frequency_equation() -> None:
    """The determinant solver with pinned ends finds the closed-form root."""
    for h in (0.1, 0.3):
        for rot in (True, False):
            closed = ref.timoshenko_frequency_pinned_pinned(L, E, NU, RHO, h, T, rotary_inertia=rot)
            det = ref._timoshenko_frequency_det("pinned-pinned", L, E, NU, RHO, h, T, 5.0 / 6.0, rot)
            assert det == pytest.approx(closed, rel=1e-12)


def test_bottom_pins_rayleigh() -> None:
    """Pins at the bottom fibre: hand value of the Rayleigh factor, and the slender limit."""
    f_pp = ref.timoshenko_frequency_pinned_pinned(L, E, NU, RHO, H, T)
    f_b = ref.timoshenko_frequency_bottom_pins_rayleigh(L, E, NU, RHO, H, T)
    # Psi = k W / (1 + E I k^2 / (kappa G A)) = k W / 1.0237; r = (h Psi)^2 / 2 / (1 + (I/A) Psi^2)
    psi = (math.pi / L) / (1.0 + 25e9 * I_HAND * (math.pi / L) ** 2 / (5.0 / 6.0 * G_HAND * A_HAND))
    r = (H * psi) ** 2 / 2.0 / (1.0 + H**2 / 12.0 * psi**2)
    assert f_b / f_pp == pytest.approx(1.0 / math.sqrt(1.0 + r), rel=1e-5)  # rho I omega^2 neglected
    assert f_b < f_pp
    h = 1e-3
    assert ref.timoshenko_frequency_bottom_pins_rayleigh(L, E, NU, RHO, h, T) == pytest.approx(
        ref.euler_bernoulli_frequency(L, E, RHO, h, T, "pinned-pinned"), rel=1e-5
    )


def test_issue3_timoshenko_values() -> None:
    """Regression values for the issue-3 scenes (kappa = 5/6)."""
    refs = ref.beam_references()
    assert refs["cantilever"]["deflection_timoshenko"] == pytest.approx(1.61152e-3, rel=1e-12)
    assert refs["three_point_bending"]["deflection_timoshenko"] == pytest.approx(1.0288e-4, rel=1e-12)
    assert refs["cantilever"]["f1_timoshenko"] == pytest.approx(51.75030, abs=1e-4)
    assert refs["three_point_bending"]["f1_timoshenko"] == pytest.approx(144.08279, abs=1e-4)


def test_load_fe_references_committed() -> None:
    """The committed FE numbers are installed with the package and consistent with beam theory."""
    fe = ref.load_fe_references()
    beam = ref.beam_references()
    for scene, keys in (
        ("cantilever", ("uy_tip", "f1")),
        ("three_point_bending", ("d_mid", "uy_mid_raw", "f1_point_supports", "f1_section_pins", "f1_axis_pins")),
    ):
        for key in keys:
            entry = fe[scene][key]
            assert {"value", "rel_error", "unit", "definition", "converged", "sequence"} <= set(entry)
            assert len(entry["sequence"]) >= 3
            if entry["converged"]:
                assert entry["rel_error"] < 1e-5
    assert fe["cantilever"]["uy_tip"]["value"] < 0.0
    # cantilever: 2D clamped body within 1 % of Timoshenko; frequencies within 1 %
    assert -fe["cantilever"]["uy_tip"]["value"] == pytest.approx(beam["cantilever"]["deflection_timoshenko"], rel=1e-2)
    assert fe["cantilever"]["f1"]["value"] == pytest.approx(beam["cantilever"]["f1_timoshenko"], rel=1e-2)
    tpb = fe["three_point_bending"]
    assert -tpb["d_mid"]["value"] == pytest.approx(beam["three_point_bending"]["deflection_timoshenko"], rel=1e-2)
    assert tpb["f1_axis_pins"]["value"] == pytest.approx(beam["three_point_bending"]["f1_timoshenko"], rel=1e-3)
    # Rayleigh's estimate is an upper bound, within 0.2 %
    rayleigh = beam["three_point_bending"]["f1_timoshenko_bottom_pins_rayleigh"]
    assert rayleigh * (1 - 2e-3) < tpb["f1_section_pins"]["value"] < rayleigh
    assert not tpb["uy_mid_raw"]["converged"] and tpb["uy_mid_raw"]["value"] is None
    assert not tpb["f1_point_supports"]["converged"] and tpb["f1_point_supports"]["value"] is None
    for key in ("python", "numpy", "scipy", "scikit-fem"):
        assert key in fe["versions"]


def test_load_fe_references_path(tmp_path) -> None:
    """An explicit path is read instead of the packaged file."""
    p = tmp_path / "r.json"
    p.write_text('{"cantilever": {}}', encoding="utf-8")
    assert ref.load_fe_references(p) == {"cantilever": {}}


def test_deflection_relative_to_end_faces():
    from iem_post.references import deflection_relative_to_end_faces

    x, y = np.meshgrid(np.linspace(0.0, 1.0, 11), np.linspace(0.0, 0.1, 5))
    xy = np.column_stack([x.ravel(), y.ravel()])
    # a rigid translation and rotation about the y axis of the faces give no relative deflection
    u = np.column_stack([np.zeros(len(xy)), -3e-4 + 1e-4 * xy[:, 0]])
    assert abs(deflection_relative_to_end_faces(xy, u, 0.5, 0.0)) < 1e-15
    # a parabolic sag of -2e-4 at mid-span, plus end-face terms linear in y whose means are
    # -1e-5 (left) and -3e-5 (right) and which vanish at y = 0: d = -2e-4 + 2e-5
    sag = -2e-4 * 4 * xy[:, 0] * (1 - xy[:, 0])
    face = np.where(xy[:, 0] < 0.5, -1e-5, -3e-5) * (xy[:, 1] / 0.05)
    u = np.column_stack([np.zeros(len(xy)), sag + face])
    d = deflection_relative_to_end_faces(xy, u, 0.5, 0.0)
    assert d == pytest.approx(-1.8e-4, rel=1e-12)
