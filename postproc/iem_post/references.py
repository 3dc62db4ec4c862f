"""Closed-form beam references and the committed finite-element references (issue 3).

Beam-theory values for the two accuracy scenes of issue 3 (plane stress, SI units):

* **Cantilever**: body ``[0, L] x [0, h]``, thickness ``t``, left face clamped, shear load
  ``P`` on the right face; quantities: tip deflection and first natural frequency.
* **Simply supported beam** (three-point bending): supports at the bottom corners, point
  load ``P`` at mid-span on the top; quantities: mid-span deflection and first frequency.

Cross-section: rectangle of depth ``h`` and width ``t``, so ``A = t h`` and
``I = t h^3 / 12``; ``G = E / (2 (1 + nu))``.

Shear correction factor: ``kappa = 5/6`` for a rectangle (:data:`KAPPA_RECTANGLE`; the
classical value, exact for the parabolic shear-stress distribution in energy and the one
used in most textbook Timoshenko formulas).  Cowper's value ``10 (1 + nu) / (12 + 11 nu)``
(0.845 for ``nu = 0.2``) is available as :func:`kappa_cowper` and can be passed as
``kappa`` to every function here; the shear terms are about 1 % of the deflection for
``h / L = 0.1``, so the choice moves the results by about 1e-4 relative.

Beam theory carries no local effects (clamping of the Poisson contraction, point loads
and supports, warping): a 2D elastic solution differs from it by a fraction of a percent
at ``h / L = 0.1``; the committed 2D references (:func:`load_fe_references`) are the
values an IEM result should converge to.

Only numpy is needed (root finding is done here by bracketing and bisection).

References
----------
* S. P. Timoshenko, J. M. Gere, *Mechanics of Materials*; S. P. Timoshenko, "On the
  correction for shear of the differential equation for transverse vibrations of
  prismatic bars", Phil. Mag. 41 (1921) 744-746.
* T. C. Huang, "The effect of rotatory inertia and of shear deformation on the frequency
  and normal mode equations of uniform beams with simple end conditions", J. Appl. Mech.
  28 (1961) 579-584 (frequency equations of the Timoshenko beam).
* G. R. Cowper, "The shear coefficient in Timoshenko's beam theory", J. Appl. Mech. 33
  (1966) 335-340.
* R. D. Blevins, *Formulas for Natural Frequency and Mode Shape* (Euler-Bernoulli
  eigenvalues ``beta_1 L = 1.87510407`` clamped-free, ``pi`` pinned-pinned).
"""

from __future__ import annotations

import json
import math
from importlib import resources
from pathlib import Path
from typing import Any, Callable, Dict, Optional, Union

import numpy as np

__all__ = [
    "ISSUE3",
    "KAPPA_RECTANGLE",
    "BETA1L_CLAMPED_FREE",
    "BETA1L_PINNED_PINNED",
    "kappa_cowper",
    "shear_modulus",
    "section",
    "cantilever_tip_deflection_euler_bernoulli",
    "cantilever_tip_deflection_timoshenko",
    "simply_supported_midspan_deflection_euler_bernoulli",
    "simply_supported_midspan_deflection_timoshenko",
    "euler_bernoulli_frequency",
    "timoshenko_frequency",
    "timoshenko_frequency_pinned_pinned",
    "timoshenko_frequency_clamped_free",
    "timoshenko_frequency_bottom_pins_rayleigh",
    "beam_references",
    "load_fe_references",
    "deflection_relative_to_end_faces",
]

#: Parameters of the two issue-3 scenes (SI units; plane stress).
ISSUE3: Dict[str, float] = {
    "E": 25e9,  # Pa
    "nu": 0.2,
    "rho": 2400.0,  # kg/m^3
    "L": 1.0,  # m
    "h": 0.1,  # m, depth
    "t": 0.1,  # m, thickness (section width)
    "P": 1000.0,  # N
}

#: Shear correction factor of a rectangular section used by default (classical 5/6).
KAPPA_RECTANGLE = 5.0 / 6.0

#: First root of ``1 + cos(x) cosh(x) = 0`` (Euler-Bernoulli clamped-free beam).
BETA1L_CLAMPED_FREE = 1.8751040687119611

