"""Fibre-section (plane-sections) reference for material-nonlinear beams.

Quasi-static, small-displacement load-deflection curves of the two beam scenes of issue 3
(see :mod:`iem_post.references` for the elastic values) made of a material whose uniaxial
law is the hyperbola

    ``sigma(eps) = E eps / (1 + E |eps| / f)``,  ``f = f_t`` for ``eps > 0``, ``f_c`` for ``eps < 0``

(tangent ``E`` at the origin, stress tending to ``f_t`` in tension and ``-f_c`` in
compression; defaults ``E = 25 GPa``, ``f_t = 3 MPa``, ``f_c = 30 MPa``, concrete-like).

Scenes (SI units, rectangle ``h`` deep and ``t`` wide, span ``L``):

* **Cantilever**: clamped at ``x = 0``, downward load ``P`` at the tip ``x = L``;
  quantity: tip deflection (positive downwards).
* **Simply supported beam**: supports at ``x = 0`` and ``x = L``, downward point load ``P``
  at mid-span; quantity: mid-span deflection relative to the supports (positive downwards).

The section (the law's primitives, the section integrals, the moment-curvature relation and
the ultimate moment) is :mod:`iem_post.fibre_section`, whose public names are re-exported
here; this module integrates it along the two beams.

Method and assumptions
----------------------
* Plane sections remain plane (Bernoulli); perfect bond, no tension stiffening, no
  softening: the hyperbola is the whole uniaxial law, used in tension and compression.
* Monotonic (proportional) loading: the secant law is path independent, no unloading.
* Small displacements (deflections by the unit-load method on the undeformed beam).
* Shear deformation, when asked for, is elastic Timoshenko shear, ``G = E / (2 (1 + nu))``,
  shear factor ``kappa`` (default 5/6): an additive term ``P L / (kappa G A)``
  (cantilever) or ``P L / (4 kappa G A)`` (simply supported).  The bending part alone is
  the default.

Ultimate load.  With ``M_u`` the limit of the section's moment as the curvature grows
without bound (:func:`ultimate_moment`),
``P_u = M_u / L`` (cantilever), ``4 M_u / L`` (simply supported).

Deflection.  Unit-load method: ``delta = int k(x) m(x) dx`` with ``m`` the moment of a unit
load at the measured point.  Since ``M(x)`` is linear in ``x`` on each half of the
integration, the substitution ``mu = |M(x)|`` turns both scenes into one integral,

    ``delta_b = c / P^2 * J(M_max)``,  ``J(M_max) = int_0^M_max k(mu) mu dmu``,

with ``c = 1``, ``M_max = P L`` (cantilever) and ``c = 4``, ``M_max = P L / 4`` (simply
supported).  ``J`` is computed by adaptive Gauss-Legendre quadrature (a panel is accepted
when its order-``n`` rule and the sum of the rules on its two halves agree within its share
of ``rtol``); ``k(mu)`` is analytic on ``[0, M_max]`` for ``M_max < M_u`` but steep near
``M_u``, where the refinement concentrates.  Elastic limit: ``k = mu / (E I)`` gives
``P L^3 / (3 E I)`` and ``P L^3 / (48 E I)``.

Only numpy is needed.
"""

from __future__ import annotations

import math
from typing import Callable, Dict, Tuple

import numpy as np

from .fibre_section import (
    FIBRE_DEFAULTS,
    ArrayLike,
    curvature_for_moment,
    hyperbolic_stress,
    neutral_axis_strain,
    section_forces,
    section_moment,
    stress_primitives,
    ultimate_moment,
)
from .references import KAPPA_RECTANGLE, section, shear_modulus

__all__ = [
    "FIBRE_DEFAULTS",
    "SCENES",
    "hyperbolic_stress",
    "stress_primitives",
    "section_forces",
    "section_moment",
    "neutral_axis_strain",
    "curvature_for_moment",
    "ultimate_moment",
    "ultimate_load",
    "bending_deflection",
    "cantilever_tip_deflection",
    "simply_supported_midspan_deflection",
    "load_deflection_curve",
]

#: The two scenes understood by :func:`load_deflection_curve` and :func:`ultimate_load`.
SCENES = ("cantilever", "simply_supported")

_E = FIBRE_DEFAULTS["E"]
_NU = FIBRE_DEFAULTS["nu"]
_FT = FIBRE_DEFAULTS["f_t"]
_FC = FIBRE_DEFAULTS["f_c"]
_L = FIBRE_DEFAULTS["L"]
_H = FIBRE_DEFAULTS["h"]
_T = FIBRE_DEFAULTS["t"]


