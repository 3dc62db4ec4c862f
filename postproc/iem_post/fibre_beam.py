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

Sign conventions
----------------
``y`` is measured from mid-depth, positive up; ``x`` along the axis.  The axial strain of
the fibre at ``y`` is ``eps(y) = eps0 - k y`` (``eps0``: strain at the centroid).  The
curvature ``k > 0`` and the moment ``M = -t * int sigma y dy > 0`` are **sagging** (bottom
fibre in tension).  The cantilever's moment ``M(x) = -P (L - x)`` is hogging (``k < 0``);
the simply supported beam's ``M(x) = P x / 2`` (``x <= L/2``, symmetric) is sagging.  The
rectangle is symmetric about mid-depth, so a hogging section state is the mirror image of
the sagging one: ``M(-k) = -M(k)`` and ``eps0(-k) = eps0(k)``.

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

Section integrals in closed form.  With ``x = E |eps| / f`` and
``phi1(x) = x - ln(1 + x)``, ``phi2(x) = x^2/2 - x + ln(1 + x)`` (evaluated by their series
for small ``x``, so no cancellation), the primitives of the law are

    ``F1(eps) = int_0^eps sigma de   = (f^2 / E) phi1(x)``  (even in the sense ``>= 0``),
    ``F2(eps) = int_0^eps sigma e de = sign(eps) (f^3 / E^2) phi2(x)``,

and, substituting ``e = eps0 - k y`` (``e_b = eps0 + k h/2`` bottom, ``e_t = eps0 - k h/2``
top),

    ``N = (t / k) [F1(e_b) - F1(e_t)]``,
    ``M = -(t / k^2) [eps0 (F1(e_b) - F1(e_t)) - (F2(e_b) - F2(e_t))]``.