#: First root of ``sin(x) = 0`` (Euler-Bernoulli pinned-pinned beam).
BETA1L_PINNED_PINNED = math.pi

_SUPPORTS = ("clamped-free", "pinned-pinned")


def kappa_cowper(nu: float) -> float:
    """Cowper's (1966) shear coefficient of a rectangle, ``10 (1 + nu) / (12 + 11 nu)``."""
    return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)


def shear_modulus(E: float, nu: float) -> float:
    """``G = E / (2 (1 + nu))``."""
    return E / (2.0 * (1.0 + nu))


def section(h: float, t: float) -> tuple[float, float]:
    """Area and second moment of a ``t`` wide, ``h`` deep rectangle: ``(t h, t h^3 / 12)``."""
    return t * h, t * h**3 / 12.0


# ---------------------------------------------------------------------------
# Static deflections
# ---------------------------------------------------------------------------


def cantilever_tip_deflection_euler_bernoulli(
    P: float, L: float, E: float, h: float, t: float
) -> float:
    """Tip deflection of an end-loaded cantilever, Euler-Bernoulli: ``P L^3 / (3 E I)``.

    Magnitude (positive) in the direction of the load.
    """
    _, I = section(h, t)
    return P * L**3 / (3.0 * E * I)


def cantilever_tip_deflection_timoshenko(
    P: float,
    L: float,
    E: float,
    nu: float,
    h: float,
    t: float,
    kappa: float = KAPPA_RECTANGLE,
) -> float:
    """Tip deflection of an end-loaded cantilever, Timoshenko beam.

    ``w = P L^3 / (3 E I) + P L / (kappa G A)`` (bending plus shear; Timoshenko & Gere).
    ``kappa`` defaults to 5/6 (rectangle).  Magnitude, positive in the load direction.
    """
    A, _ = section(h, t)
    G = shear_modulus(E, nu)
    return cantilever_tip_deflection_euler_bernoulli(P, L, E, h, t) + P * L / (kappa * G * A)


def simply_supported_midspan_deflection_euler_bernoulli(
    P: float, L: float, E: float, h: float, t: float
) -> float:
    """Mid-span deflection of a simply supported beam under a central point load,
    Euler-Bernoulli: ``P L^3 / (48 E I)``.  Magnitude, positive in the load direction."""
    _, I = section(h, t)
    return P * L**3 / (48.0 * E * I)


def simply_supported_midspan_deflection_timoshenko(
    P: float,
    L: float,
    E: float,
    nu: float,
    h: float,
    t: float,
    kappa: float = KAPPA_RECTANGLE,
) -> float:
    """Mid-span deflection of a simply supported beam under a central point load,
    Timoshenko beam: ``w = P L^3 / (48 E I) + P L / (4 kappa G A)``.

    ``kappa`` defaults to 5/6 (rectangle).  Magnitude, positive in the load direction.
    The beam's supports act at the section (its axis); see :func:`load_fe_references`
    for the 2D value with point supports measured relative to the end faces.
    """
    A, _ = section(h, t)
    G = shear_modulus(E, nu)
    return simply_supported_midspan_deflection_euler_bernoulli(P, L, E, h, t) + P * L / (
        4.0 * kappa * G * A
    )


# ---------------------------------------------------------------------------
# Natural frequencies
# ---------------------------------------------------------------------------


def _check_support(support: str) -> None:
    if support not in _SUPPORTS:
        raise ValueError(f"support must be one of {_SUPPORTS}, not {support!r}")


def euler_bernoulli_frequency(
    L: float, E: float, rho: float, h: float, t: float, support: str = "clamped-free"
) -> float:
    """First natural frequency (Hz) of an Euler-Bernoulli beam.

    ``omega_1 = (beta_1 L)^2 sqrt(E I / (rho A L^4))``, ``f_1 = omega_1 / (2 pi)``, with
    ``beta_1 L = 1.8751040687`` for ``support="clamped-free"`` (root of
    ``1 + cos x cosh x = 0``) and ``pi`` for ``support="pinned-pinned"`` (Blevins).
    """
    _check_support(support)
    A, I = section(h, t)
    bl = BETA1L_CLAMPED_FREE if support == "clamped-free" else BETA1L_PINNED_PINNED
    return bl**2 * math.sqrt(E * I / (rho * A * L**4)) / (2.0 * math.pi)