# ---------------------------------------------------------------------------
# Deflections (unit-load method)
# ---------------------------------------------------------------------------


def _check_scene(scene: str) -> None:
    if scene not in SCENES:
        raise ValueError(f"scene must be one of {SCENES}, not {scene!r}")


def ultimate_load(
    scene: str,
    L: float = _L,
    f_t: float = _FT,
    f_c: float = _FC,
    h: float = _H,
    t: float = _T,
) -> float:
    """Load at which the peak moment reaches ``M_u``: ``M_u / L`` (cantilever, peak at the
    clamp) or ``4 M_u / L`` (simply supported, peak at mid-span)."""
    _check_scene(scene)
    M_u = ultimate_moment(f_t, f_c, h, t)
    return M_u / L if scene == "cantilever" else 4.0 * M_u / L


def _adaptive_gauss(
    fun: Callable[[np.ndarray], np.ndarray], a: float, b: float, rtol: float, order: int = 10
) -> Tuple[float, float]:
    """``int_a^b fun`` by adaptive composite Gauss-Legendre; returns (value, error estimate).

    Each panel is integrated with the ``order``-point rule and with the same rule on its
    two halves; a panel is accepted (with the halves' value) when the two differ by less
    than its length's share of ``rtol |integral|``, else it is split.  The returned error
    estimate is the sum of those differences, a conservative bound on the error of the
    (more accurate) accepted values.
    """
    xi, w = np.polynomial.legendre.leggauss(order)
    lo = np.linspace(a, b, 5)[:-1]
    hi = np.linspace(a, b, 5)[1:]
    total = 0.0
    err = 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        ends = np.stack([lo, lo, mid], axis=1), np.stack([hi, mid, hi], axis=1)
        c, r = 0.5 * (ends[0] + ends[1]), 0.5 * (ends[1] - ends[0])
        x = c[..., None] + r[..., None] * xi
        vals = np.sum(w * fun(x.ravel()).reshape(x.shape), axis=-1) * r
        whole, halves = vals[:, 0], vals[:, 1] + vals[:, 2]
        diff = np.abs(whole - halves)
        estimate = abs(total + np.sum(halves))
        ok = diff <= rtol * estimate * (hi - lo) / (b - a)
        total += float(np.sum(halves[ok]))
        err += float(np.sum(diff[ok]))
        if np.all(ok):
            return total, err
        lo, hi = np.concatenate([lo[~ok], mid[~ok]]), np.concatenate([mid[~ok], hi[~ok]])
    raise RuntimeError("adaptive quadrature did not converge")


def bending_deflection(
    scene: str,
    P: float,
    L: float = _L,
    E: float = _E,
    f_t: float = _FT,
    f_c: float = _FC,
    h: float = _H,
    t: float = _T,
    rtol: float = 1e-11,
    order: int = 10,
) -> Tuple[float, float]:
    """Bending part of the measured deflection and its quadrature error estimate.

    Cantilever tip (``scene="cantilever"``) or simply supported mid-span deflection, positive
    in the direction of ``P`` (odd in ``P``), by the unit-load method
    ``delta = int k(x) m(x) dx = c / P^2 int_0^M_max k(mu) mu dmu`` (``c = 1``,
    ``M_max = P L``; ``c = 4``, ``M_max = P L / 4``), adaptive Gauss-Legendre to ``rtol``.
    ``|M_max|`` must be below the ultimate moment.
    """
    _check_scene(scene)
    if P == 0.0:
        return 0.0, 0.0
    Pa = abs(P)
    c, M_max = (1.0, Pa * L) if scene == "cantilever" else (4.0, 0.25 * Pa * L)
    M_u = ultimate_moment(f_t, f_c, h, t)
    if M_max >= M_u:
        raise ValueError(f"peak moment {M_max:.6g} is not below M_u = {M_u:.6g}")

    def integrand(mu: np.ndarray) -> np.ndarray:
        return np.asarray(curvature_for_moment(mu, E, f_t, f_c, h, t)) * mu

    J, err = _adaptive_gauss(integrand, 0.0, M_max, rtol, order)
    return math.copysign(c * J / Pa**2, P), c * err / Pa**2


def _shear_deflection(
    scene: str, P: float, L: float, E: float, nu: float, h: float, t: float, kappa: float
) -> float:
    """Elastic Timoshenko shear deflection ``P L / (kappa G A)`` or ``P L / (4 kappa G A)``."""
    A, _ = section(h, t)
    base = P * L / (kappa * shear_modulus(E, nu) * A)
    return base if scene == "cantilever" else 0.25 * base


