"""The figure runner: compute (or load) a study's data, save it with its sidecar, plot it.

Each study module of :mod:`taylorball.figures` defines a frozen ``Config``, ``QUICK`` and
``FULL`` instances, ``compute(cfg) -> (arrays: dict, meta: dict)`` (pure: no files, no
plotting) and ``plot(arrays, meta, outdir) -> list[Path]`` (no computation). :func:`run`
ties them together; ``taylorball reproduce`` calls it for every figure, and the scripts in
the checkout's ``studies/`` folder call :func:`main`.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import inspect
import logging
import time
from pathlib import Path
from typing import List

from ..errors import UsageError

_log = logging.getLogger("taylorball.figures")

__all__ = ["FIGURES", "ON_REQUEST", "STUDIES", "DEFAULT_OUT", "figure_studies", "load_study", "schedule", "run", "main"]

#: The figure studies, in figure order (the modules ``taylorball.figures.<name>``).
FIGURES = ("fig1_mparallel_map", "fig2_homogeneous", "fig3_symmetric", "fig4_asymmetric_map",
           "fig5_contact_point")

#: Studies beyond the paper's figures that ``taylorball reproduce`` runs too (quick in seconds).
EXTRA_FIGURES = ("megno_map", "chaos_atlas", "diffusion")

#: Studies that ``taylorball reproduce`` runs only when named (``--only skeleton``): kept out
#: of the quick default, whose first minute is part of the product.
ON_REQUEST = ("skeleton", "skeleton_bifurcation", "skeleton_surface", "skeleton_tori")

#: Every study: the figures and the studies beyond them.
STUDIES = FIGURES + EXTRA_FIGURES + ON_REQUEST + ("contact_diffusion", "diffusion_large")

#: Default output folder (relative to the working directory, as ``taylorball reproduce --out``).
DEFAULT_OUT = Path("output")


def figure_studies() -> List[str]:
    """Names of the studies ``taylorball reproduce`` runs: the figures in figure order, then
    :data:`EXTRA_FIGURES`."""
    return list(FIGURES + EXTRA_FIGURES)


#: Rough CPU seconds of each quick study on an empty compile cache (data, compilation and
#: plotting, each alone in a fresh process; AMD EPYC Zen 5, 2026-11-27, load ~3), for
#: :func:`schedule`. Their sum is about twice the cold ``taylorball reproduce`` on 2 cores.
#: (``diffusion`` remeasured after its MEGNO classes and Monte Carlo reference were added:
#: 8.2 s data + 2.5 s plots, cold, quiet machine, ``bench_reproduce.py --quick-cold``.)
#: (``megno_map`` after its quick map went to T = 500 on 8 x 8 so that it shows the full map's
#: chaos: its three panels took 4.0 + 4.3 + 1.6 CPU s alone, 2026-11-28, load ~10.)
#: (``fig3_symmetric`` and ``fig1_mparallel_map`` after their MEGNO cuts, 2026-11-28: scaled by
#: the ratio measured in one run of ``bench_reproduce.py --per-study --against``, 11.9 -> 7.7
#: and 9.9 -> 8.2 CPU s at load ~14.)
QUICK_CPU_S = {"fig3_symmetric": 7.4, "fig4_asymmetric_map": 9.9, "fig1_mparallel_map": 4.8, "diffusion": 10.7,
               "fig2_homogeneous": 5.1, "chaos_atlas": 4.8, "megno_map": 11.0, "fig5_contact_point": 3.2,
               # skeleton: 15.4 CPU s with heyoka's disk cache warm, 8.1 of it the Fig. 3 saddle's manifold
               # and homoclinic point (2026-11-28, shared 2-core machine, load ~7)
               "skeleton": 15.4,
               # skeleton_bifurcation: 25.5 CPU s with its held-in-place panels, warm compile cache
               # (2026-11-29, shared 2-core machine under load)
               "skeleton_bifurcation": 25.5,
               # skeleton_surface: 5.3 CPU s, warm compile cache (2026-11-29, shared 2-core machine, load ~5)
               "skeleton_surface": 5.3,
               # skeleton_tori: 18.7 CPU s, warm compile cache (2026-11-29, shared 2-core machine under load)
               "skeleton_tori": 18.7}

#: Quick studies that compile the same integrators (the reduced system's batch section and
#: MEGNO integrators, ~2 CPU s on an empty cache): :func:`schedule` does not start two of
#: them at once, so that the second finds them in heyoka's disk cache. (Two studies that
#: meet later compile a shared key once as well: :func:`run` shares builds between the
#: processes, and the second waits for the first's; this order keeps that wait out of the
#: run's start.)
SHARED_COMPILES = ("fig2_homogeneous", "fig3_symmetric", "fig4_asymmetric_map", "fig5_contact_point", "megno_map")


def schedule(names, jobs: int) -> List[str]:
    """``names`` in the order ``jobs`` worker processes should take them (``taylorball
    reproduce``, quick): longest first (:data:`QUICK_CPU_S`), so that the short ones even out
    the workers' ends, except that the first ``jobs`` studies include at most one of
    :data:`SHARED_COMPILES` (two processes compiling the same system at once each pay the
    compilation). Names without a cost keep their order, at the end."""
    rest = sorted((n for n in names if n in QUICK_CPU_S), key=lambda n: -QUICK_CPU_S[n])
    first: List[str] = []
    for n in list(rest):
        if len(first) == jobs:
            break
        if n not in SHARED_COMPILES or not any(f in SHARED_COMPILES for f in first):
            first.append(n)
            rest.remove(n)
    return first + rest + [n for n in names if n not in QUICK_CPU_S]


def load_study(name: str):
    """The study module ``taylorball.figures.<name>`` (``name`` one of :data:`STUDIES`)."""
    if name not in STUDIES:
        raise UsageError(f"study must be one of {list(STUDIES)}, got {name!r}")
    return importlib.import_module(f"{__package__}.{name}")


def data_path(name: str, outdir: Path, full: bool = False) -> Path:
    """Where study ``name`` keeps its data (an ``.npz`` with a ``.json`` sidecar)."""
    return Path(outdir) / "data" / f"{name}{'_full' if full else ''}.npz"


def check_plot_only(names, outdir: Path, full: bool = False) -> None:
    """Before ``--plot-only`` does anything: every study's saved data must be there."""
    missing = [str(data_path(n, outdir, full)) for n in names if not data_path(n, outdir, full).exists()]
    if missing:
        raise UsageError(f"--plot-only re-plots saved data, but there is none for: {', '.join(missing)}; "
                         "run without --plot-only first (same --out" + (" and --full" if full else "") + ")")