def timoshenko_frequency_pinned_pinned(
    L: float,
    E: float,
    nu: float,
    rho: float,
    h: float,
    t: float,
    kappa: float = KAPPA_RECTANGLE,
    rotary_inertia: bool = True,
    mode: int = 1,
) -> float:
    """Natural frequency (Hz) of the ``mode``-th bending mode of a pinned-pinned
    Timoshenko beam (closed form).

    With ``w = W sin(k x)``, ``psi = Psi cos(k x)``, ``k = mode pi / L``, the Timoshenko
    equations ``EI psi'' + kappa G A (w' - psi) + rho I omega^2 psi = 0`` and
    ``kappa G A (w'' - psi') + rho A omega^2 w = 0`` give the quadratic in ``Omega = omega^2``
    (Huang 1961)::

        rho^2 A I Omega^2 - [rho A E I k^2 + rho A kappa G A + rho I kappa G A k^2] Omega
            + kappa G A E I k^4 = 0

    whose smaller root is the bending branch.  ``kappa=math.inf`` drops shear deformation,
    ``rotary_inertia=False`` drops the ``rho I`` terms; both together give Euler-Bernoulli.
    """
    A, I = section(h, t)
    J = rho * I if rotary_inertia else 0.0
    EI = E * I
    k = mode * math.pi / L
    if math.isinf(kappa):
        # no shear deformation: (E I k^4 - rho A Omega - J k^2 Omega) = 0 (Rayleigh beam)
        omega2 = EI * k**4 / (rho * A + J * k**2)
    else:
        S = kappa * shear_modulus(E, nu) * A
        a = rho * A * J
        b = rho * A * EI * k**2 + rho * A * S + J * S * k**2
        c = S * EI * k**4
        # smaller root, written to stay accurate when a -> 0
        omega2 = 2.0 * c / (b + math.sqrt(b * b - 4.0 * a * c))
    return math.sqrt(omega2) / (2.0 * math.pi)


def timoshenko_frequency_bottom_pins_rayleigh(
    L: float,
    E: float,
    nu: float,
    rho: float,
    h: float,
    t: float,
    kappa: float = KAPPA_RECTANGLE,
) -> float:
    """First frequency (Hz) of a simply supported Timoshenko beam whose pins sit at the
    bottom fibre of the end sections (one pin, one roller), Rayleigh estimate.

    With the pins on the axis the mode is ``w = W sin(k x)``, ``psi = Psi cos(k x)``
    (:func:`timoshenko_frequency_pinned_pinned`, ``Psi = kappa G A k W / (E I k^2 +
    kappa G A - rho I omega^2)``).  A pin at the bottom fibre ``y = -h/2`` of the section
    at ``x = 0`` holds ``u_x = (h/2) psi(0) + u_0 = 0`` there, so the whole beam moves
    axially by ``u_0 = -(h/2) Psi``: extra kinetic energy ``rho A L (h Psi / 2)^2 / 2``
    with no extra strain energy.  Rayleigh's quotient with this shape (an upper bound)::

        omega^2 = omega_pp^2 / (1 + r),   r = (h^2 Psi^2 / 2) / (W^2 + (I/A) Psi^2)

    about ``1 / sqrt(1 + (pi h / L)^2 / 2)`` times the axis-pinned value (-2.4 % at
    ``h / L = 0.1``).  Plain Timoshenko beam theory (pins on the axis) misses this.
    """
    A, I = section(h, t)
    f_pp = timoshenko_frequency_pinned_pinned(L, E, nu, rho, h, t, kappa)
    omega2 = (2.0 * math.pi * f_pp) ** 2
    k = math.pi / L
    S = kappa * shear_modulus(E, nu) * A
    psi = S * k / (E * I * k**2 + S - rho * I * omega2)  # per unit W
    r = (h**2 * psi**2 / 2.0) / (1.0 + (I / A) * psi**2)
    return math.sqrt(omega2 / (1.0 + r)) / (2.0 * math.pi)


