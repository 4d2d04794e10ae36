"""Shared plumbing of the studies: command line, output paths, saving, plotting style.

Each study module defines a frozen ``Config``, ``QUICK`` and ``FULL`` instances,
``compute(cfg) -> (arrays: dict, meta: dict)`` (pure: no files, no plotting) and
``plot(arrays, meta, outdir) -> list[Path]`` (no computation). :func:`run` ties them
together; ``taylorball reproduce`` calls it for every figure.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import math
import sys
import time
from pathlib import Path
from typing import List

import numpy as np

STUDIES_DIR = Path(__file__).resolve().parent
DEFAULT_OUT = STUDIES_DIR.parent / "output"


def load_study(name: str):
    """Import ``studies/<name>.py`` as a module (studies are scripts, not a package)."""
    path = STUDIES_DIR / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"taylorball_study_{name}", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def figure_studies() -> List[str]:
    """Names of the figure studies, in figure order."""
    return sorted(p.stem for p in STUDIES_DIR.glob("fig*.py"))


def run(module, *, full: bool = False, outdir: Path = DEFAULT_OUT, plot_only: bool = False, log=print):
    """Compute (or load) one study's data, save it with its sidecar, and plot it."""
    from taylorball.io import load_result, save_result

    name = module.__name__.replace("taylorball_study_", "").split(".")[-1]
    cfg = module.FULL if full else module.QUICK
    outdir = Path(outdir)
    data_path = outdir / "data" / f"{name}{'_full' if full else ''}.npz"
    t0 = time.perf_counter()
    if plot_only:
        arrays, side = load_result(data_path)
        meta = side["meta"]
    else:
        arrays, meta = module.compute(cfg)
        meta = {"study": name, "config": dataclasses.asdict(cfg), "quality": "full" if full else "quick", **meta}
        save_result(data_path, arrays, meta)
        from taylorball.io import jsonable

        meta = jsonable(meta)
    t1 = time.perf_counter()
    figs = module.plot(arrays, meta, outdir / "figures")
    log(f"{name}: data {data_path} ({t1 - t0:.1f} s); figures: " + ", ".join(str(f) for f in figs))
    return data_path, figs


def main(module, argv=None):
    """``python studies/<fig>.py [--full] [--out DIR] [--plot-only]``."""
    ap = argparse.ArgumentParser(description=module.__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true", help="publication density (slow)")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    ap.add_argument("--plot-only", action="store_true", help="re-plot saved data without computing")
    args = ap.parse_args(argv)
    run(module, full=args.full, outdir=args.out, plot_only=args.plot_only)
    return 0


# ---------------------------------------------------------------------------------------
# Plotting helpers (matplotlib imported lazily, Agg backend).
# ---------------------------------------------------------------------------------------
def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"figure.dpi": 110, "savefig.dpi": 150, "font.size": 9, "axes.titlesize": 9})
    return plt


def save_figure(fig, outdir: Path, stem: str) -> List[Path]:
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    paths = []
    for ext in ("png", "pdf"):
        p = outdir / f"{stem}.{ext}"
        fig.savefig(p, bbox_inches="tight")
        paths.append(p)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return paths


def orbit_colors(n):
    plt = pyplot()
    cmap = plt.get_cmap("turbo")
    return [cmap(x) for x in np.linspace(0.05, 0.95, max(n, 1))]


def scatter_orbits(ax, points, orbit, cols=(0, 1), size=0.6, **kw):
    """Scatter section points coloured by orbit index."""
    n = int(orbit.max()) + 1 if len(orbit) else 0
    colors = orbit_colors(n)
    for k in range(n):
        m = orbit == k
        ax.scatter(points[m, cols[0]], points[m, cols[1]], s=size, color=colors[k], linewidths=0, **kw)


def wrap_angle(a):
    return np.mod(a, 2 * math.pi)
