"""Momentum vs omega formulation of the reduced system: steps, wall time, integral drift.

``taylorball.model`` integrates the reduced system either in ``(M, gamma, R)`` with
``dM/dt = M x omega`` and ``omega`` from Sherman--Morrison ("momentum", the default) or in
the paper's variables ``(omega, gamma, R)`` with paper eq. (15) [eq10] literally ("omega"). This
benchmark integrates the same initial states with both, through
``taylorball.make_integrator(..., formulation=...)`` at the default tolerance (eps), and
reports for each state and span

* the number of Taylor steps and the wall time;
* the drift ``max_t |I(t) - I(0)| / scale`` of ``C2 = |M|^2``, ``M_gamma``, ``E``,
  ``gamma2``, ``R_gamma`` on a grid of samples, evaluated two ways:
  *public* -- on the public states (omega, gamma, R) that ``taylorball.propagate``
  returns, with ``taylorball._integrals`` (what a user sees);
  *internal* -- on the integrated variables themselves, with the compiled
  ``integrals_cfunc(kind, formulation)`` (what the integrator conserves);
* the medians over the states of the ratios omega/momentum.

System: the Fig. 5 ball (I = (2, 3, 4), m = 1, a = 5, Omega = 2); states: the demo state
and ``--states - 1`` random admissible states (seeded). The machine is shared (2 cores,
other jobs): wall times are noisy, the two formulations run back to back per state.

With ``--full-system`` the same for the full system (paper eqs. (8)-(10) [eq6]; integrals ``F1, F2, F3, E``),
from the same states lifted to SO(3) x R^2 by ``taylorball.reduced_to_full``.

Run: ``python benchmarks/bench_formulation.py [--quick] [--full-system]`` (``--quick``:
spans 1e3, 1e4 and 3 states instead of 1e4, 1e5 and 5).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

INTEGRALS_BY_KIND = {"reduced": ("C2", "M_gamma", "E", "gamma2", "R_gamma"), "full": ("F1", "F2", "F3", "E")}
FORMULATIONS = ("momentum", "omega")


def demo_state():
    from taylorball.paper import demo_reduced_state

    return demo_reduced_state()


def initial_states(n, seed=2024):
    """The demo state and ``n - 1`` random states: omega ~ N(0, 0.5^2), gamma uniform on
    the sphere, R ~ N(0, 1) projected onto (R, gamma) = 0."""
    import taylorball as tb

    rng = np.random.default_rng(seed)
    out = [tb.project("reduced", demo_state())]
    while len(out) < n:
        g = rng.normal(size=3)
        x = np.concatenate([0.5 * rng.normal(size=3), g / np.linalg.norm(g), rng.normal(size=3)])
        out.append(tb.project("reduced", x))
    return out


def _drift(I, S):
    return {k: float(np.max(np.abs(I[k] - I[k][0])) / np.max(np.abs(S[k]))) for k in I}


def run(params, x0, span, n_samples, formulation, kind="reduced"):
    import taylorball as tb
    from taylorball._integrals import integrals_cfunc
    from taylorball._propagate import public_state

    grid = np.linspace(0.0, span, n_samples + 1)
    t0 = time.perf_counter()
    ta, system, spec = tb.make_integrator(kind, params, x0, formulation=formulation)
    res = ta.propagate_grid(grid)
    wall = time.perf_counter() - t0
    if res[0] != __import__("heyoka").taylor_outcome.time_limit:
        raise RuntimeError(f"integration failed: {res[0]}")
    internal = res[-1]
    pars = np.array(ta.pars)
    d_int = _drift(integrals_cfunc(kind, formulation)(internal, pars),
                   integrals_cfunc(kind, formulation, which="scales")(internal, pars))
    pub = np.stack([public_state(system, pars, row, spec) for row in internal])
    d_pub = _drift(tb.integrals(kind, params, pub, check=False),
                   tb.integral_scales(kind, params, pub, check=False))
    return dict(steps=int(res[3]), wall=wall, internal=d_int, public=d_pub)


def _fmt(d):
    return " ".join(f"{v:8.1e}" for v in d.values())


def report(kind, params, states, spans, n_samples):
    """Run both formulations on every state and span of ``kind``; print the tables."""
    import taylorball as tb

    names = INTEGRALS_BY_KIND[kind]
    x0s = states if kind == "reduced" else [tb.reduced_to_full(params, x) for x in states]
    results = {}
    for span in spans:
        for i, x0 in enumerate(x0s):
            for f in FORMULATIONS:
                results[(span, i, f)] = run(params, x0, span, n_samples, f, kind)

    hdr = " ".join(f"{k:>8s}" for k in names)
    for which in ("public", "internal"):
        print(f"\n[{kind}] drift max|dI|/scale, evaluated on {which} states")
        print(f"{'span':>6s} {'state':>5s} {'form':>9s} {'steps':>9s} {'wall s':>7s}  {hdr}")
        for span in spans:
            for i in range(len(x0s)):
                for f in FORMULATIONS:
                    r = results[(span, i, f)]
                    print(f"{span:6.0e} {i:5d} {f:>9s} {r['steps']:9d} {r['wall']:7.3f}  {_fmt(r[which])}")

    print(f"\n[{kind}] medians over states of omega / momentum (> 1: momentum better):")
    print(f"{'span':>6s} {'steps':>6s} {'wall':>6s}  drift public: {hdr}   drift internal: {hdr}")
    for span in spans:
        def med(fn):
            return statistics.median(fn(results[(span, i, "omega")], results[(span, i, "momentum")])
                                     for i in range(len(x0s)))
        st = med(lambda o, m: o["steps"] / m["steps"])
        wl = med(lambda o, m: o["wall"] / m["wall"])
        dp = {k: med(lambda o, m, k=k: o["public"][k] / m["public"][k]) for k in names}
        di = {k: med(lambda o, m, k=k: o["internal"][k] / m["internal"][k]) for k in names}
        print(f"{span:6.0e} {st:6.3f} {wl:6.2f}  {'':14s}" + " ".join(f"{dp[k]:8.2f}" for k in names)
              + f"   {'':16s}" + " ".join(f"{di[k]:8.2f}" for k in names))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--states", type=int, default=None, help="number of initial states (default 5, quick 3)")
    ap.add_argument("--samples", type=int, default=2000, help="grid samples per span")
    ap.add_argument("--full-system", action="store_true",
                    help="also the full system (paper eqs. (8)-(10) [eq6]) from the same states lifted by "
                         "reduced_to_full")
    args = ap.parse_args(argv)

    import heyoka as hy

    import taylorball as tb
    from taylorball.paper import FIG5_BALL

    params = FIG5_BALL
    spans = (1e3, 1e4) if args.quick else (1e4, 1e5)
    states = initial_states(args.states or (3 if args.quick else 5))
    print("systems: reduced (eqs. (15)-(16) [eq10])"
          + (" and full (eqs. (8)-(10) [eq6])" if args.full_system else "")
          + ", I=(2,3,4), m=1, a=5, Omega=2; tol = eps (float64)")
    print(f"heyoka {hy.__version__}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} "
          "(shared machine: wall times noisy; step counts and drifts are not)")
    for f in FORMULATIONS:  # compile outside the timings
        tb.propagate("reduced", params, states[0], 1.0, formulation=f)

    kinds = ("reduced", "full") if args.full_system else ("reduced",)
    if args.full_system:
        tb.propagate("full", params, tb.reduced_to_full(params, states[0]), 1.0)
        tb.propagate("full", params, tb.reduced_to_full(params, states[0]), 1.0, formulation="omega")
    for kind in kinds:
        report(kind, params, states, spans, args.samples)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
