"""The finite-element model of the issue-3 accuracy scenes (scikit-fem), for fe_reference.py.

Plane stress by default (E = 25 GPa, nu = 0.2, rho = 2400 kg/m^3, body [0, 1] x [0, 0.1] m,
thickness 0.1 m, P = 1000 N: ``iem_post.references.ISSUE3``): graded tensor-product meshes
(:func:`graded_coords`), the 9-node biquadratic Lagrange model with consistent mass and exact
face integrals (:class:`Model`), the sparse solvers (LU with iterative refinement,
shift-invert eigenpairs, elimination of linear constraints) and one mesh level of each scene
(:func:`cantilever`, :func:`three_point_bending`), returning the quantities of that level.
The refinement sequences, the extrapolation and the JSON file are fe_reference.py's (which
re-exports this module's public names); see its docstring and postproc/references/README.md
for the definitions and the method.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from skfem import Basis, BilinearForm, ElementQuad2, ElementVector, FacetBasis, LinearForm, MeshQuad, asm
from skfem.helpers import ddot, div, sym_grad
from skfem.models.elasticity import linear_elasticity, plane_stress

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
from iem_post.references import ISSUE3  # noqa: E402

E, NU, RHO, L, H_DEPTH, T, P = (ISSUE3[k] for k in ("E", "nu", "rho", "L", "h", "t", "P"))
LAM, MU = plane_stress(E, NU)
INTORDER = 4  # 3x3 Gauss: exact for Quad2 stiffness and mass on rectangles
INTORDER_REDUCED = 3  # 2x2 Gauss: the volumetric term of the "sri" variant (plane strain only)
GRADE_ZONE = H_DEPTH / 2  # a: length of the graded zone at a singular point


# ---------------------------------------------------------------------------
# meshes
# ---------------------------------------------------------------------------


def graded_coords(length: float, base: float, points: list[float], zone: float, gamma: float) -> np.ndarray:
    """1D node coordinates on [0, length]: element size ``base`` away from ``points``,
    algebraic grading ``p +- zone (i/n)^gamma`` (n = round(zone gamma / base)) on each side
    of each point, so that the graded zone ends with an element of about ``base``.
    ``gamma = 1`` gives a uniform grid."""
    marks = []
    for p in points:
        if p > 0:
            marks.append((max(p - zone, 0.0), p, "towards_right"))
        if p < length:
            marks.append((p, min(p + zone, length), "towards_left"))
    marks.sort()
    xs = [0.0]
    cur = 0.0
    for x0, x1, kind in marks:
        if x0 > cur + 1e-14:
            n = max(1, int(round((x0 - cur) / base)))
            xs += list(np.linspace(cur, x0, n + 1)[1:])
        n = max(1, int(round((x1 - x0) * gamma / base)))
        s = np.linspace(0.0, 1.0, n + 1)[1:]
        if kind == "towards_left":
            xs += list(x0 + (x1 - x0) * s**gamma)
        else:
            xs += list(x1 - (x1 - x0) * (1.0 - s) ** gamma)
        cur = x1
    if cur < length - 1e-14:
        n = max(1, int(round((length - cur) / base)))
        xs += list(np.linspace(cur, length, n + 1)[1:])
    out = np.array(xs)
    out[0], out[-1] = 0.0, length
    assert np.all(np.diff(out) > 0)
    return out


@BilinearForm
def _mass(u, v, w):
    return RHO * T * (u[0] * v[0] + u[1] * v[1])


def plane_strain(E: float, nu: float) -> tuple[float, float]:
    """Lame parameters of the 2D plane-strain constitutive matrix."""
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def _shear_form(mu: float) -> BilinearForm:
    @BilinearForm
    def form(u, v, w):
        return 2.0 * mu * ddot(sym_grad(u), sym_grad(v))

    return form


def _volumetric_form(lam: float) -> BilinearForm:
    @BilinearForm
    def form(u, v, w):
        return lam * div(u) * div(v)

    return form


class Model:
    """Quad2 model on the tensor grid ``xs x ys``: plane stress by default; ``lam, mu`` are
    the 2D Lame parameters of the constitutive matrix.  ``variant = "sri"`` integrates the
    lambda term with 2x2 Gauss (selective reduced integration)."""

    def __init__(
        self, xs: np.ndarray, ys: np.ndarray, lam: float = LAM, mu: float = MU, variant: str = "full"
    ) -> None:
        self.xs, self.ys = xs, ys
        self.mesh = MeshQuad.init_tensor(xs, ys)
        self.basis = Basis(self.mesh, ElementVector(ElementQuad2()), intorder=INTORDER)
        b = self.basis
        self.comp = np.zeros(b.N, dtype=int)
        for dofs in (b.nodal_dofs, b.facet_dofs, b.interior_dofs):
            self.comp[dofs[1]] = 1
        if variant == "full":
            self.K = asm(linear_elasticity(lam, mu), b) * T
        elif variant == "sri":
            reduced = Basis(self.mesh, b.elem, intorder=INTORDER_REDUCED)
            self.K = (asm(_shear_form(mu), b) + asm(_volumetric_form(lam), reduced)) * T
        else:
            raise ValueError(f"unknown variant {variant!r}")
        self._M = None

    @property
    def M(self) -> sp.csr_matrix:
        if self._M is None:
            self._M = asm(_mass, self.basis)
        return self._M

    @property
    def n_elements(self) -> int:
        return int(self.mesh.t.shape[1])

    def dof(self, x: float, y: float, c: int) -> int:
        """The dof of component ``c`` (0: x, 1: y) of the node at (x, y)."""
        loc = self.basis.doflocs
        d = np.nonzero((self.comp == c) & (np.abs(loc[0] - x) < 1e-12) & (np.abs(loc[1] - y) < 1e-12))[0]
        if len(d) != 1:
            raise RuntimeError(f"no unique node at ({x}, {y})")
        return int(d[0])

    def face_weights(self, X: float, c: int, weight=lambda y: np.ones_like(y)) -> np.ndarray:
        """Vector g with g @ u = integral over the face x = X of weight(y) * u_c dy.

        The trace of u on an element edge is quadratic (nodes: ends and mid-point); for a
        weight of degree <= 1 the product is cubic and Simpson's rule (1/6, 2/3, 1/6) is
        exact: this is the facet-basis integral, evaluated exactly."""
        loc = self.basis.doflocs
        sel = np.nonzero((self.comp == c) & (np.abs(loc[0] - X) < 1e-12))[0]
        sel = sel[np.argsort(loc[1, sel])]
        y = loc[1, sel]
        assert len(y) == 2 * (len(self.ys) - 1) + 1
        lengths = np.diff(y[::2])
        w = np.zeros(len(sel))
        w[0:-1:2] += lengths / 6.0
        w[2::2] += lengths / 6.0
        w[1::2] += 2.0 * lengths / 3.0
        g = np.zeros(self.basis.N)
        g[sel] = w * weight(y)
        return g

    def facet_basis_check(self, X: float) -> None:
        """Compare face_weights with skfem's FacetBasis assembly (coarse meshes only)."""
        fb = FacetBasis(
            self.mesh, self.basis.elem, facets=self.mesh.facets_satisfying(lambda x: np.isclose(x[0], X)),
            intorder=INTORDER,
        )
        for c in (0, 1):
            ref = asm(LinearForm(lambda v, w, c=c: v[c] * (1.0 + w.x[1])), fb)
            mine = self.face_weights(X, c, lambda y: 1.0 + y)
            assert np.allclose(ref, mine, rtol=0, atol=1e-14), "face integral differs from FacetBasis"