def run(module, *, full: bool = False, outdir: Path = DEFAULT_OUT, plot_only: bool = False, log=print):
    """Compute (or load) one study's data, save it with its sidecar, and plot it.

    Builds of compiled code are shared with other processes running studies at the same
    time (``taylorball reproduce``'s workers): one compiles, the others load its machine
    code from heyoka's disk cache (:func:`taylorball._cache.share_builds_between_processes`)."""
    from .._cache import share_builds_between_processes
    from ..io import jsonable, load_result, save_result

    share_builds_between_processes()

    name = module.__name__.rpartition(".")[2]
    cfg = module.FULL if full else module.QUICK
    outdir = Path(outdir)
    if plot_only:
        check_plot_only([name], outdir, full)
    data_path_ = data_path(name, outdir, full)
    t0, c0 = time.perf_counter(), time.process_time()
    if plot_only:
        arrays, side = load_result(data_path_)
        meta = side["meta"]
    else:
        # a study with long runs keeps their checkpoints under the output folder (resumable)
        kw = {"workdir": outdir / "longruns"} if "workdir" in inspect.signature(module.compute).parameters else {}
        arrays, meta = module.compute(cfg, **kw)
        meta = {"study": name, "config": dataclasses.asdict(cfg), "quality": "full" if full else "quick", **meta}
        save_result(data_path_, arrays, meta)
        meta = jsonable(meta)
    t1, c1 = time.perf_counter(), time.process_time()
    figs = module.plot(arrays, meta, outdir / "figures")
    _log.debug("%s: data %.1f s (%.1f s CPU), plots %.1f s (%.1f s CPU)", name, t1 - t0, c1 - c0,
               time.perf_counter() - t1, time.process_time() - c1)
    log(f"{name}: data {data_path_} ({t1 - t0:.1f} s); figures: " + ", ".join(str(f) for f in figs))
    return data_path_, figs


def main(module, argv=None, *, default_out: Path = DEFAULT_OUT) -> int:
    """``python studies/<fig>.py [--full] [--out DIR] [--plot-only]`` (the scripts pass their
    checkout's ``output/`` as ``default_out``)."""
    ap = argparse.ArgumentParser(description=module.__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true", help="publication density (slow)")
    ap.add_argument("--out", type=Path, default=default_out, help=f"output folder (default {default_out})")
    ap.add_argument("--plot-only", action="store_true", help="re-plot saved data without computing")
    args = ap.parse_args(argv)
    run(module, full=args.full, outdir=args.out, plot_only=args.plot_only)
    return 0
