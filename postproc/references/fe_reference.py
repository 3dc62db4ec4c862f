#!/usr/bin/env python3
"""Finite-element references for the issue-3 accuracy scenes (scikit-fem).

Plane stress, E = 25 GPa, nu = 0.2, rho = 2400 kg/m^3, body [0, 1] x [0, 0.1] m,
thickness 0.1 m, P = 1000 N.  See postproc/references/README.md for the definitions.

* cantilever: left face x = 0 clamped, uniform shear traction on x = L (total P, -y):
  ``uy_tip`` = u_y(L, h/2) [m]; ``f1`` = first natural frequency of the clamped body [Hz].
* three_point_bending: point supports (0, 0) (x and y) and (L, 0) (y), point load P (-y)
  at (L/2, h):
  ``d_mid`` = u_y(L/2, 0) - (mean_face(x=0) u_y + mean_face(x=L) u_y) / 2 [m];
  ``uy_mid_raw`` = u_y(L/2, 0) [m] (diverges like log of the mesh size at the supports);
  ``f1_point_supports`` = first (bending) frequency on the point supports [Hz] (diverges
  the same way); two well-posed variants of the supported beam (converge):
  ``f1_section_pins``: the supports act on the end sections: mean u_y over each end face
  = 0, and at x = 0 the plane-section fit of u_x at the bottom fibre y = 0 is 0 (pins at
  the bottom of the end sections, as in the scene); ``f1_axis_pins``: as before but with
  the mean u_x over the face x = 0 = 0 (pins on the axis, as in Timoshenko beam theory).

Discretisation: 9-node biquadratic Lagrange quadrilaterals (skfem ElementQuad2, exact
3x3 Gauss quadrature on the rectangles), consistent edge loads and face integrals (exact
integration of the quadratic edge traces), point loads and supports at mesh nodes,
consistent mass, eigenpairs by scipy.sparse.linalg.eigsh in shift-invert mode (sigma = 0,
SuperLU factor reused from the static solve).  Meshes: tensor-product grids with base
element size H = h/ny, graded algebraically (x = a (i/n)^gamma, a = h/2; gamma = 2 for the cantilever, 3 for three-point bending) towards
the singular points, refined by halving H; a uniform sequence is computed for comparison.

Plane strain (``--plane strain --nu NU``): the cantilever tip deflection ``uy_tip`` only,
same geometry and load, with lambda = E nu / ((1 + nu)(1 - 2 nu)), mu = E / (2 (1 + nu));
the result is merged into the output file under ``cantilever_plane_strain`` -> ``nu_NU``
(the other keys of an existing file are kept as they are).  ``--variant sri`` integrates the
lambda (volumetric) term with 2x2 Gauss instead of 3x3 (selective reduced integration, a
check on volumetric locking near nu = 0.5).

The model, the meshes and one mesh level of each scene are fe_model.py (this directory);
this script runs the refinement sequences, extrapolates and writes the JSON file.

Usage::

    python postproc/references/fe_reference.py [--out FILE] [--quick]
    python postproc/references/fe_reference.py --plane strain --nu 0.49 [--variant full|sri] [--out FILE] [--quick]
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import platform
import sys
import tempfile
import time
from datetime import datetime, timezone
from importlib.metadata import version
from pathlib import Path

import numpy as np
import scipy

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
from iem_post.references import ISSUE3, beam_references  # noqa: E402
sys.path.insert(0, str(HERE))
from fe_model import (  # noqa: E402, F401  (the model's public names, re-exported)
    E,
    GRADE_ZONE,
    H_DEPTH,
    INTORDER,
    INTORDER_REDUCED,
    LAM,
    MU,
    NU,
    RHO,
    L,
    P,
    T,
    Model,
    cantilever,
    elimination,
    factor,
    graded_coords,
    lowest_frequencies,
    plane_strain,
    solve_refined,
    three_point_bending,
)

# grading exponents: the clamped corners (stress ~ r^-0.25) need less than the point
# forces (u ~ log r); gamma = 2 gives order ~3 for the cantilever, while three-point bending
# needs gamma = 3 for order ~3 (order 2 with gamma = 2).  gamma = 3 on the cantilever
# reaches round-off at ny = 32 (elements of 5e-7 m with aspect ratio 7000).
GAMMA = {"cantilever": 2.0, "three_point_bending": 3.0}
TOL = 1e-5  # convergence criterion on the relative change between levels
# plane strain (--plane strain): the cantilever only; a mesh sequence one level longer
# than plane stress, since near nu = 0.5 the constant of the Q2 error grows (mild locking)
PLANE_STRAIN_NYS_GRADED = [2, 4, 8, 16, 32, 64]
PLANE_STRAIN_NYS_UNIFORM = [2, 4, 8, 16, 32, 64]
PLANE_STRAIN_TOL = 1e-4  # near nu = 0.5 the last levels change by 1e-5 (round-off grows with lambda/mu)
DEFAULT_OUT = HERE.parent / "iem_post" / "data" / "fe_references.json"


# ---------------------------------------------------------------------------
# convergence analysis
# ---------------------------------------------------------------------------


def richardson(v: list[float]) -> tuple[float, float]:
    """Extrapolation from the last three values of a sequence refined by halving:
    observed order p = log2(|v1 - v0| / |v2 - v1|), v_inf = v2 + (v2 - v1) / (2^p - 1).
    Returns (v_inf, p); when the differences are not monotone, returns (v2, nan)."""
    v0, v1, v2 = v[-3:]
    d1, d2 = v1 - v0, v2 - v1
    if d1 == 0.0 or d2 == 0.0 or d1 * d2 < 0.0 or abs(d2) >= abs(d1):
        return v2, float("nan")
    p = math.log2(abs(d1) / abs(d2))
    return v2 + d2 / (2.0**p - 1.0), p


def converged_entry(
    values: list[float], levels: list[dict], key: str, independent: float | None, tol: float = TOL
) -> dict:
    """Extrapolated value and error estimate of a converging quantity.

    The estimate is the largest of: the change of the extrapolated value over the last
    level, a tenth of the extrapolation step, and the distance to ``independent`` (the
    extrapolation of the uniform sequence: another mesh family, with small round-off); the
    round-off estimate at the finest level (``KEY_roundoff``, static quantities) is added.
    Round-off limits all sequences to about 1e-7 relative: the graded meshes have elements
    of 1e-5..1e-7 m with aspect ratios of hundreds to thousands, and a bending energy is a
    small difference of large stiffness terms."""
    rel_changes = [abs(b - a) / abs(b) for a, b in zip(values[:-1], values[1:])]
    met = next((levels[i + 1]["ny"] for i, r in enumerate(rel_changes) if r < tol), None)
    r_last, p_last = richardson(values)
    if len(values) >= 4:
        r_prev, p_prev = richardson(values[:-1])
    else:
        r_prev, p_prev = values[-2], float("nan")
    if math.isnan(p_last):
        value, err = values[-1], abs(values[-1] - values[-2])
    else:
        value = r_last
        # the change of the extrapolated value over the last level, but never less than a
        # tenth of the extrapolation step itself
        err = max(abs(r_last - r_prev), 0.1 * abs(r_last - values[-1]))
    spread = abs(value - independent) if independent is not None and math.isfinite(independent) else 0.0
    err = max(err, spread)
    roundoff = levels[-1].get(key + "_roundoff", 0.0)
    err += roundoff
    return {
        "value": value,
        "rel_error": err / abs(value),
        "finest_value": values[-1],
        "finest_rel_error": abs(values[-1] - value) / abs(value) + err / abs(value),
        "roundoff_finest": roundoff,
        "rel_spread_to_uniform_extrapolation": spread / abs(value),
        "observed_order": p_last,
        "observed_order_previous": p_prev,
        "last_rel_change": rel_changes[-1],
        "criterion": f"relative change between successive levels < {tol:g}",
        "criterion_met_at_ny": met,
        "converged": met is not None and rel_changes[-1] < tol,
    }


def log_fit(values: list[float], spacing: list[float]) -> dict:
    """Least-squares fit v = A + B ln(s / h) over the last three levels (s: node spacing
    at the singular points)."""
    x = np.log(np.array(spacing[-3:]) / H_DEPTH)
    y = np.array(values[-3:])
    B, A = np.polyfit(x, y, 1)
    return {
        "model": "A + B*ln(s/h), s = node spacing at the supports (half the element size there)",
        "A": float(A),
        "B": float(B),
        "change_per_halving_of_s": float(-B * math.log(2.0)),
        "rel_change_per_halving_of_s": float(abs(B) * math.log(2.0) / abs(values[-1])),
    }


def run_sequence(fun, nys: list[int], gamma: float, label: str) -> list[dict]:
    levels = []
    for i, ny in enumerate(nys):
        t0 = time.time()
        lev = fun(ny, gamma, check=(i == 0))
        lev["seconds"] = round(time.time() - t0, 2)
        levels.append(lev)
        shown = {k: v for k, v in lev.items() if k not in ("ny",)}
        print(f"  {label} gamma={gamma:g} ny={ny}: {shown}", flush=True)
    return levels


DEFINITIONS = {
    "cantilever": {
        "uy_tip": ("m", "u_y at (L, h/2), the mid-depth point of the loaded face"),
        "f1": ("Hz", "first natural frequency of the clamped body (no load)"),
    },
    "cantilever_plane_strain": {
        "uy_tip": ("m", "u_y at (L, h/2), the mid-depth point of the loaded face (plane strain)"),
    },
    "three_point_bending": {
        "d_mid": (
            "m",
            "u_y(L/2, 0) - (mean over x=0 of u_y + mean over x=L of u_y)/2; face mean = "
            "integral over the face / h",
        ),
        "uy_mid_raw": ("m", "u_y(L/2, 0) relative to the point supports; diverges like log of the mesh size there"),
        "f1_point_supports": (
            "Hz",
            "first (bending) frequency on the point supports; diverges like log of the mesh size at the supports",
        ),
        "f1_section_pins": (
            "Hz",
            "first frequency with the supports acting on the end sections: mean u_y over x=0 and over x=L "
            "= 0, and plane-section fit of u_x over x=0 evaluated at the bottom fibre y=0 equal to 0",
        ),
        "f1_axis_pins": (
            "Hz",
            "first frequency with mean u_y over x=0 and x=L = 0 and mean u_x over x=0 = 0 (pins on the "
            "axis: the Timoshenko-beam pinned-pinned conditions)",
        ),
    },
}
DIVERGENT = {"uy_mid_raw", "f1_point_supports"}


def analyse(scene: str, graded: list[dict], uniform: list[dict], gamma: float, tol: float = TOL) -> dict:
    out = {}
    for key, (unit, definition) in DEFINITIONS[scene].items():
        seq = [
            {k: lev[k] for k in ("ny", "elements", "dofs", "h_min")}
            | {"value": lev[key]}
            | ({"roundoff": lev[key + "_roundoff"]} if key + "_roundoff" in lev else {})
            for lev in graded
        ]
        useq = [
            {k: lev[k] for k in ("ny", "elements", "dofs", "h_min")} | {"value": lev[key]} for lev in uniform
        ]
        vals = [lev[key] for lev in graded]
        entry: dict = {"unit": unit, "definition": definition}
        if key in DIVERGENT:
            # node spacing at the supports: half the corner element (Quad2 has mid-side nodes)
            s_graded = [lev["h_min"] / 2 for lev in graded]
            s_uniform = [H_DEPTH / lev["ny"] / 2 for lev in uniform]
            entry |= {
                "value": None,
                "rel_error": None,
                "converged": False,
                "finest_value": vals[-1],
                "log_fit_graded": log_fit(vals, s_graded),
            }
            if len(uniform) >= 3:
                entry["log_fit_uniform"] = log_fit([lev[key] for lev in uniform], s_uniform)
            for row, s in zip(seq, s_graded):
                row["node_spacing_at_supports"] = s
            for row, s in zip(useq, s_uniform):
                row["node_spacing_at_supports"] = s
        else:
            r_uniform = p_uniform = None
            if len(uniform) >= 3:
                r_uniform, p_uniform = richardson([lev[key] for lev in uniform])
            entry |= converged_entry(vals, graded, key, r_uniform, tol)
            entry["uniform_extrapolated"] = r_uniform
            entry["uniform_observed_order"] = p_uniform
        entry["sequence"] = seq
        entry["sequence_mesh"] = f"graded, gamma = {gamma:g}, zone a = h/2, base element size h/ny"
        entry["uniform_sequence"] = useq
        out[key] = entry
    return out


def _finite(obj):
    """NaN (an order that could not be observed) becomes null: strict JSON."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def timoshenko_plane_strain(nu: float, kappa: float = 5.0 / 6.0) -> dict:
    """Timoshenko tip deflection of the cantilever in plane strain (magnitudes):
    P L^3 / (3 E' I) + P L / (kappa G A), E' = E / (1 - nu^2), G = E / (2 (1 + nu))."""
    A, I = T * H_DEPTH, T * H_DEPTH**3 / 12.0
    E_prime, G = E / (1.0 - nu**2), E / (2.0 * (1.0 + nu))
    bending = P * L**3 / (3.0 * E_prime * I)
    return {
        "E_prime": E_prime,
        "G": G,
        "kappa": kappa,
        "deflection_eb": bending,
        "deflection_timoshenko": bending + P * L / (kappa * G * A),
    }