def cantilever_tip_deflection(
    P: float,
    L: float = _L,
    E: float = _E,
    f_t: float = _FT,
    f_c: float = _FC,
    h: float = _H,
    t: float = _T,
    nu: float = _NU,
    kappa: float = KAPPA_RECTANGLE,
    shear: bool = False,
    rtol: float = 1e-11,
) -> float:
    """Tip deflection (positive downwards, the direction of ``P``) of the cantilever
    clamped at ``x = 0`` with a tip load ``P`` at ``x = L``, fibre-section bending.

    ``M(x) = -P (L - x)`` (hogging), ``m(x) = -(L - x)``; the elastic limit is
    ``P L^3 / (3 E I)``.  ``shear=True`` adds the elastic shear term ``P L / (kappa G A)``.
    ``P L`` must be below :func:`ultimate_moment`.
    """
    delta, _ = bending_deflection("cantilever", P, L, E, f_t, f_c, h, t, rtol)
    if shear:
        delta += _shear_deflection("cantilever", P, L, E, nu, h, t, kappa)
    return delta


def simply_supported_midspan_deflection(
    P: float,
    L: float = _L,
    E: float = _E,
    f_t: float = _FT,
    f_c: float = _FC,
    h: float = _H,
    t: float = _T,
    nu: float = _NU,
    kappa: float = KAPPA_RECTANGLE,
    shear: bool = False,
    rtol: float = 1e-11,
) -> float:
    """Mid-span deflection relative to the supports (positive downwards, the direction of
    ``P``) of the simply supported beam with a central point load ``P``, fibre-section
    bending.

    ``M(x) = P x / 2`` for ``x <= L/2`` (sagging, symmetric), ``m(x) = x / 2``; the elastic
    limit is ``P L^3 / (48 E I)``.  ``shear=True`` adds ``P L / (4 kappa G A)``.
    ``P L / 4`` must be below :func:`ultimate_moment`.
    """
    delta, _ = bending_deflection("simply_supported", P, L, E, f_t, f_c, h, t, rtol)
    if shear:
        delta += _shear_deflection("simply_supported", P, L, E, nu, h, t, kappa)
    return delta


def load_deflection_curve(
    scene: str,
    P_values: ArrayLike,
    L: float = _L,
    E: float = _E,
    f_t: float = _FT,
    f_c: float = _FC,
    h: float = _H,
    t: float = _T,
    nu: float = _NU,
    kappa: float = KAPPA_RECTANGLE,
    rtol: float = 1e-11,
) -> Dict[str, np.ndarray]:
    """Load-deflection curve of ``scene`` (``"cantilever"`` or ``"simply_supported"``).

    Returns arrays over ``P_values`` (loads below the ultimate load, see
    :func:`ultimate_load`):

    * ``P``, ``P_over_Pu`` (and the scalar ``P_u`` as a 0-d array), ``M_max`` (peak moment);
    * ``bending`` (fibre-section bending deflection), ``shear`` (elastic shear term),
      ``deflection`` (their sum), ``quadrature_error`` (estimate for ``bending``);
    * ``elastic_bending`` (Euler-Bernoulli) and ``elastic`` (Timoshenko) deflections;
    * ``ratio_bending = bending / elastic_bending`` and ``ratio = deflection / elastic``.
    """
    _check_scene(scene)
    P = np.atleast_1d(np.asarray(P_values, dtype=float))
    P_u = ultimate_load(scene, L, f_t, f_c, h, t)
    bend = np.empty_like(P)
    qerr = np.empty_like(P)
    for i, p in enumerate(P):
        bend[i], qerr[i] = bending_deflection(scene, float(p), L, E, f_t, f_c, h, t, rtol)
    shear = np.array([_shear_deflection(scene, float(p), L, E, nu, h, t, kappa) for p in P])
    _, I = section(h, t)
    el_bend = P * L**3 / ((3.0 if scene == "cantilever" else 48.0) * E * I)
    el = el_bend + shear
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio_bending = np.where(P != 0.0, bend / el_bend, 1.0)
        ratio = np.where(P != 0.0, (bend + shear) / el, 1.0)
    return {
        "P": P,
        "P_u": np.asarray(P_u),
        "P_over_Pu": P / P_u,
        "M_max": np.abs(P) * (L if scene == "cantilever" else 0.25 * L),
        "bending": bend,
        "shear": shear,
        "deflection": bend + shear,
        "quadrature_error": qerr,
        "elastic_bending": el_bend,
        "elastic": el,
        "ratio_bending": ratio_bending,
        "ratio": ratio,
    }
