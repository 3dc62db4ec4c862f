"""Load-displacement and load-CMOD curves from the reactions and probes of an iem run.

Conventions: the load is one component of ``/history/reactions/<bc>`` (the force the bc's
prescribed dofs exert on the body, N) times ``load_scale``; the displacement is one component
of a probe's displacement times ``length_scale``, and the CMOD is u_x(B) - u_x(A) of two
probes (positive when the points move apart, A left of B) times ``cmod_scale``. A reference table (columns
``cmod``, ``load_min``, ``load_max``) is multiplied column-wise by its own scales to bring it
into the same units as the model's curves.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .fracture import read_reaction, require
from .plots import _new_figure, _no_data
from .reader import IemFile, InputError

__all__ = [
    "COMPONENTS",
    "Curves",
    "Reference",
    "parse_target",
    "read_curves",
    "read_reference",
    "plot_curves",
    "write_csv",
]

#: Component letters and their columns.
COMPONENTS = {"x": 0, "y": 1}


@dataclass(frozen=True)
class Curves:
    """Scaled curves at the history samples; ``cmod`` is None without a CMOD pair."""

    time: np.ndarray
    load: np.ndarray
    displacement: np.ndarray
    cmod: np.ndarray | None
    load_label: str
    displacement_label: str
    cmod_label: str

    def peak(self) -> int:
        """Sample index of the largest load (the first one if tied)."""
        return int(np.nanargmax(self.load)) if np.isfinite(self.load).any() else 0


@dataclass(frozen=True)
class Reference:
    """A reference band: load_min..load_max against cmod (already scaled)."""

    cmod: np.ndarray
    load_min: np.ndarray
    load_max: np.ndarray
    label: str


def parse_target(text: str, default: str = "y") -> tuple[str, str]:
    """Split ``NAME[:x|y]`` into (NAME, component); the component defaults to ``default``."""
    name, sep, comp = text.rpartition(":")
    if sep and comp.strip().lower() in COMPONENTS and name:
        return name, comp.strip().lower()
    return text, default


def _scale_note(scale: float) -> str:
    """' x s' for a scale other than 1, else ''."""
    return "" if scale == 1.0 else f" \u00d7 {scale:g}"


def _probe_displacement(data: IemFile, name: str) -> np.ndarray:
    """Displacement history (n_samples, 2) of probe ``name``, with a clear error if absent."""
    path = f"history/probes/{name}/displacement"
    if not data.has_dataset(path):
        found = data.group_members("history/probes")
        require(data, path, f"probes in this file: {', '.join(found)}" if found
                else "this file has no probes")
    return data.history_series(path, width=2)


def read_curves(
    data: IemFile,
    load: tuple[str, str],
    displacement: tuple[str, str],
    cmod: tuple[str, str] | None = None,
    load_scale: float = 1.0,
    length_scale: float = 1.0,
    cmod_scale: float = 1.0,
) -> Curves:
    """Load against displacement (and CMOD) from reaction ``load`` = (bc, component), probe
    ``displacement`` = (name, component) and ``cmod`` = (probe A, probe B)."""
    bc, load_comp = load
    probe, disp_comp = displacement
    reaction = read_reaction(data, bc)
    disp = _probe_displacement(data, probe)
    series = [reaction[:, COMPONENTS[load_comp]], disp[:, COMPONENTS[disp_comp]]]
    if cmod is not None:
        a, b = (_probe_displacement(data, name) for name in cmod)
        n = min(a.shape[0], b.shape[0])
        series.append(b[:n, 0] - a[:n, 0])
    time = data.history_time
    n = min([time.shape[0]] + [s.shape[0] for s in series])
    # "+ 0.0" turns the -0.0 a negative scale makes of a zero into 0.0
    return Curves(
        time=time[:n],
        load=load_scale * series[0][:n] + 0.0,
        displacement=length_scale * series[1][:n] + 0.0,
        cmod=None if cmod is None else cmod_scale * series[2][:n] + 0.0,
        load_label=f"load: reaction {bc} {load_comp} (N{_scale_note(load_scale)})",
        displacement_label=(f"displacement: probe {probe} u_{disp_comp} "
                            f"(m{_scale_note(length_scale)})"),
        cmod_label=("" if cmod is None else
                    f"CMOD = u_x({cmod[1]}) \u2212 u_x({cmod[0]}) (m{_scale_note(cmod_scale)})"),
    )


def read_reference(path: Path, scale: tuple[float, float] = (1.0, 1.0)) -> Reference:
    """Read a CSV with a header naming ``cmod``, ``load_min`` and ``load_max``; multiply cmod
    by scale[0] and both loads by scale[1]."""
    try:
        with open(path, encoding="utf-8") as handle:
            header = handle.readline()
            names = [name.strip().lower() for name in header.split(",")]
            missing = [c for c in ("cmod", "load_min", "load_max") if c not in names]
            if missing:
                raise InputError(f"{path}: the header lacks the column(s) {', '.join(missing)} "
                                 f"(found: {header.strip()!r})")
            table = np.loadtxt(handle, delimiter=",", ndmin=2)
    except OSError as exc:
        raise InputError(f"cannot read the reference {path}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise InputError(f"{path}: not a table of numbers below the header ({exc})") from None
    if table.shape[0] == 0 or table.shape[1] != len(names):
        raise InputError(f"{path}: expected rows of {len(names)} numbers below the header")
    columns = {c: table[:, names.index(c)] for c in ("cmod", "load_min", "load_max")}
    order = np.argsort(columns["cmod"], kind="stable")
    return Reference(
        cmod=scale[0] * columns["cmod"][order],
        load_min=scale[1] * columns["load_min"][order],
        load_max=scale[1] * columns["load_max"][order],
        label=f"reference band ({path.name})",
    )


def plot_curves(curves: Curves, reference: Reference | None = None, title: str = "") -> Figure:
    """Load against displacement, and load against CMOD (with the reference band) if any."""
    panels = 1 if curves.cmod is None else 2
    fig = _new_figure(6.0 * panels + 1.0, 5.5)
    if title:
        fig.suptitle(title)
    if curves.time.size == 0:
        return _no_data(fig, "no history samples")
    axes = np.atleast_1d(fig.subplots(1, panels, sharey=True))
    peak = curves.peak()
    xs = [(curves.displacement, curves.displacement_label)]
    if curves.cmod is not None:
        xs.append((curves.cmod, curves.cmod_label))
    for ax, (x, label) in zip(axes, xs):
        ax.plot(x, curves.load, color="tab:blue", label="model")
        ax.plot(x[peak], curves.load[peak], "o", color="tab:red", ms=5,
                label=f"peak {curves.load[peak]:.4g}")
        ax.set_xlabel(label)
        ax.grid(True, alpha=0.3)
    if reference is not None and curves.cmod is not None:
        axes[-1].fill_between(reference.cmod, reference.load_min, reference.load_max,
                              color="0.6", alpha=0.4, linewidth=0, label=reference.label)
    for ax in axes:
        ax.legend(fontsize="small", loc="best")
    axes[0].set_ylabel(curves.load_label)
    return fig


def write_csv(curves: Curves, path: Path) -> Path:
    """Write time, displacement, load (and cmod) per sample, as plotted, to ``path``."""
    columns = [curves.time, curves.displacement, curves.load]
    names = ["time", "displacement", "load"]
    if curves.cmod is not None:
        columns.append(curves.cmod)
        names.append("cmod")
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, np.column_stack(columns), delimiter=",", fmt="%.17g",
               header=",".join(names), comments="")
    return path