def plane_strain_main(args: argparse.Namespace) -> int:
    """The plane-strain cantilever (``uy_tip``) for one Poisson ratio, merged into ``args.out``
    under ``cantilever_plane_strain`` -> ``nu_NU``; every other key of the file is kept."""
    nu = args.nu
    if not 0.0 <= nu < 0.5:
        raise SystemExit("--nu must lie in [0, 0.5)")
    lam, mu = plane_strain(E, nu)
    gamma = GAMMA["cantilever"] if args.gamma is None else args.gamma
    if args.quick:
        nys_graded, nys_uniform = [2, 4, 8], [2, 4, 8]
    else:
        nys_graded, nys_uniform = PLANE_STRAIN_NYS_GRADED, PLANE_STRAIN_NYS_UNIFORM
    fun = functools.partial(cantilever, lam=lam, mu=mu, variant=args.variant, frequency=False)
    t_start = time.time()
    print(f"cantilever, plane strain, nu = {nu:g}, variant {args.variant}:", flush=True)
    graded = run_sequence(fun, nys_graded, gamma, "graded ")
    uniform = run_sequence(fun, nys_uniform, 1.0, "uniform")
    entry = analyse("cantilever_plane_strain", graded, uniform, gamma, PLANE_STRAIN_TOL)["uy_tip"]
    beam = timoshenko_plane_strain(nu)
    command = "postproc/references/fe_reference.py --plane strain --nu " + f"{nu:g}"
    if args.variant != "full":
        command += f" --variant {args.variant}"
    if args.quick:
        command += " --quick"
    entry = {
        "nu": nu,
        "lambda": lam,
        "mu": mu,
        "variant": args.variant,
        **entry,
        "beam_theory": beam,
        "rel_diff_to_timoshenko": (-entry["value"] - beam["deflection_timoshenko"]) / beam["deflection_timoshenko"],
        "generated_by": command,
        "generated_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "quick": bool(args.quick),
        "versions": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "scikit-fem": version("scikit-fem"),
        },
        "seconds": round(time.time() - t_start, 1),
    }
    key = f"nu_{nu:g}" + ("" if args.variant == "full" else f"_{args.variant}")
    if args.out.exists():
        result = json.loads(args.out.read_text(encoding="utf-8"))
    else:
        result = {}
    section = result.setdefault("cantilever_plane_strain", {})
    section["parameters"] = {
        **{k: ISSUE3[k] for k in ("E", "L", "h", "t", "P")},
        "plane": "strain",
        "constitutive": "2D plane-strain matrix: lambda = E nu / ((1 + nu)(1 - 2 nu)), mu = E / (2 (1 + nu))",
        "body": "[0, L] x [0, h]",
        "load_cantilever": "uniform shear traction P/(h t) in -y on x = L; x = 0 clamped",
        "entries": "nu_NU: one Poisson ratio each (nu_NU_sri: selective reduced integration check)",
    }
    section["method"] = {
        "element": "ElementVector(ElementQuad2): 9-node biquadratic Lagrange quadrilateral; variant full: 3x3 "
        "Gauss for the whole stiffness; variant sri: 2x2 Gauss for the lambda div u div v term",
        "meshes": "as the plane-stress cantilever (graded gamma = 2 towards (0,0), (0,h), and uniform), "
        "one level further (ny up to 64 in both sequences)",
        "loads_solver_extrapolation": "as in the top-level method entry",
        "beam_theory": "Timoshenko P L^3/(3 E' I) + P L/(kappa G A), E' = E/(1 - nu^2), G = E/(2 (1 + nu)), "
        "kappa = 5/6 (magnitudes)",
    }
    section[key] = entry
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(_finite(result), indent=1, allow_nan=False) + "\n", encoding="utf-8")
    print(f"\nwrote {args.out} (cantilever_plane_strain -> {key}; {entry['seconds']} s)")
    state = "converged" if entry["converged"] else "NOT converged"
    print(
        f"  uy_tip {entry['value']:.10g} m +- {entry['rel_error']:.1e} (rel), {state}, order "
        f"{entry['observed_order']}, criterion met at ny={entry['criterion_met_at_ny']}; Timoshenko "
        f"{-beam['deflection_timoshenko']:.6g} m ({100 * entry['rel_diff_to_timoshenko']:+.3f} %)"
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help=f"JSON file to write (default: {DEFAULT_OUT.relative_to(HERE.parent.parent)}; with --quick: "
        "fe_references_quick.json in the temporary directory)",
    )
    ap.add_argument("--quick", action="store_true", help="coarse smoke run (ny up to 8; not a reference)")
    ap.add_argument(
        "--gamma",
        type=float,
        default=None,
        help="grading exponent for both scenes (default: 2 for the cantilever, 3 for three-point bending)",
    )
    ap.add_argument(
        "--plane",
        choices=("stress", "strain"),
        default="stress",
        help="stress (default): both scenes, nu = 0.2, writes the whole file; strain: the cantilever "
        "tip deflection for --nu, merged into the file under cantilever_plane_strain",
    )
    ap.add_argument("--nu", type=float, default=None, help="Poisson ratio (with --plane strain only)")
    ap.add_argument(
        "--variant",
        choices=("full", "sri"),
        default="full",
        help="with --plane strain: full (3x3 Gauss, default) or sri (2x2 Gauss on the lambda term)",
    )
    args = ap.parse_args(argv)
    if args.out is None:
        args.out = Path(tempfile.gettempdir()) / "fe_references_quick.json" if args.quick else DEFAULT_OUT
    if args.plane == "strain":
        if args.nu is None:
            ap.error("--plane strain needs --nu")
        return plane_strain_main(args)
    if args.nu is not None or args.variant != "full":
        ap.error("--nu and --variant apply to --plane strain only")

    t_start = time.time()
    if args.quick:
        nys_graded, nys_uniform = [2, 4, 8], [2, 4, 8]
    else:
        nys_graded, nys_uniform = [2, 4, 8, 16, 32], [2, 4, 8, 16, 32, 64]

    result: dict = {
        "schema": 1,
        "generated_by": "postproc/references/fe_reference.py" + (" --quick" if args.quick else ""),
        "generated_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "quick": bool(args.quick),
        "versions": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "scikit-fem": version("scikit-fem"),
        },
        "parameters": {
            **ISSUE3,
            "plane": "stress",
            "body": "[0, L] x [0, h]",
            "load_cantilever": "uniform shear traction P/(h t) in -y on x = L; x = 0 clamped",
            "load_three_point_bending": "point load P in -y at (L/2, h); supports (0,0) in x and y, (L,0) in y",
        },
        "method": {
            "library": f"scikit-fem {version('scikit-fem')}",
            "element": "ElementVector(ElementQuad2): 9-node biquadratic Lagrange quadrilateral",
            "quadrature": "3x3 Gauss (exact for stiffness and consistent mass on rectangles)",
            "loads": "edge traction and face means integrated exactly over the quadratic edge traces "
            "(checked against skfem FacetBasis); point loads and supports at mesh nodes",
            "mass": "consistent",
            "eigen": "scipy.sparse.linalg.eigsh, shift-invert, sigma = 0",
            "linear_solver": "SuperLU, MMD_AT_PLUS_A ordering, symmetric mode with diagonal pivots (SPD matrices)",
            "section_constraints": "linear constraints eliminated (one master dof per constraint)",
            "meshes": "tensor-product grids; base element size h/ny; algebraic grading "
            "x = p +- a (i/n)^gamma, a = h/2, n = round(a gamma ny / h), gamma per scene (see "
            "sequence_mesh), towards "
            "(0,0),(0,h) for the cantilever and towards x = 0, L/2, L and y = 0, h for three-point bending; "
            "levels halve h/ny",
            "extrapolation": "Richardson on the last three graded levels with the observed order; "
            "rel_error = (max(|R_n - R_(n-1)|, 0.1 |R_n - v_n|, |R_n - R_uniform|) + roundoff) / |R_n| "
            "(R: extrapolated, v: finest, R_uniform: extrapolation of the uniform sequence, roundoff: "
            "change of the quantity in one step of iterative refinement at the finest level)",
        },
        "beam_theory": beam_references(),
    }
    for scene, fun in (("cantilever", cantilever), ("three_point_bending", three_point_bending)):
        print(f"{scene}:", flush=True)
        gamma = GAMMA[scene] if args.gamma is None else args.gamma
        graded = run_sequence(fun, nys_graded, gamma, "graded ")
        uniform = run_sequence(fun, nys_uniform, 1.0, "uniform")
        result[scene] = analyse(scene, graded, uniform, gamma)
    result["seconds"] = round(time.time() - t_start, 1)

    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(_finite(result), indent=1, allow_nan=False) + "\n", encoding="utf-8")

    print(f"\nwrote {args.out} ({result['seconds']} s)")
    for scene in ("cantilever", "three_point_bending"):
        for key, e in result[scene].items():
            if e["converged"]:
                print(
                    f"  {scene:20s} {key:18s} {e['value']:.10g} {e['unit']} +- {e['rel_error']:.1e} (rel), "
                    f"order {e['observed_order']:.2f}, criterion met at ny={e['criterion_met_at_ny']}"
                )
            elif e["value"] is None:
                fit = e["log_fit_graded"]
                print(
                    f"  {scene:20s} {key:18s} diverges: finest {e['finest_value']:.6g} {e['unit']}, "
                    f"{fit['rel_change_per_halving_of_s']:.1e} relative per halving of the support spacing"
                )
            else:
                print(f"  {scene:20s} {key:18s} NOT converged: {e['value']:.10g} +- {e['rel_error']:.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