``N = 0`` is thus ``F1(e_b) = F1(e_t)``: for a sagging state with bottom strain
``e_b >= 0`` the top strain ``e_t = -u`` follows from ``phi1(E u / f_c) = (f_t / f_c)^2
phi1(E e_b / f_t)`` (a convex monotone equation, solved by Newton from an upper bound), and
then ``k = (e_b + u) / h``, ``eps0 = (e_b - u) / 2`` and
``M = (t / k^2) [G(e_b; f_t) + G(u; f_c)]`` with ``G(u; f) = (f^3 / E^2) phi2(E u / f)``:
a sum of positive terms.  The sagging state is therefore parametrised by ``e_b``; ``k`` and
``M`` both increase with it.  :func:`section_moment` finds ``e_b`` (hence ``eps0`` with
``N = 0``) for a given ``k``, :func:`curvature_for_moment` finds it for a given ``M``; both
by Newton's method safeguarded by a bracket (bisection when a step leaves it), vectorised
over arrays.  Gauss-Legendre quadrature over the depth (split at the neutral axis, where
the law's second derivative jumps, with panels graded towards it) is available as an independent check
(:func:`section_forces` with ``method="quadrature"``).

Ultimate moment.  As ``k -> infinity`` the stress block becomes rectangular: ``f_t`` over
a tension depth ``d_t`` and ``f_c`` over ``d_c = h - d_t``; ``N = 0`` gives
``d_t = h f_c / (f_t + f_c)``, the lever arm of the two resultants is ``h / 2``, so

    ``M_u = t h^2 f_t f_c / (2 (f_t + f_c))``

(``t h^2 f / 4``, the plastic moment, when ``f_t = f_c = f``).  The approach is slow: the
stress deficit ``f - sigma ~ f^2 / (E |eps|)`` next to the neutral axis gives, about the
neutral axis, ``M_u - M(k) = t h f_t f_c / (E k) (1 + O(ln(k) / k))`` (the ``ln(k) / k``
force deficits act at the neutral axis, and the shift of the axis they cause changes the
moment only to higher order).  For small ``k``,
``M(k) = E I k - t E^2 h^4 (1 / f_t + 1 / f_c) k^2 / 64 + O(k^3)``.
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
from typing import Callable, Dict, Tuple, Union

import numpy as np

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

ArrayLike = Union[float, np.ndarray]

#: Default parameters (SI units): geometry of the issue-3 scenes, concrete-like strengths.
FIBRE_DEFAULTS: Dict[str, float] = {
    "E": 25e9,  # Pa
    "nu": 0.2,
    "f_t": 3.0e6,  # Pa, tensile strength (asymptote of the hyperbola)
    "f_c": 30.0e6,  # Pa, compressive strength (magnitude)
    "L": 1.0,  # m
    "h": 0.1,  # m, depth
    "t": 0.1,  # m, width (thickness)
}

#: The two scenes understood by :func:`load_deflection_curve` and :func:`ultimate_load`.
SCENES = ("cantilever", "simply_supported")

_E = FIBRE_DEFAULTS["E"]
_NU = FIBRE_DEFAULTS["nu"]
_FT = FIBRE_DEFAULTS["f_t"]
_FC = FIBRE_DEFAULTS["f_c"]
_L = FIBRE_DEFAULTS["L"]
_H = FIBRE_DEFAULTS["h"]
_T = FIBRE_DEFAULTS["t"]

_EPS = np.finfo(float).eps
_SERIES_LIMIT = 0.25  # phi1, phi2 by their series below this argument
_SERIES_TERMS = 32  # 0.25^29 < 4e-18: full double precision


# ---------------------------------------------------------------------------
# Uniaxial law and its primitives
# ---------------------------------------------------------------------------


def _as_output(x: np.ndarray) -> ArrayLike:
    """A 0-d array as a float, anything else unchanged."""
    return float(x) if np.ndim(x) == 0 else x


def hyperbolic_stress(eps: ArrayLike, E: float = _E, f_t: float = _FT, f_c: float = _FC) -> ArrayLike:
    """Uniaxial stress ``sigma = E eps / (1 + E |eps| / f)``, ``f = f_t`` (tension, ``eps > 0``)
    or ``f_c`` (compression, ``eps < 0``); ``f_t``, ``f_c`` are positive magnitudes.

    Initial tangent ``E``, odd-like shape with asymptotes ``+f_t`` and ``-f_c``; monotone
    (secant) law, valid for monotonic loading only.
    """
    e = np.asarray(eps, dtype=float)
    f = np.where(e > 0.0, f_t, f_c)
    return _as_output(E * e / (1.0 + E * np.abs(e) / f))


def _series(x: np.ndarray, first: int, sign0: float) -> np.ndarray:
    """``sum_{n >= first} sign0 (-1)^(n-first) x^n / n`` by Horner's rule (small ``x``)."""
    acc = np.full_like(x, 1.0 / (first + _SERIES_TERMS - 1))
    for m in range(_SERIES_TERMS - 2, -1, -1):
        acc = acc * (-x) + 1.0 / (first + m)
    return sign0 * x**first * acc


def _phi1(x: np.ndarray) -> np.ndarray:
    """``x - ln(1 + x)`` for ``x >= 0`` without cancellation (``~ x^2 / 2`` for small ``x``)."""
    x = np.asarray(x, dtype=float)
    small = x < _SERIES_LIMIT
    out = np.empty_like(x)
    out[small] = _series(x[small], 2, 1.0)
    xl = x[~small]
    out[~small] = xl - np.log1p(xl)
    return out


def _phi2(x: np.ndarray) -> np.ndarray:
    """``x^2 / 2 - x + ln(1 + x)`` for ``x >= 0`` without cancellation (``~ x^3 / 3``)."""
    x = np.asarray(x, dtype=float)
    small = x < _SERIES_LIMIT
    out = np.empty_like(x)
    out[small] = _series(x[small], 3, 1.0)
    xl = x[~small]
    out[~small] = 0.5 * xl * xl - xl + np.log1p(xl)
    return out


def stress_primitives(
    eps: ArrayLike, E: float = _E, f_t: float = _FT, f_c: float = _FC
) -> Tuple[ArrayLike, ArrayLike]:
    """Closed-form primitives of the hyperbolic law, ``(F1, F2)``:

    ``F1(eps) = int_0^eps sigma(e) de = (f^2 / E) [x - ln(1 + x)]`` (``>= 0``) and
    ``F2(eps) = int_0^eps sigma(e) e de = sign(eps) (f^3 / E^2) [x^2/2 - x + ln(1 + x)]``,
    with ``x = E |eps| / f`` and ``f`` chosen by the sign of ``eps``.
    """
    e = np.asarray(eps, dtype=float)
    f = np.where(e > 0.0, f_t, f_c)
    x = E * np.abs(e) / f
    F1 = f * f / E * _phi1(x)
    F2 = np.sign(e) * f**3 / E**2 * _phi2(x)
    return _as_output(F1), _as_output(F2)


# ---------------------------------------------------------------------------
# Section integrals
# ---------------------------------------------------------------------------


def _gauss_depth(
    eps0: np.ndarray,
    k: np.ndarray,
    E: float,
    f_t: float,
    f_c: float,
    h: float,
    t: float,
    n: int,
    n_panels: int = 1,
) -> Tuple[np.ndarray, np.ndarray]:
    """``N``, ``M`` by composite ``n``-point Gauss-Legendre on each side of the neutral axis,
    ``n_panels`` panels per side graded geometrically (ratio 1/2) towards the neutral axis."""
    xi, w = np.polynomial.legendre.leggauss(n)
    eps0, k = np.broadcast_arrays(np.asarray(eps0, dtype=float), np.asarray(k, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        y_n = np.where(k != 0.0, eps0 / k, np.inf)
    y_c = np.clip(y_n, -0.5 * h, 0.5 * h)[..., None]
    # relative breakpoints 0, 2^-(n_panels-1), ..., 1/2, 1 measured from the neutral axis
    rel = np.concatenate([[0.0], 0.5 ** np.arange(n_panels - 1, -1, -1, dtype=float)])
    N = np.zeros(eps0.shape)
    M = np.zeros(eps0.shape)
    for end in (-0.5 * h, 0.5 * h):
        bp = y_c + (end - y_c) * rel  # shape (..., n_panels + 1)
        mid = 0.5 * (bp[..., 1:] + bp[..., :-1])[..., None]
        half = 0.5 * (bp[..., 1:] - bp[..., :-1])[..., None]  # signed
        y = mid + half * xi
        s = np.asarray(hyperbolic_stress(eps0[..., None, None] - k[..., None, None] * y, E, f_t, f_c))
        N = N + t * np.sum(w * np.abs(half) * s, axis=(-2, -1))
        M = M - t * np.sum(w * np.abs(half) * s * y, axis=(-2, -1))
    return N, M


def section_forces(
    eps0: ArrayLike,
    k: ArrayLike,
    E: float = _E,
    f_t: float = _FT,
    f_c: float = _FC,
    h: float = _H,
    t: float = _T,
    method: str = "closed",
    n_gauss: int = 64,
    n_panels: int = 1,
) -> Tuple[ArrayLike, ArrayLike]:
    """Axial force and bending moment ``(N, M)`` of the rectangle for the strain field
    ``eps(y) = eps0 - k y`` (``y`` up from mid-depth, ``k > 0`` sagging).

    ``N = t int sigma dy`` (tension positive), ``M = -t int sigma y dy`` (sagging positive),
    both about the centroid.  ``method="closed"`` uses the closed form (module docstring);
    where ``|k| h < 0.1 |eps0|`` (the closed form would cancel) it falls back to quadrature.
    ``method="quadrature"`` uses ``n_gauss``-point Gauss-Legendre on each side of the
    neutral axis, on ``n_panels`` panels per side graded geometrically towards it: the
    independent check.  One panel is exact to round-off while ``|k| h`` is below about
    ``100 f_t / E``; beyond, the stress varies over a depth ``~ f / (E |k|)`` next to the
    neutral axis and about ``log2(E |k| h / f_t)`` graded panels are needed.
    """
    e0 = np.asarray(eps0, dtype=float)
    kk = np.asarray(k, dtype=float)
    e0, kk = np.broadcast_arrays(e0, kk)
    if method == "quadrature":
        N, M = _gauss_depth(e0, kk, E, f_t, f_c, h, t, n_gauss, n_panels)
        return _as_output(N), _as_output(M)
    if method != "closed":
        raise ValueError(f"method must be 'closed' or 'quadrature', not {method!r}")
    use_quad = np.abs(kk) * h < 0.1 * np.abs(e0)
    use_quad |= kk == 0.0
    ks = np.where(use_quad, 1.0, kk)  # dummy curvature where quadrature is used
    e_b = e0 + 0.5 * ks * h
    e_t = e0 - 0.5 * ks * h
    F1b, F2b = stress_primitives(e_b, E, f_t, f_c)
    F1t, F2t = stress_primitives(e_t, E, f_t, f_c)
    dF1 = np.asarray(F1b) - np.asarray(F1t)
    dF2 = np.asarray(F2b) - np.asarray(F2t)
    N = t / ks * dF1
    M = -t / ks**2 * (e0 * dF1 - dF2)
    if np.any(use_quad):
        Nq, Mq = _gauss_depth(e0[use_quad], kk[use_quad], E, f_t, f_c, h, t, n_gauss)
        N = np.array(N)
        M = np.array(M)
        N[use_quad] = Nq
        M[use_quad] = Mq
    return _as_output(N), _as_output(M)


# ---------------------------------------------------------------------------
# Sagging state parametrised by the bottom (tensile) strain
# ---------------------------------------------------------------------------


def _inverse_phi1(c: np.ndarray) -> np.ndarray:
    """``x >= 0`` with ``x - ln(1 + x) = c`` (``c >= 0``), vectorised.

    Newton from the upper bound ``c + sqrt(c^2 + 2 c)`` (from ``phi1(x) >= x^2 / (2 (1 + x))``);
    ``phi1`` is increasing and convex, so the iterates decrease monotonically to the root.
    """
    c = np.asarray(c, dtype=float)
    x = c + np.sqrt(c * c + 2.0 * c)
    for _ in range(100):
        with np.errstate(divide="ignore", invalid="ignore"):
            step = (_phi1(x) - c) * (1.0 + x) / x
        step = np.where(x > 0.0, step, 0.0)
        x = np.maximum(x - step, 0.0)
        if np.all(np.abs(step) <= 4.0 * _EPS * x):
            break
    return x


def _sagging_state(
    e_b: np.ndarray, E: float, f_t: float, f_c: float, h: float, t: float
) -> Dict[str, np.ndarray]:
    """Section state with ``N = 0`` and bottom strain ``e_b >= 0`` (sagging).

    Returns ``u`` (magnitude of the top, compressive strain), ``k``, ``eps0``, ``M`` and the
    derivatives ``dk`` = dk/de_b, ``dM`` = dM/de_b.
    """
    e_b = np.asarray(e_b, dtype=float)
    x_b = E * e_b / f_t
    x_c = _inverse_phi1((f_t / f_c) ** 2 * _phi1(x_b))
    u = f_c * x_c / E
    k = (e_b + u) / h
    S = t * (f_t**3 * _phi2(x_b) + f_c**3 * _phi2(x_c)) / E**2
    sig_b = f_t * x_b / (1.0 + x_b)
    sig_c = f_c * x_c / (1.0 + x_c)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(sig_c > 0.0, sig_b / sig_c, 1.0)  # du/de_b (-> 1 as e_b -> 0)
        dk = (1.0 + ratio) / h
        M = np.where(k > 0.0, S / k**2, 0.0)
        # d/de_b [G(e_b; f_t) + G(u; f_c)] = sig_b e_b + sig_c u du/de_b = sig_b k h
        dM = np.where(k > 0.0, t * sig_b * h / k - 2.0 * S / k**3 * dk, E * t * h**2 / 6.0)
    return {"u": u, "k": k, "eps0": 0.5 * (e_b - u), "M": M, "dk": dk, "dM": dM}


def _bracketed_newton(
    fun: Callable[[np.ndarray], Tuple[np.ndarray, np.ndarray]],
    lo: np.ndarray,
    hi: np.ndarray,
    x0: np.ndarray,
    scale: np.ndarray,
    rtol: float = 1e-14,
    maxiter: int = 200,
) -> np.ndarray:
    """Root of the increasing ``g`` (``fun(x) = (g, g')``) in ``[lo, hi]``, elementwise.

    Newton steps that leave the current bracket (or are not finite) are replaced by
    bisection, so the iteration cannot fail; it stops when the step is below
    ``rtol |x|`` or ``|g| <= 4 eps scale`` everywhere.
    """
    x = np.clip(np.asarray(x0, dtype=float), lo, hi)
    lo = np.array(lo, dtype=float)
    hi = np.array(hi, dtype=float)
    for _ in range(maxiter):
        g, dg = fun(x)
        lo = np.where(g < 0.0, x, lo)
        hi = np.where(g > 0.0, x, hi)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            x_new = x - g / dg
        bad = ~np.isfinite(x_new) | (x_new < lo) | (x_new > hi)
        x_new = np.where(bad, 0.5 * (lo + hi), x_new)
        done = (np.abs(x_new - x) <= rtol * np.abs(x_new)) | (np.abs(g) <= 4.0 * _EPS * scale)
        x = x_new
        if np.all(done):
            break
    return x


def _solve_tension_strain_for_curvature(
    k: np.ndarray, E: float, f_t: float, f_c: float, h: float, t: float
) -> np.ndarray:
    """``e_b`` with ``e_b + u(e_b) = k h`` (``k >= 0``); ``u`` from ``N = 0``."""
    kh = np.asarray(k, dtype=float) * h

    def fun(e_b: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        s = _sagging_state(e_b, E, f_t, f_c, h, t)
        return s["k"] * h - kh, s["dk"] * h

    return _bracketed_newton(fun, np.zeros_like(kh), kh, 0.5 * kh, kh)


def _section_state(
    k: ArrayLike, E: float, f_t: float, f_c: float, h: float, t: float
) -> Tuple[np.ndarray, np.ndarray]:
    """``(eps0, M)`` with ``N = 0`` for curvature ``k`` (any sign; mirror for hogging)."""
    kk = np.asarray(k, dtype=float)
    if not np.all(np.isfinite(kk)):
        raise ValueError("curvature must be finite")
    e_b = _solve_tension_strain_for_curvature(np.abs(kk), E, f_t, f_c, h, t)
    s = _sagging_state(e_b, E, f_t, f_c, h, t)
    return s["eps0"], np.sign(kk) * s["M"]


def section_moment(
    k: ArrayLike,
    E: float = _E,
    f_t: float = _FT,
    f_c: float = _FC,
    h: float = _H,
    t: float = _T,
) -> ArrayLike:
    """Bending moment ``M(k)`` of the rectangle at curvature ``k`` with zero axial force.

    Sagging positive (``k > 0``: bottom in tension); ``M(-k) = -M(k)``.  The centroidal
    strain ``eps0`` that makes ``N = 0`` is found first (:func:`neutral_axis_strain`), then
    ``M`` follows in closed form.  ``M`` increases monotonically with ``|k|``, starts as
    ``E I k`` and tends to :func:`ultimate_moment`.
    """
    return _as_output(_section_state(k, E, f_t, f_c, h, t)[1])


def neutral_axis_strain(
    k: ArrayLike,
    E: float = _E,
    f_t: float = _FT,
    f_c: float = _FC,
    h: float = _H,
    t: float = _T,
) -> ArrayLike:
    """Axial strain at the centroid ``eps0(k)`` that makes the axial force vanish.

    Even in ``k``; positive (neutral axis above mid-depth, towards the stiffer compression
    side) when ``f_t < f_c``, zero when ``f_t = f_c``.  The neutral axis is at
    ``y = eps0 / k``.
    """
    return _as_output(_section_state(k, E, f_t, f_c, h, t)[0])


def ultimate_moment(f_t: float = _FT, f_c: float = _FC, h: float = _H, t: float = _T) -> float:
    """Limit of ``M(k)`` as ``k -> infinity``: ``M_u = t h^2 f_t f_c / (2 (f_t + f_c))``.

    Rectangular stress blocks ``f_t`` (depth ``h f_c / (f_t + f_c)``) and ``f_c`` (depth
    ``h f_t / (f_t + f_c)``) in equilibrium, lever arm ``h / 2``.  Independent of ``E``.
    The approach is ``M_u - M(k) ~ t h f_t f_c / (E k)`` (module docstring).
    """
    return t * h * h * f_t * f_c / (2.0 * (f_t + f_c))


def curvature_for_moment(
    M: ArrayLike,
    E: float = _E,
    f_t: float = _FT,
    f_c: float = _FC,
    h: float = _H,
    t: float = _T,
) -> ArrayLike:
    """Curvature ``k(M)``, the inverse of :func:`section_moment` (odd in ``M``).

    ``|M|`` must be below :func:`ultimate_moment` (``ValueError`` otherwise).  Solved for the
    bottom strain of the sagging state by bracketed, safeguarded Newton: the bracket
    ``[0, e_hi]`` has ``e_hi`` grown geometrically until ``M(e_hi) >= |M|``.
    """
    MM = np.asarray(M, dtype=float)
    target = np.abs(MM)
    M_u = ultimate_moment(f_t, f_c, h, t)
    if not np.all(target < M_u):
        raise ValueError(f"|M| must be below the ultimate moment M_u = {M_u:.6g}")
    _, I = section(h, t)
    e_el = target / (E * I) * h  # k_el h: the curvature is at least elastic (secant <= E)
    hi = np.array(np.maximum(e_el, 1e-300), dtype=float)
    for _ in range(200):
        low = _sagging_state(hi, E, f_t, f_c, h, t)["M"] < target
        if not np.any(low):
            break
        hi = np.where(low, 4.0 * hi, hi)

    def fun(e_b: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        s = _sagging_state(e_b, E, f_t, f_c, h, t)
        return s["M"] - target, s["dM"]

    e_b = _bracketed_newton(fun, np.zeros_like(hi), hi, 0.5 * e_el, target)
    k = _sagging_state(e_b, E, f_t, f_c, h, t)["k"]
    return _as_output(np.sign(MM) * k)


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
