"""One ``poincare_section`` call against raw heyoka doing the same work.

System: the Fig. 4a ball (I = (2, 3, 4), m = 1, a = 5, Omega = 2), the first Fig. 4a
orbit of ``bench_refactor.py`` (levels C = G = 10, M_gamma = H = 2, h = 5, the chart point
``section_admissible_sample(..., n=16, direction=1, seed=0)[0]``), section g = 0,
direction +1, float64, tolerance eps.

Both sides are warm (compiled before the clock starts) and timed interleaved, best of
``--repeats`` (default 5):

* taylorball: one public call ``tb.poincare_section("reduced", ball, x0, n_points=N)``,
  everything included (argument checks, start state, integration, results, provenance);
* raw heyoka: a ``hy.taylor_adaptive`` of the same equations with the same ``nt_event``
  (the section event function, direction +1), built once before timing; per run its
  state, parameters and time are reset and it is propagated in one ``propagate_until``
  to the time of the N-th crossing (taken from the taylorball result: the shortest span
  that contains the N crossings, so the raw side never integrates past them), its
  callback recording each crossing's time and dense-output state, kept crossings then
  selected by the half-line test. It does none of taylorball's extra work (Newton
  refinement of each crossing, integrals, chart, public states, provenance).

Ratio = taylorball best / raw best, for N = 120 (the issue's target: <= 1.25) and N = 1:
per round (each side's best of ``--repeats`` calls, one call of each side in turn), their
median, and the ratio of the best over all rounds; also of the process's CPU time
(``time.process_time``, less sensitive to other jobs on the machine than wall time).
The script checks that both sides find crossings at the same times (to 1e-9: the raw
side's times are heyoka's unrefined roots) and prints the machine's load average
(the machine is shared: compare ratios, measured in the same run).

Run: ``python benchmarks/bench_section_call.py [--repeats 5] [--rounds 3]`` (each round
is a full best-of measurement; the median over rounds of the ratio is printed too).
Exit status 1 if the two sides disagree on the crossings.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np


def _fig4a_state():
    import taylorball as tb
    from taylorball.paper import FIG4_BALL

    lev = dict(C=10.0, M_gamma=2.0, h=5.0)
    pts = tb.section_admissible_sample(FIG4_BALL, n=16, direction=1, seed=0, **lev)["points"]
    return tb.states_on_section(FIG4_BALL, point=tuple(pts[0]), direction=1, **lev)[0]


class _Record:
    """The raw side's event callback: crossing time and dense-output state, nothing else."""

    def __init__(self):
        self.times, self.states = [], []

    def __deepcopy__(self, memo):
        return _Record()

    def __call__(self, ta, t, d_sgn):
        hi, lo = ta.dtime
        self.times.append(t)
        self.states.append(ta.update_d_output((t - hi) - lo, rel_time=True).copy())


def _raw_integrator(kind, g0):
    import heyoka as hy

    from taylorball.model import get_system
    from taylorball.sections import _event_expression

    system = get_system(kind)
    ev = hy.nt_event(_event_expression(kind, g0), _Record(), direction=hy.event_direction.positive)
    return hy.taylor_adaptive(system.equations(), [0.1] * system.dim, pars=[0.0] * system.n_pars,
                              nt_events=[ev])


def _raw_run(ta, internal, pars, t_span, g0):
    from taylorball.sections import START_TOL, _branch_mask
    from taylorball.numbers import resolve_fp_type

    cb = ta.nt_events[0].callback
    cb.times.clear()
    cb.states.clear()
    ta.state[:] = internal
    ta.pars[:] = pars
    ta.time = 0.0
    ta.propagate_until(t_span)
    keep = _branch_mask(cb.states, g0, resolve_fp_type(float))
    return [t for t, k in zip(cb.times, keep) if k and t > START_TOL]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5, help="best of this many calls per side and round")
    ap.add_argument("--rounds", type=int, default=3, help="rounds (median of the per-round ratios)")
    args = ap.parse_args(argv)

    import heyoka as hy

    import taylorball as tb
    from taylorball._problem import problem
    from taylorball._propagate import start_state
    from taylorball.paper import FIG4_BALL

    x0 = _fig4a_state()
    prob = problem("reduced", FIG4_BALL)
    internal = start_state(prob, x0)
    pars = np.asarray(prob.pars, dtype=float)
    raw = _raw_integrator("reduced", 0.0)
    print(f"heyoka {hy.__version__}, taylorball {tb.__version__}, {os.cpu_count()} cores, "
          f"load average at start {os.getloadavg()[0]:.2f} (shared machine: compare the ratios)")
    ok = True
    for n in (120, 1):
        ref = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=n)  # warm: compiled and cached
        t_span = float(ref.times[-1])
        got = _raw_run(raw, internal, pars, t_span, 0.0)  # warm
        # the raw side stops at the N-th crossing itself: heyoka may or may not report a root
        # exactly at the end of the span, so N - 1 kept crossings are accepted there
        same = len(got) in (n, n - 1) and np.allclose(got, ref.times[:len(got)], rtol=0, atol=1e-9)
        ok &= bool(same)
        wall = {"tb": [], "raw": []}  # per round: best of the round's repeats
        cpu = {"tb": [], "raw": []}
        sides = {"tb": lambda: tb.poincare_section("reduced", FIG4_BALL, x0, n_points=n),
                 "raw": lambda: _raw_run(raw, internal, pars, t_span, 0.0)}
        for _ in range(args.rounds):
            w = {"tb": [], "raw": []}
            c = {"tb": [], "raw": []}
            for _ in range(args.repeats):
                for side, fn in sides.items():  # interleaved: one call of each in turn
                    c0, t0 = time.process_time(), time.perf_counter()
                    fn()
                    w[side].append(time.perf_counter() - t0)
                    c[side].append(time.process_time() - c0)
            for side in sides:
                wall[side].append(min(w[side]))
                cpu[side].append(min(c[side]))
        ratios = [a / b for a, b in zip(wall["tb"], wall["raw"])]
        per_round = ", ".join(f"{r:.3f}" for r in ratios)
        print(f"N = {n:3d} crossings (span {t_span:.4g} t.u.; taylorball t_end {ref.t_end:.6g}, "
              f"{ref.n_steps} steps; same crossings: {same})\n"
              f"  wall, best of {args.repeats} per round: taylorball {min(wall['tb']) * 1e3:7.3f} ms, raw heyoka "
              f"{min(wall['raw']) * 1e3:7.3f} ms; ratio of the bests {min(wall['tb']) / min(wall['raw']):.3f}, "
              f"per round {per_round} (median {statistics.median(ratios):.3f})\n"
              f"  CPU time of the process, best: taylorball {min(cpu['tb']) * 1e3:7.3f} ms, raw heyoka "
              f"{min(cpu['raw']) * 1e3:7.3f} ms; ratio {min(cpu['tb']) / min(cpu['raw']):.3f}")
    print(f"load average at end {os.getloadavg()[0]:.2f}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