def _timoshenko_matrix(
    omega: float,
    support: str,
    L: float,
    EI: float,
    rhoA: float,
    J: float,
    S: float,
) -> np.ndarray:
    """Boundary matrix of the Timoshenko beam at circular frequency ``omega``.

    ``w = C1 cosh(a x) + C2 sinh(a x) + C3 cos(b x) + C4 sin(b x)``, where ``a^2`` and
    ``-b^2`` are the roots of ``EI k^4 + (J w^2 + EI q) k^2 + (J w^2 q - rho A w^2) = 0``
    (``q = rho A w^2 / S``, ``S = kappa G A``), and ``psi`` follows from
    ``psi' = w'' + q w``.  Rows: the four end conditions (clamped: ``w = psi = 0``;
    free: ``M = EI psi' = 0`` and ``V = S (w' - psi) = 0``; pinned: ``w = 0``, ``M = 0``).
    """
    w2 = omega * omega
    q = rhoA * w2 / S if math.isfinite(S) else 0.0
    B = J * w2 + EI * q
    C = J * w2 * q - rhoA * w2
    if C >= 0.0:
        raise ValueError("frequency at or above the Timoshenko cut-off frequency")
    disc = math.sqrt(B * B - 4.0 * EI * C)
    a2 = (-B + disc) / (2.0 * EI)
    b2 = (B + disc) / (2.0 * EI)
    a, b = math.sqrt(a2), math.sqrt(b2)
    ca, cb = (a2 + q) / a, (q - b2) / b  # psi amplitudes (see docstring)

    def w(x: float) -> list[float]:
        return [math.cosh(a * x), math.sinh(a * x), math.cos(b * x), math.sin(b * x)]

    def psi(x: float) -> list[float]:
        return [ca * math.sinh(a * x), ca * math.cosh(a * x), cb * math.sin(b * x), -cb * math.cos(b * x)]

    def moment(x: float) -> list[float]:  # EI psi' / EI
        return [
            (a2 + q) * math.cosh(a * x),
            (a2 + q) * math.sinh(a * x),
            (q - b2) * math.cos(b * x),
            (q - b2) * math.sin(b * x),
        ]

    def shear(x: float) -> list[float]:  # S (w' - psi), written without S
        return [
            -rhoA * w2 / a * math.sinh(a * x),
            -rhoA * w2 / a * math.cosh(a * x),
            -rhoA * w2 / b * math.sin(b * x),
            rhoA * w2 / b * math.cos(b * x),
        ]

    if support == "clamped-free":
        rows = [w(0.0), psi(0.0), moment(L), shear(L)]
    else:
        rows = [w(0.0), moment(0.0), w(L), moment(L)]
    m = np.array(rows, dtype=float)
    return m / np.linalg.norm(m, axis=1, keepdims=True)


def _first_root(fun: Callable[[float], float], lo: float, hi: float, steps: int) -> float:
    """First sign change of ``fun`` on a geometric scan of ``[lo, hi]``, refined by bisection."""
    xs = np.geomspace(lo, hi, steps)
    prev_x, prev_f = xs[0], fun(xs[0])
    for x in xs[1:]:
        fx = fun(x)
        if prev_f == 0.0:
            return float(prev_x)
        if np.sign(fx) != np.sign(prev_f):
            a, b, fa = prev_x, x, prev_f
            for _ in range(200):
                mid = 0.5 * (a + b)
                fm = fun(mid)
                if fm == 0.0:
                    return float(mid)
                if np.sign(fm) == np.sign(fa):
                    a, fa = mid, fm
                else:
                    b = mid
                if b - a <= 4e-16 * b:
                    break
            return float(0.5 * (a + b))
        prev_x, prev_f = x, fx
    raise RuntimeError("no root found in the scanned interval")


