"""Fibre section of a rectangle made of a hyperbolic material: moment and curvature.

The section model under :mod:`iem_post.fibre_beam` (which re-exports every public name of
this module): a rectangle ``h`` deep and ``t`` wide (SI units) made of a material whose
uniaxial law is the hyperbola

    ``sigma(eps) = E eps / (1 + E |eps| / f)``,  ``f = f_t`` for ``eps > 0``, ``f_c`` for ``eps < 0``

(tangent ``E`` at the origin, stress tending to ``f_t`` in tension and ``-f_c`` in
compression; defaults ``E = 25 GPa``, ``f_t = 3 MPa``, ``f_c = 30 MPa``, concrete-like).

Sign conventions
----------------
``y`` is measured from mid-depth, positive up; ``x`` along the axis.  The axial strain of
the fibre at ``y`` is ``eps(y) = eps0 - k y`` (``eps0``: strain at the centroid).  The
curvature ``k > 0`` and the moment ``M = -t * int sigma y dy > 0`` are **sagging** (bottom
fibre in tension).  The cantilever's moment ``M(x) = -P (L - x)`` is hogging (``k < 0``);
the simply supported beam's ``M(x) = P x / 2`` (``x <= L/2``, symmetric) is sagging.  The
rectangle is symmetric about mid-depth, so a hogging section state is the mirror image of
the sagging one: ``M(-k) = -M(k)`` and ``eps0(-k) = eps0(k)``.

Assumptions
-----------
* Plane sections remain plane (Bernoulli); perfect bond, no tension stiffening, no
  softening: the hyperbola is the whole uniaxial law, used in tension and compression.
* Monotonic (proportional) loading: the secant law is path independent, no unloading.

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

Only numpy is needed.
"""

from __future__ import annotations

from typing import Callable, Dict, Tuple, Union

import numpy as np

from .references import section

__all__ = [
    "FIBRE_DEFAULTS",
    "hyperbolic_stress",
    "stress_primitives",
    "section_forces",
    "section_moment",
    "neutral_axis_strain",
    "curvature_for_moment",
    "ultimate_moment",
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

_E = FIBRE_DEFAULTS["E"]
_FT = FIBRE_DEFAULTS["f_t"]
_FC = FIBRE_DEFAULTS["f_c"]
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