def solve_refined(A: sp.spmatrix, lu, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solution of A x = b and the same after one step of iterative refinement; the change
    of a quantity between the two estimates its round-off error (graded meshes have
    elements down to 1e-6 of the body and aspect ratios in the thousands)."""
    x0 = lu.solve(b)
    return x0, x0 + lu.solve(b - A @ x0)


def factor(A: sp.spmatrix):
    """Sparse LU of an SPD matrix: minimum-degree ordering on A^T + A, diagonal pivots
    (partial pivoting destroys the ordering: 50x slower on 3e5 dofs, same result)."""
    return sla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})


def lowest_frequencies(Kc: sp.spmatrix, Mc: sp.spmatrix, lu=None, k: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Lowest k eigenfrequencies (Hz) and modes of Kc x = w^2 Mc x (shift-invert, sigma=0)."""
    if lu is None:
        lu = factor(Kc)
    op = sla.LinearOperator(Kc.shape, matvec=lu.solve, dtype=float)
    w2, modes = sla.eigsh(Kc.tocsc(), k=k, M=Mc.tocsc(), sigma=0.0, OPinv=op, which="LM")
    order = np.argsort(w2)
    return np.sqrt(w2[order]) / (2.0 * math.pi), modes[:, order]


def elimination(N: int, constraints: list[np.ndarray]) -> sp.csr_matrix:
    """T (N x N-m) with u = T w satisfying c @ u = 0 for each constraint c: each constraint
    eliminates its largest-weight dof (constraints must have disjoint supports)."""
    masters = []
    for c in constraints:
        masters.append(int(np.argmax(np.abs(c))))
    supports = [set(np.nonzero(c)[0]) for c in constraints]
    for i in range(len(supports)):
        for j in range(i + 1, len(supports)):
            assert not supports[i] & supports[j]
    free = np.setdiff1d(np.arange(N), masters)
    index = -np.ones(N, dtype=int)
    index[free] = np.arange(len(free))
    rows, cols, vals = list(free), list(range(len(free))), [1.0] * len(free)
    for c, m in zip(constraints, masters):
        nz = np.nonzero(c)[0]
        nz = nz[nz != m]
        rows += [m] * len(nz)
        cols += list(index[nz])
        vals += list(-c[nz] / c[m])
    return sp.csr_matrix((vals, (rows, cols)), shape=(N, len(free)))


# ---------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------


def cantilever(
    ny: int,
    gamma: float,
    check: bool = False,
    lam: float = LAM,
    mu: float = MU,
    variant: str = "full",
    frequency: bool = True,
) -> dict:
    base = H_DEPTH / ny
    xs = graded_coords(L, base, [0.0], GRADE_ZONE, gamma)
    ys = graded_coords(H_DEPTH, base, [0.0, H_DEPTH], GRADE_ZONE, gamma)
    m = Model(xs, ys, lam, mu, variant)
    if check:
        m.facet_basis_check(L)
    # uniform shear traction P/(h t) in -y on x = L, times thickness t
    F = -(P / H_DEPTH) * m.face_weights(L, 1)
    assert math.isclose(F.sum(), -P, rel_tol=1e-12)
    loc = m.basis.doflocs
    fixed = np.nonzero(np.abs(loc[0]) < 1e-12)[0]  # both components on x = 0
    free = np.setdiff1d(np.arange(m.basis.N), fixed)
    Kc = m.K[free][:, free].tocsc()
    lu = factor(Kc)
    x0, x1 = solve_refined(Kc, lu, F[free])
    tip = m.dof(L, H_DEPTH / 2, 1)
    u = np.zeros(m.basis.N)
    u[free] = x1
    u0 = np.zeros(m.basis.N)
    u0[free] = x0
    out = {
        "ny": ny,
        "elements": m.n_elements,
        "dofs": int(m.basis.N),
        "h_min": float(min(np.diff(xs).min(), np.diff(ys).min())),
        "uy_tip": float(u[tip]),
        "uy_tip_roundoff": float(abs(u[tip] - u0[tip])),
    }
    if frequency:
        f, _ = lowest_frequencies(Kc, m.M[free][:, free], lu, k=2)
        out["f1"] = float(f[0])
    return out


def three_point_bending(ny: int, gamma: float, check: bool = False) -> dict:
    base = H_DEPTH / ny
    xs = graded_coords(L, base, [0.0, L / 2, L], GRADE_ZONE, gamma)
    ys = graded_coords(H_DEPTH, base, [0.0, H_DEPTH], GRADE_ZONE, gamma)
    m = Model(xs, ys)
    if check:
        m.facet_basis_check(0.0)
    N = m.basis.N
    F = np.zeros(N)
    F[m.dof(L / 2, H_DEPTH, 1)] = -P
    fixed = np.array([m.dof(0.0, 0.0, 0), m.dof(0.0, 0.0, 1), m.dof(L, 0.0, 1)])
    free = np.setdiff1d(np.arange(N), fixed)
    mean0 = m.face_weights(0.0, 1) / H_DEPTH
    meanL = m.face_weights(L, 1) / H_DEPTH
    Kc = m.K[free][:, free].tocsc()
    lu = factor(Kc)
    x0, x1 = solve_refined(Kc, lu, F[free])
    mid = m.dof(L / 2, 0.0, 1)
    qd = {}
    for name, x in (("first", x0), ("refined", x1)):
        u = np.zeros(N)
        u[free] = x
        qd[name] = (float(u[mid]), float(u[mid] - 0.5 * (mean0 @ u + meanL @ u)))
    raw, d = qd["refined"]
    # point supports: first mode must be the symmetric bending mode
    f_pt, modes = lowest_frequencies(Kc, m.M[free][:, free], lu, k=3)
    mode = np.zeros(N)
    mode[free] = modes[:, 0]
    d_mode = mode[mid] - 0.5 * (mean0 @ mode + meanL @ mode)
    assert abs(d_mode) > 0.5 * np.abs(mode[m.comp == 1]).max(), "first mode is not the bending mode"
    # well-posed variants: supports acting on the end sections
    mean0x = m.face_weights(0.0, 0) / H_DEPTH
    # plane-section fit u_x ~ a + b (y - h/2) over x = 0; bottom fibre value a - b h/2,
    # b = 12/h^3 * int (y - h/2) u_x dy
    bottom0x = mean0x - (6.0 / H_DEPTH**2) * m.face_weights(0.0, 0, lambda y: y - H_DEPTH / 2)
    out = {
        "ny": ny,
        "elements": m.n_elements,
        "dofs": int(N),
        "h_min": float(min(np.diff(xs).min(), np.diff(ys).min())),
        "d_mid": d,
        "d_mid_roundoff": abs(d - qd["first"][1]),
        "uy_mid_raw": raw,
        "uy_mid_raw_roundoff": abs(raw - qd["first"][0]),
        "f1_point_supports": float(f_pt[0]),
    }
    for key, cons in (("f1_section_pins", [mean0, meanL, bottom0x]), ("f1_axis_pins", [mean0, meanL, mean0x])):
        Tm = elimination(N, cons)
        f, _ = lowest_frequencies((Tm.T @ m.K @ Tm).tocsc(), (Tm.T @ m.M @ Tm).tocsc(), k=2)
        out[key] = float(f[0])
    return out