def timoshenko_frequency_clamped_free(
    L: float,
    E: float,
    nu: float,
    rho: float,
    h: float,
    t: float,
    kappa: float = KAPPA_RECTANGLE,
    rotary_inertia: bool = True,
) -> float:
    """First natural frequency (Hz) of a clamped-free Timoshenko beam.

    Solves the Timoshenko frequency equation (Huang 1961) numerically: the determinant of
    the 4x4 boundary matrix of :func:`_timoshenko_matrix` (clamped ``w = psi = 0`` at
    ``x = 0``; free ``M = 0``, ``V = 0`` at ``x = L``) is scanned upward from well below the
    Euler-Bernoulli frequency and its first zero is bisected to round-off.
    ``kappa=math.inf`` drops shear deformation, ``rotary_inertia=False`` drops rotary
    inertia; both together reproduce Euler-Bernoulli (``beta_1 L = 1.8751040687``).
    """
    return _timoshenko_frequency_det("clamped-free", L, E, nu, rho, h, t, kappa, rotary_inertia)


def _timoshenko_frequency_det(
    support: str,
    L: float,
    E: float,
    nu: float,
    rho: float,
    h: float,
    t: float,
    kappa: float,
    rotary_inertia: bool,
) -> float:
    _check_support(support)
    A, I = section(h, t)
    EI, rhoA = E * I, rho * A
    J = rho * I if rotary_inertia else 0.0
    S = kappa * shear_modulus(E, nu) * A if math.isfinite(kappa) else math.inf
    w_eb = 2.0 * math.pi * euler_bernoulli_frequency(L, E, rho, h, t, support)
    hi = 1.000001 * w_eb  # shear and rotary inertia only lower the frequency
    if J > 0.0 and math.isfinite(S):
        hi = min(hi, 0.999999 * math.sqrt(S / J))  # below the cut-off frequency

    def det(omega: float) -> float:
        return float(np.linalg.det(_timoshenko_matrix(omega, support, L, EI, rhoA, J, S)))

    omega = _first_root(det, 1e-3 * w_eb, hi, 4000)
    return omega / (2.0 * math.pi)


def timoshenko_frequency(
    L: float,
    E: float,
    nu: float,
    rho: float,
    h: float,
    t: float,
    support: str = "clamped-free",
    kappa: float = KAPPA_RECTANGLE,
    rotary_inertia: bool = True,
) -> float:
    """First bending frequency (Hz) of a Timoshenko beam (shear deformation and rotary
    inertia), ``support`` ``"clamped-free"`` (numerical root of the frequency equation,
    :func:`timoshenko_frequency_clamped_free`) or ``"pinned-pinned"`` (closed form,
    :func:`timoshenko_frequency_pinned_pinned`).  ``kappa`` defaults to 5/6."""
    _check_support(support)
    if support == "clamped-free":
        return timoshenko_frequency_clamped_free(L, E, nu, rho, h, t, kappa, rotary_inertia)
    return timoshenko_frequency_pinned_pinned(L, E, nu, rho, h, t, kappa, rotary_inertia)


def beam_references(params: Optional[Dict[str, float]] = None, kappa: float = KAPPA_RECTANGLE) -> Dict[str, Dict[str, float]]:
    """All beam-theory values of the two issue-3 scenes (magnitudes; m and Hz).

    ``params`` defaults to :data:`ISSUE3`.  Returns ``{"cantilever": {...},
    "three_point_bending": {...}}`` with keys ``deflection_eb``, ``deflection_timoshenko``,
    ``f1_eb``, ``f1_timoshenko`` and, for three-point bending,
    ``f1_timoshenko_bottom_pins_rayleigh``.
    """
    p = dict(ISSUE3 if params is None else params)
    E, nu, rho, L, h, t, P = (p[k] for k in ("E", "nu", "rho", "L", "h", "t", "P"))
    return {
        "cantilever": {
            "deflection_eb": cantilever_tip_deflection_euler_bernoulli(P, L, E, h, t),
            "deflection_timoshenko": cantilever_tip_deflection_timoshenko(P, L, E, nu, h, t, kappa),
            "f1_eb": euler_bernoulli_frequency(L, E, rho, h, t, "clamped-free"),
            "f1_timoshenko": timoshenko_frequency(L, E, nu, rho, h, t, "clamped-free", kappa),
        },
        "three_point_bending": {
            "deflection_eb": simply_supported_midspan_deflection_euler_bernoulli(P, L, E, h, t),
            "deflection_timoshenko": simply_supported_midspan_deflection_timoshenko(
                P, L, E, nu, h, t, kappa
            ),
            "f1_eb": euler_bernoulli_frequency(L, E, rho, h, t, "pinned-pinned"),
            "f1_timoshenko": timoshenko_frequency(L, E, nu, rho, h, t, "pinned-pinned", kappa),
            "f1_timoshenko_bottom_pins_rayleigh": timoshenko_frequency_bottom_pins_rayleigh(
                L, E, nu, rho, h, t, kappa
            ),
        },
    }


