"""Propagation speed and integral drift: taylorball vs raw heyoka vs scipy DOP853.

System: the reduced system (paper eqs. (15)-(16) [eq10]) of the Fig. 5 ball, I = (2, 3, 4), m = 1, a = 5,
Omega = 2, from the demo state of ``taylorball demo`` (float64, projected onto
``|gamma| = 1``, ``(R, gamma) = 0`` once, in float64; all three integrators start from the
same bits).

Integrators, all measured in this run on the same machine:

(a) ``taylorball.propagate`` on a time grid (default "momentum" formulation; also the
    "omega" formulation, which integrates paper eqs. (15)-(16) [eq10] literally);
(b) raw heyoka: ``hy.taylor_adaptive`` on paper eqs. (15)-(16) [eq10] written by hand below (Itilde as an
    explicit 3x3 matrix with the paper's ``gamma^2 E``, ``domega/dt`` by Cramer's rule),
    numeric parameters baked into the expression graph, default tolerance (eps); and,
    to isolate the wrapper's overhead, raw heyoka on taylorball's own momentum graph
    (same steps as (a));
(c) scipy ``solve_ivp(method="DOP853")`` at its tightest accepted tolerance, ``rtol =
    100 eps`` (scipy raises anything lower to this, with a warning) and ``atol = 1e-300``
    so that only rtol acts, on the same hand-written paper eqs. (15)-(16) [eq10] evaluated on Python floats.
    DOP853 is ~200 times slower per time unit (measured), so it runs over a shorter span
    (``--scipy-span``); its rates are per time unit and its drift is over that span only.

Drift: ``max_t |I(t) - I(0)| / scale`` for each integral of ``taylorball._integrals``
(``C2 = |M|^2``, ``M_gamma``, ``E``, ``gamma2``, ``R_gamma``), sampled on a grid of
``--samples`` times, ``scale`` = ``taylorball.integral_scales`` (max over the samples).
Wall times are medians over ``--repeats`` rounds (each round runs every Taylor integrator
once, in a rotated order) and each ratio is the median of the per-round ratios: the
machine is shared (2 cores, other jobs running), so compare the ratios.

Run: ``python benchmarks/bench_propagate.py [--quick]`` (``--quick``: spans 1e3 and 1e4
instead of 1e4 and 1e5). ``--fp-types`` instead measures the cost per step of float64,
long double, real128 and 256-bit ``heyoka.real`` on the same system.

``--many``: ``taylorball.propagate`` of an array of ``n`` states (shape ``(n, 9)``, the SIMD
lanes, ``workers=1``) against raw heyoka batch mode (``hy.taylor_adaptive_batch`` of
``hy.recommended_simd_size()`` lanes on taylorball's own graph, the states' internal
variables loaded by hand, ``propagate_until`` per group of lanes, a fresh integrator copy
per call) and against a loop of one-state ``propagate`` calls; CPU seconds of the process
(``time.process_time``), rounds in a rotated order, medians of per-round ratios.
``--fixed``: the fixed cost of one ``propagate`` call (span 1e-3, one step): CPU per call of
``propagate(problem, x, t)`` and ``propagate("reduced", ball, x, t)`` against raw heyoka
stepping a reused integrator (state and time set, ``propagate_until``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
import warnings

import numpy as np

INTEGRALS = ("C2", "M_gamma", "E", "gamma2", "R_gamma")


def demo_state():
    """The demo state of ``taylorball demo``: omega, gamma, R with (R, gamma) = 0."""
    from taylorball.paper import demo_reduced_state

    return demo_reduced_state()


# ---------------------------------------------------------------------------------------
# Paper eqs. (15)-(16) [eq10] by hand, on any scalars with + - * / (heyoka expressions or Python floats).
# ---------------------------------------------------------------------------------------
def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _cross(u, v):
    return (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


def eq10_rhs(state, inertia, m, a, Omega):
    r"""Paper eqs. (15)-(16) [eq10], written out directly:

    .. math::
        \tilde I \dot\omega = I\omega\times\omega - m a\Omega(\omega,\gamma) R\times\gamma
                              - m a\Omega(\dot R\times\gamma)\times\gamma,\quad
        \dot\gamma = \gamma\times\omega,\quad
        \dot R = R\times(\omega - \Omega\gamma) - a\gamma\times\omega,

    with ``Itilde = I + m a^2 (gamma^2 E - gamma gamma^T)`` as a 3x3 matrix and
    ``domega/dt`` from Cramer's rule (no Sherman--Morrison, no ``gamma^2 = 1``: an
    implementation independent of :mod:`taylorball.model`)."""
    w, g, R = tuple(state[0:3]), tuple(state[3:6]), tuple(state[6:9])
    d = m * a * a
    mao = m * a * Omega
    g2 = _dot(g, g)
    T = [[None] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(3):
            T[i][j] = inertia[i] + d * (g2 - g[i] * g[i]) if i == j else -d * g[i] * g[j]
    Rdot = tuple(
        x - a * y for x, y in zip(_cross(R, tuple(wi - Omega * gi for wi, gi in zip(w, g))), _cross(g, w))
    )
    Iw = tuple(inertia[i] * w[i] for i in range(3))
    wg = _dot(w, g)
    t1, t2, t3 = _cross(Iw, w), _cross(R, g), _cross(_cross(Rdot, g), g)
    b = tuple(t1[k] - mao * wg * t2[k] - mao * t3[k] for k in range(3))
    c0, c1, c2 = (T[0][0], T[1][0], T[2][0]), (T[0][1], T[1][1], T[2][1]), (T[0][2], T[1][2], T[2][2])
    c1xc2 = _cross(c1, c2)
    inv_det = 1.0 / _dot(c0, c1xc2)
    wdot = (_dot(b, c1xc2) * inv_det, _dot(c0, _cross(b, c2)) * inv_det, _dot(c0, _cross(c1, b)) * inv_det)
    return (*wdot, *_cross(g, w), *Rdot)


# ---------------------------------------------------------------------------------------
# Measurements.
# ---------------------------------------------------------------------------------------
def drift(params, states):
    """``max |I(t) - I(0)| / scale`` per integral over sampled public states (float64)."""
    import taylorball as tb

    X = np.asarray(states, dtype=float)
    I = tb.integrals("reduced", params, X, check=False)
    S = tb.integral_scales("reduced", params, X, check=False)
    return {k: float(np.max(np.abs(I[k] - I[k][0])) / np.max(np.abs(S[k]))) for k in INTEGRALS}


def _median_wall(fn, repeats):
    walls, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t0)
    return statistics.median(walls), out


def run_taylorball(params, x0, span, n_samples, repeats, formulation=None):
    """Wall time (median) of ``tb.propagate`` on a grid, its step count (from the same
    integration through ``make_integrator``, checked bit-identical), and the drift."""
    import taylorball as tb

    grid = np.linspace(0.0, span, n_samples + 1)
    wall, X = _median_wall(lambda: tb.propagate("reduced", params, x0, grid, formulation=formulation), repeats)
    ta, system, spec = tb.make_integrator("reduced", params, x0, formulation=formulation)
    res = ta.propagate_grid(grid)
    from taylorball._propagate import public_state

    last = public_state(system, np.array(ta.pars), res[-1][-1], spec)
    assert np.array_equal(last, X[-1]), "make_integrator and propagate took different steps"
    return dict(wall=wall, steps=int(res[3]), drift=drift(params, X), t=span)


def raw_heyoka_integrator(params):
    import heyoka as hy

    xs = hy.make_vars("w1", "w2", "w3", "g1", "g2", "g3", "R1", "R2", "R3")
    rhs = eq10_rhs(xs, params.inertia, params.mass, params.radius, params.plane_rate)
    return hy.taylor_adaptive(list(zip(xs, rhs)), [0.0] * 9)


def raw_package_graph_integrator(params):
    """Raw heyoka on taylorball's own momentum-form graph (``System.equations()``, runtime
    ``hy.par``): the same steps as (a) without the wrapper, to isolate its overhead."""
    import heyoka as hy

    import taylorball as tb

    return hy.taylor_adaptive(tb.get_system("reduced").equations(), [0.0] * 9, pars=list(params.pars))


def run_raw(ta_template, params, x0, span, n_samples, repeats, to_internal=None):
    import copy

    grid = np.linspace(0.0, span, n_samples + 1)

    start = x0 if to_internal is None else to_internal(x0)

    def once():
        ta = copy.copy(ta_template)
        ta.state[:] = start
        ta.time = 0.0
        return ta.propagate_grid(grid)

    wall, res = _median_wall(once, repeats)
    X = res[-1] if to_internal is None else _to_public(params, res[-1])
    return dict(wall=wall, steps=int(res[3]), drift=drift(params, X), t=span)


def _to_public(params, internal):
    import taylorball as tb

    system = tb.get_system("reduced")
    cols = tuple(internal[:, i] for i in range(9))
    return np.column_stack(system.to_public(tuple(params.pars), cols))


def _to_internal(params):
    """The internal start state exactly as taylorball forms it (projection in the working
    precision, omega -> M), so that the raw run takes the same steps."""
    from taylorball.numbers import resolve_fp_type
    from taylorball._propagate import working_state

    return lambda x0: working_state("reduced", params, x0, resolve_fp_type(float))[2]


def run_scipy(params, x0, span, n_samples):
    from scipy.integrate import solve_ivp

    I, m, a, Om = params.inertia, params.mass, params.radius, params.plane_rate
    nfev = [0]

    def rhs(t, x):
        nfev[0] += 1
        return eq10_rhs(x.tolist(), I, m, a, Om)

    eps = np.finfo(float).eps
    grid = np.linspace(0.0, span, n_samples + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # refuse a silently clipped rtol
        t0 = time.perf_counter()
        sol = solve_ivp(rhs, (0.0, span), x0, method="DOP853", rtol=100 * eps, atol=1e-300, t_eval=grid)
        wall = time.perf_counter() - t0
    if not sol.success:
        raise RuntimeError(f"DOP853 failed: {sol.message}")
    steps = (nfev[0] - 1) // 12  # DOP853: 12 evaluations per step (accepted or rejected)
    return dict(wall=wall, steps=steps, nfev=nfev[0], drift=drift(params, sol.y.T), t=span)


def fp_type_costs(params, x0, rounds):
    """Cost per Taylor step of each number type (compile excluded, reported apart).

    Each type integrates the same state over a span giving a few thousand steps (its
    tolerance is its own epsilon, so the orders and step counts differ); reported: us per
    step, us per time unit, and both relative to float64 measured in the same round."""
    import heyoka as hy

    import taylorball as tb

    types = [("float", float, None, 200.0), ("longdouble", np.longdouble, None, 50.0),
             ("real128", hy.real128, None, 40.0), ("real 256 bits", hy.real, 256, 12.0)]
    compile_s = {}
    for name, fp, prec, _ in types:
        t0 = time.perf_counter()
        tb.make_integrator("reduced", params, x0, fp_type=fp, prec=prec)
        compile_s[name] = time.perf_counter() - t0
    per = {name: [] for name, *_ in types}
    for _ in range(rounds):
        for name, fp, prec, span in types:
            ta, system, spec = tb.make_integrator("reduced", params, x0, fp_type=fp, prec=prec)
            t0 = time.perf_counter()
            res = ta.propagate_until(spec.scalar(span))
            wall = time.perf_counter() - t0
            per[name].append((wall / int(res[3]), wall / span, int(res[3]), ta.order))
    print(f"\nnumber types (reduced system, tol = eps of the type; medians of {rounds} rounds):")
    print(f"{'type':>14s} {'order':>5s} {'steps':>6s} {'us/step':>10s} {'x float':>8s} {'us/t.u.':>10s} {'x float':>9s} "
          f"{'first make_integrator s':>24s}")
    f_step = statistics.median(r[0] for r in per["float"])
    f_tu = statistics.median(r[1] for r in per["float"])
    for name, *_ in types:
        st = statistics.median(r[0] for r in per[name])
        tu = statistics.median(r[1] for r in per[name])
        print(f"{name:>14s} {per[name][0][3]:5d} {per[name][0][2]:6d} {st * 1e6:10.2f} {st / f_step:8.1f} "
              f"{tu * 1e6:10.1f} {tu / f_tu:9.1f} {compile_s[name]:24.2f}")
    print("  (first make_integrator: compilation, or a hit in heyoka's in-memory/disk cache of machine code)")


def _states(n):
    """``n`` states near the demo state (omega perturbed by N(0, 0.05^2), seed 3), projected."""
    import taylorball as tb

    rng = np.random.default_rng(3)
    out = []
    for _ in range(n):
        s = demo_state()
        s[0:3] += 0.05 * rng.normal(size=3)
        out.append(tb.project("reduced", s))
    return np.stack(out)


def _header():
    import heyoka as hy

    print(f"heyoka {hy.__version__}, numpy {np.__version__}, {os.cpu_count()} cores, SIMD lanes "
          f"{hy.recommended_simd_size()}, load average {os.getloadavg()[0]:.2f} (shared machine: CPU seconds, "
          "compare ratios)")


def many_states(ns, span, rounds):
    """--many: CPU seconds of propagate over (n, 9) states vs raw batch mode vs a loop."""
    import copy

    import heyoka as hy

    import taylorball as tb
    from taylorball.paper import FIG5_BALL

    _header()
    prob = tb.problem("reduced", FIG5_BALL)
    size = int(hy.recommended_simd_size())
    system = tb.get_system("reduced")
    raw_template = hy.taylor_adaptive_batch(system.equations(), np.full((9, size), 0.1),
                                            pars=np.zeros((system.n_pars, size)))
    to_int = _to_internal(FIG5_BALL)
    pars = np.asarray(FIG5_BALL.pars, dtype=float)

    def raw(S):
        internal = [to_int(s) for s in S]
        out = []
        ta = copy.copy(raw_template)
        for start in range(0, len(internal), size):
            block = internal[start : start + size]
            ta.set_time(np.zeros(size))
            for lane in range(size):
                ta.state[:, lane] = block[min(lane, len(block) - 1)]
                ta.pars[:, lane] = pars
            ta.propagate_until(np.full(size, span))
            out.extend(np.array(ta.state[:, lane]) for lane in range(len(block)))
        return np.stack(out)

    runners = {
        "lanes": lambda S: tb.propagate(prob, S, span, workers=1),
        "raw batch": raw,
        "one by one": lambda S: np.stack([tb.propagate(prob, s, span) for s in S]),
    }
    tb.propagate(prob, _states(2), 1.0)  # compile / warm up outside the clock
    raw(_states(1))
    print(f"\nmany states: span {span:g}, reduced system, Fig. 5 ball, float64; CPU s per call")
    print(f"{'n':>4s} " + " ".join(f"{k:>12s}" for k in runners) + "   lanes/raw (rounds)          one-by-one/raw")
    keys = list(runners)
    for n in ns:
        S = _states(n)
        per = []
        for r in range(rounds):
            got = {}
            for key in keys[r % len(keys):] + keys[: r % len(keys)]:
                c0 = time.process_time()
                runners[key](S)
                got[key] = time.process_time() - c0
            per.append(got)
        med = {k: statistics.median(p[k] for p in per) for k in keys}
        rl = [p["lanes"] / p["raw batch"] for p in per]
        ro = [p["one by one"] / p["raw batch"] for p in per]
        print(f"{n:4d} " + " ".join(f"{med[k]:12.4f}" for k in keys)
              + f"   {statistics.median(rl):.3f} ({', '.join(f'{x:.3f}' for x in rl)})   {statistics.median(ro):.2f}")


def fixed_cost(rounds, calls=3000):
    """--fixed: CPU per propagate call over a one-step span against raw heyoka."""
    import copy

    import taylorball as tb
    from taylorball._propagate import integrator
    from taylorball.paper import FIG5_BALL

    _header()
    prob = tb.problem("reduced", FIG5_BALL)
    x0 = tb.project("reduced", demo_state())
    t = 1e-3
    tb.propagate(prob, x0, t)
    ta = copy.copy(integrator(prob))
    ta.pars[:] = prob.pars
    start = _to_internal(FIG5_BALL)(x0)

    def raw():
        ta.state[:] = start
        ta.time = 0.0
        ta.propagate_until(t)

    runners = {"propagate(problem, x, t)": lambda: tb.propagate(prob, x0, t),
               'propagate("reduced", ball, x, t)': lambda: tb.propagate("reduced", FIG5_BALL, x0, t),
               "raw heyoka (reused integrator)": raw}
    per = {k: [] for k in runners}
    for _ in range(rounds):
        for key, fn in runners.items():
            c0 = time.process_time()
            for _ in range(calls):
                fn()
            per[key].append((time.process_time() - c0) / calls * 1e3)
    raw_ms = statistics.median(per["raw heyoka (reused integrator)"])
    print(f"\nfixed cost per call (span {t:g}, one step; CPU ms per call, median of {rounds} rounds of {calls})")
    for key, v in per.items():
        m = statistics.median(v)
        print(f"  {key:34s} {m:.4f} ms  (fixed cost over raw: {m - raw_ms:.4f} ms; rounds "
              + ", ".join(f"{x:.4f}" for x in v) + ")")


def _fmt_drift(d):
    return "  ".join(f"{k}={d[k]:.1e}" for k in INTEGRALS)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="spans 1e3 and 1e4 instead of 1e4 and 1e5")
    ap.add_argument("--repeats", type=int, default=3, help="rounds of the Taylor runs (medians)")
    ap.add_argument("--samples", type=int, default=2000, help="grid samples per span for the drift")
    ap.add_argument("--scipy-span", type=float, default=None, help="time span of the DOP853 run (default 100, quick 20)")
    ap.add_argument("--fp-types", action="store_true",
                    help="only the cost per step of float64, long double, real128 and 256-bit real")
    ap.add_argument("--many", action="store_true", help="only many states: lanes vs raw heyoka batch mode")
    ap.add_argument("--many-n", type=int, nargs="+", default=[8, 64], help="numbers of states for --many")
    ap.add_argument("--many-span", type=float, default=100.0, help="time span of --many")
    ap.add_argument("--fixed", action="store_true", help="only the fixed cost of one propagate call")
    args = ap.parse_args(argv)
    if args.many or args.fixed:
        if args.many:
            many_states(args.many_n, args.many_span, args.repeats)
        if args.fixed:
            fixed_cost(args.repeats)
        return 0

    import heyoka as hy
    import scipy

    import taylorball as tb
    from taylorball.paper import FIG5_BALL

    params = FIG5_BALL
    x0 = tb.project("reduced", demo_state())
    spans = (1e3, 1e4) if args.quick else (1e4, 1e5)
    sp_span = args.scipy_span or (20.0 if args.quick else 100.0)
    print("system: reduced (eqs. (15)-(16) [eq10]), I=(2,3,4), m=1, a=5, Omega=2, demo state")
    print(f"heyoka {hy.__version__}, scipy {scipy.__version__}, numpy {np.__version__}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.2f} (shared machine: compare ratios)")

    if args.fp_types:
        fp_type_costs(params, x0, args.repeats)
        return 0

    # compile / warm up everything outside the timings
    t0 = time.perf_counter()
    raw = raw_heyoka_integrator(params)
    t_raw_compile = time.perf_counter() - t0
    rawpkg = raw_package_graph_integrator(params)
    for f in (None, "omega"):
        tb.propagate("reduced", params, x0, [0.0, 1.0], formulation=f)

    # Rounds: every integrator once per round, in a rotated order, so that load changes
    # on the shared machine hit all of them alike; walls are medians over rounds and each
    # ratio is the median of the per-round ratios. Steps and drifts are deterministic
    # (checked equal across rounds).
    runners = {
        "tb": lambda span: run_taylorball(params, x0, span, args.samples, 1),
        "tb-omega": lambda span: run_taylorball(params, x0, span, args.samples, 1, formulation="omega"),
        "raw": lambda span: run_raw(raw, params, x0, span, args.samples, 1),
        "rawpkg": lambda span: run_raw(rawpkg, params, x0, span, args.samples, 1, to_internal=_to_internal(params)),
    }
    keys = list(runners)
    rows, rounds = {}, {}
    for span in spans:
        per_round = []
        for r in range(args.repeats):
            got = {}
            for key in keys[r % len(keys):] + keys[: r % len(keys)]:
                got[key] = runners[key](span)
            per_round.append(got)
        for key in keys:
            first = per_round[0][key]
            assert all(pr[key]["steps"] == first["steps"] and pr[key]["drift"] == first["drift"] for pr in per_round)
            rows[(key, span)] = dict(first, wall=statistics.median(pr[key]["wall"] for pr in per_round))
        rounds[span] = per_round

    def ratio(span, a, b):
        return statistics.median(pr[a]["wall"] / pr[b]["wall"] for pr in rounds[span])

    # DOP853 rounds: each DOP853 run is followed by a taylorball run over spans[0]; the speed
    # ratio per time unit is the median of the per-round ratios.
    sp_rounds = []
    for r in range(args.repeats):
        sp_r = run_scipy(params, x0, sp_span, max(10, int(sp_span)))
        tb_r = runners["tb"](spans[0])
        sp_rounds.append((sp_r, (sp_r["wall"] / sp_span) / (tb_r["wall"] / spans[0])))
    sp = dict(sp_rounds[0][0], wall=statistics.median(x[0]["wall"] for x in sp_rounds))
    sp_speed = statistics.median(x[1] for x in sp_rounds)

    labels = {"tb": "taylorball.propagate (momentum)", "tb-omega": "taylorball.propagate (omega)",
              "raw": "raw heyoka, eqs. (15)-(16) [eq10] by hand", "rawpkg": "raw heyoka, taylorball's graph"}
    print(f"\n(raw heyoka compile: {t_raw_compile:.2f} s, excluded)")
    print(f"{'integrator':34s} {'span':>8s} {'steps':>9s} {'wall s':>8s} {'steps/s':>10s} {'wall/t.u.':>10s}  drift (max |dI|/scale)")
    for span in spans:
        for key in ("tb", "tb-omega", "raw", "rawpkg"):
            r = rows[(key, span)]
            print(f"{labels[key]:34s} {span:8.0e} {r['steps']:9d} {r['wall']:8.3f} {r['steps'] / r['wall']:10.3e} "
                  f"{r['wall'] / span:10.2e}  {_fmt_drift(r['drift'])}")
    print(f"{'scipy DOP853 rtol=100eps':34s} {sp_span:8.0e} {sp['steps']:9d} {sp['wall']:8.3f} "
          f"{sp['steps'] / sp['wall']:10.3e} {sp['wall'] / sp_span:10.2e}  {_fmt_drift(sp['drift'])}")
    print(f"  (DOP853 over {sp_span:g} time units only, {sp['nfev']} rhs calls; per-time-unit rates extrapolate)")

    print("\nratios (same run):")
    for span in spans:
        tb_r, raw_r = rows[("tb", span)], rows[("raw", span)]
        print(f"  span {span:.0e}: wall taylorball(momentum) / raw heyoka = {ratio(span, 'tb', 'raw'):.2f}, "
              f"taylorball(omega) / raw heyoka = {ratio(span, 'tb-omega', 'raw'):.2f}; "
              f"steps momentum / raw = {tb_r['steps'] / raw_r['steps']:.2f}; "
              f"taylorball(momentum) / raw heyoka on its graph = {ratio(span, 'tb', 'rawpkg'):.2f} "
              "(wrapper overhead, same steps)")
    big = spans[-1]
    sp_tpu = sp["wall"] / sp_span
    print(f"  speed per time unit, taylorball(momentum) vs scipy DOP853: {sp_speed:.0f}x (median of per-round "
          f"ratios, DOP853 over {sp_span:g} t.u. vs taylorball over {spans[0]:.0e} t.u.); from the medians: "
          + ", ".join(f"{labels[k]} {sp_tpu / (rows[(k, big)]['wall'] / big):.0f}x" for k in ("tb", "tb-omega", "raw")))
    print(f"  DOP853 estimated wall for {big:.0e} time units: {sp_tpu * big:.0f} s "
          f"(taylorball: {rows[('tb', big)]['wall']:.2f} s)")
    sp_worst = max(sp["drift"].values())
    tb_short = max(rows[("tb", spans[0])]["drift"].values())
    print(f"  worst drift: DOP853 over {sp_span:g} t.u. {sp_worst:.1e}; taylorball over {spans[0]:.0e} t.u. "
          f"{tb_short:.1e}, over {big:.0e} t.u. {max(rows[('tb', big)]['drift'].values()):.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