# ---------------------------------------------------------------------------
# Committed finite-element references
# ---------------------------------------------------------------------------


def load_fe_references(path: Optional[Union[str, Path]] = None) -> Dict[str, Any]:
    """The committed 2D finite-element references of issue 3.

    Reads ``iem_post/data/fe_references.json`` (written by
    ``postproc/references/fe_reference.py``; see ``postproc/references/README.md``), or
    ``path`` when given.  Layout: ``{"cantilever": {QUANTITY: ENTRY}, "three_point_bending":
    {QUANTITY: ENTRY}, "versions": ..., "parameters": ..., "method": ...}``; each ENTRY has
    ``value`` (the extrapolated reference, signed as defined: ``u_y`` is negative for a
    downward deflection; ``None`` for a quantity that does not converge), ``rel_error``
    (estimated relative error of ``value``), ``unit``, ``definition``, ``converged`` and the
    mesh ``sequence``.  Quantities: cantilever ``uy_tip`` and ``f1``; three-point bending
    ``d_mid``, ``uy_mid_raw`` (diverges), ``f1_point_supports`` (diverges),
    ``f1_section_pins`` and ``f1_axis_pins``.

    ``"cantilever_plane_strain"`` holds the plane-strain cantilever tip deflection
    (``uy_tip``, m) for near-incompressible material: ``"nu_0.49"`` and ``"nu_0.499"`` (ENTRY
    as above, plus ``nu``, ``lambda``, ``mu`` and the plane-strain Timoshenko values in
    ``beam_theory``); ``"nu_0.49_sri"`` and ``"nu_0.499_sri"`` (the same with selective reduced
    integration, a locking check); ``"parameters"`` and ``"method"``.
    """
    if path is not None:
        text = Path(path).read_text(encoding="utf-8")
    else:
        text = resources.files("iem_post").joinpath("data/fe_references.json").read_text(encoding="utf-8")
    return json.loads(text)


def deflection_relative_to_end_faces(
    coordinates: np.ndarray, displacement: np.ndarray, x: float, y: float
) -> float:
    """Deflection ``u_y`` of the node nearest to ``(x, y)`` relative to the end faces: minus
    the mean of the two end faces' mean ``u_y`` (each face's mean is the trapezoid integral
    of ``u_y`` over the nodes on ``x = min x`` and ``x = max x``, divided by the face height).

    This is the three-point-bending quantity ``d_mid`` of :func:`load_fe_references` when
    ``(x, y) = (L/2, 0)``: it converges as the grid is refined, whereas the raw ``u_y`` does
    not (a point support indents a 2D body by an amount that grows like the log of the grid
    size).  ``coordinates`` and ``displacement`` are ``(n, 2)`` arrays of a frame.
    """
    xy = np.asarray(coordinates, dtype=float)
    u = np.asarray(displacement, dtype=float)
    height = float(xy[:, 1].max() - xy[:, 1].min())
    tol = 1e-9 * max(float(np.ptp(xy[:, 0])), height)

    def face_mean(x_face: float) -> float:
        on = np.abs(xy[:, 0] - x_face) <= tol
        order = np.argsort(xy[on, 1])
        return float(np.trapezoid(u[on, 1][order], xy[on, 1][order])) / height

    node = int(np.argmin(np.hypot(xy[:, 0] - x, xy[:, 1] - y)))
    return float(u[node, 1]) - 0.5 * (face_mean(float(xy[:, 0].min())) + face_mean(float(xy[:, 0].max())))
