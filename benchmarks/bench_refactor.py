"""Before/after timings of the architecture refactor, measured in the same run.

The refactor (the commits after ``c562eb2`` on main: a Problem object, one compile cache, a
Section object, the many-orbit engine ``taylorball.ensemble``) must not make propagation or
sections slower, and must not change a bit of their results. This script runs the same
measurements on the code before the refactor and on the current checkout, each in its own
interpreter, and compares the wall times and the results' bits.

Measurements (all float64, the Fig. 4/5 ball ``BallParams(inertia=(2, 3, 4), mass=1,
radius=5, plane_rate=2)``, reduced system, public functions only: their signatures are the
same before and after):

* ``propagate_long``: ``tb.propagate`` of the demo state to ``t = 1e4`` (~2.3e5 steps);
* ``propagate_short``: 2000 chained ``tb.propagate`` calls of ``t = 0.1`` (the per-call
  boundary work dominates: parameters, validation, projection, template copy);
* ``section_scalar``: one ``tb.poincare_section`` of a Fig. 4a orbit, 120 crossings
  (timed ``--inner`` times per round: one call is ~20 ms);
* ``sections_lanes``: ``tb.poincare_sections(..., batch=True)``, 16 Fig. 4a orbits x 500
  crossings (the SIMD-lane path);
* ``sections_threads``: ``tb.poincare_sections`` (scalar integrators on threads), 8 Fig. 4a
  orbits x 1000 crossings;
* ``megno_many``: ``taylorball.chaos.megno_many`` of 8 Fig. 4a orbits to ``t = 500``,
  ``compact_mode=True``.

Fig. 4a orbits: states on the levels ``C = 10, M_gamma = 2, h = 5`` at the chart points of
``tb.section_admissible_sample(..., n=16, direction=1, seed=0)`` (``tb.states_on_section``),
computed once by the "after" interpreter and handed to both sides in a file (both sides also
compute them and the script reports whether they agree).

How it runs: for each round, one worker process per side (the "before" interpreter with
``PYTHONPATH`` = the pre-refactor worktree, the "after" interpreter with ``PYTHONPATH`` =
this checkout), each warmed up untimed (every measured call once, small, so that compiled
objects are in the package's and heyoka's caches); then every measurement runs on one side
and at once on the other (the side that goes first alternates from round to round), the
idle worker waiting on its stdin. So load changes on the shared machine hit both sides
alike. Reported per measurement: best-of and median over all rounds (and inner repeats) of
each side, after/before of both, and the median of the paired ratios (after/before of
the two samples taken back to back), and after/before of the best-of CPU time of the worker
process (``time.process_time``, all its threads: what the work costs, less sensitive to the
load of the machine than wall time); plus whether every result (states, crossing times,
section points, MEGNO values: SHA-256 of the arrays' bytes) is bit-identical between before
and after and across repeats.

Run (from the checkout, with its venv; the pre-refactor worktree needs its own venv)::

    git worktree add --detach /work/wt-before c562eb2
    (cd /work/wt-before && python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]")
    python benchmarks/bench_refactor.py [--rounds 7] [--before /work/wt-before]

Exit status 1 if any result differs between before and after.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

MARK = "@@bench_refactor "
LEVELS = {"C": 10.0, "M_gamma": 2.0, "h": 5.0}

# name -> (description, inner repeats per round)
MEASUREMENTS = {
    "propagate_long": ("propagate, demo state, t = 1e4 (one call)", 1),
    "propagate_short": ("propagate, 2000 chained calls of t = 0.1", 1),
    "section_scalar": ("poincare_section, 1 Fig. 4a orbit x 120 crossings", 10),
    "sections_lanes": ("poincare_sections(batch=True), 16 orbits x 500", 1),
    "sections_threads": ("poincare_sections (scalar, threads), 8 orbits x 1000", 1),
    "megno_many": ("megno_many, 8 orbits to t = 500, compact mode", 1),
}


# ---------------------------------------------------------------------------------------
# Worker side: runs under either interpreter, public API only.
# ---------------------------------------------------------------------------------------
def _digest(*arrays):
    import numpy as np

    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def _ball():
    import taylorball as tb

    return tb.BallParams(inertia=(2, 3, 4), mass=1, radius=5, plane_rate=2)


def _demo_state():
    """README's "A first session" state (the package's demo state)."""
    import numpy as np

    g = np.array([0.3, 0.4, np.sqrt(0.75)])
    R = np.array([1.0, -0.5, 0.0])
    R[2] = -(R[0] * g[0] + R[1] * g[1]) / g[2]
    return np.array([0.1, 0.2, 0.3, *g, *R])


def _fig4a_states(n):
    import numpy as np

    import taylorball as tb

    ball = _ball()
    pts = tb.section_admissible_sample(ball, n=n, direction=1, seed=0, **LEVELS)["points"]
    return np.array([tb.states_on_section(ball, point=tuple(p), direction=1, **LEVELS)[0] for p in pts])


def _section_digest(results):
    return _digest(*[a for r in results for a in (r.points, r.times, r.states, r.residuals)])


def _measure(name, inputs, small=False):
    """Run one measurement (``small``: a short untimed warm-up version); returns the digest."""
    import numpy as np

    import taylorball as tb
    from taylorball.chaos import megno_many

    ball, x0, S = _ball(), inputs["x0"], inputs["states"]
    if name == "propagate_long":
        return _digest(tb.propagate("reduced", ball, x0, 10.0 if small else 1e4))
    if name == "propagate_short":
        out, x = [], x0
        for _ in range(20 if small else 2000):
            x = tb.propagate("reduced", ball, x, 0.1)
            out.append(x)
        return _digest(np.array(out))
    if name == "section_scalar":
        return _section_digest([tb.poincare_section("reduced", ball, S[0], n_points=2 if small else 120)])
    if name == "sections_lanes":
        return _section_digest(tb.poincare_sections("reduced", ball, list(S[:2] if small else S[:16]),
                                                    n_points=2 if small else 500, batch=True))
    if name == "sections_threads":
        return _section_digest(tb.poincare_sections("reduced", ball, list(S[:2] if small else S[:8]),
                                                    n_points=2 if small else 1000))
    if name == "megno_many":
        try:  # the options object since 2026-11-28; the pre-refactor code takes the keyword
            from taylorball.chaos import MegnoOptions
            mode = dict(options=MegnoOptions(compact_mode=True))
        except ImportError:
            mode = dict(compact_mode=True)
        res = megno_many("reduced", ball, list(S[:2] if small else S[:8]), 5.0 if small else 500.0,
                         norm="full", **mode)
        return _digest(np.array([[c.t, c.megno, c.mean_megno, c.fli, c.lyapunov] for c in res]))
    raise ValueError(f"unknown measurement {name!r}")


def worker(inputs_path):
    """Serve commands from stdin (one JSON object a line), answer on stdout after MARK."""
    import numpy as np

    import taylorball as tb

    def reply(obj):
        sys.stdout.write(MARK + json.dumps(obj) + "\n")
        sys.stdout.flush()

    for line in sys.stdin:
        cmd = json.loads(line)
        op = cmd["op"]
        if op == "prepare":
            x0, S = _demo_state(), _fig4a_states(16)
            if cmd.get("save"):
                np.savez(inputs_path, x0=x0, states=S)
            reply({"inputs": _digest(x0, S), "module": tb.__file__})
        elif op == "warmup":
            with np.load(inputs_path) as f:
                inputs = {"x0": f["x0"], "states": f["states"]}
            t = time.perf_counter()
            for name in MEASUREMENTS:
                _measure(name, inputs, small=True)
            reply({"wall": time.perf_counter() - t, "inputs": _digest(inputs["x0"], inputs["states"])})
        elif op == "run":
            t, c = time.perf_counter(), time.process_time()
            d = _measure(cmd["name"], inputs)
            reply({"wall": time.perf_counter() - t, "cpu": time.process_time() - c, "digest": d})
        elif op == "quit":
            reply({})
            return 0
    return 0


# ---------------------------------------------------------------------------------------
# Driver side.
# ---------------------------------------------------------------------------------------
class Side:
    def __init__(self, label, python, path, inputs_path):
        self.label, self.python, self.path, self.inputs_path = label, python, path, inputs_path
        self.proc = None

    def start(self):
        env = dict(os.environ, PYTHONPATH=self.path)
        self.proc = subprocess.Popen([self.python, os.path.abspath(__file__), "--worker", self.inputs_path],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
                                     cwd=self.path)

    def ask(self, **cmd):
        self.proc.stdin.write(json.dumps(cmd) + "\n")
        self.proc.stdin.flush()
        for line in self.proc.stdout:
            if line.startswith(MARK):
                return json.loads(line[len(MARK):])
        raise RuntimeError(f"{self.label} worker ended (exit status {self.proc.wait()})")

    def stop(self):
        if self.proc is not None:
            self.ask(op="quit")
            self.proc.wait(timeout=60)
            self.proc = None


def _git(path, *args):
    try:
        out = subprocess.run(["git", "-C", path, *args], capture_output=True, text=True, check=True)
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "?"


def _load():
    return "{:.2f} {:.2f} {:.2f}".format(*os.getloadavg())


def main(argv=None):
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", default="/work/wt-before", help="checkout of the pre-refactor code")
    ap.add_argument("--before-python", default=None,
                    help="its interpreter (default: BEFORE/.venv/bin/python)")
    ap.add_argument("--after-python", default=None,
                    help="interpreter for this checkout (default: .venv/bin/python here, else this one)")
    ap.add_argument("--rounds", type=int, default=7, help="rounds (one worker pair each; at least 5)")
    ap.add_argument("--only", nargs="*", choices=list(MEASUREMENTS), help="a subset of the measurements")
    ap.add_argument("--worker", metavar="INPUTS", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        return worker(args.worker)

    before_py = args.before_python or os.path.join(args.before, ".venv", "bin", "python")
    local_py = os.path.join(here, ".venv", "bin", "python")
    after_py = args.after_python or (local_py if os.path.exists(local_py) else sys.executable)
    names = args.only or list(MEASUREMENTS)
    tmp = tempfile.mkdtemp(prefix="bench_refactor_")
    inputs_path = os.path.join(tmp, "inputs.npz")
    before = Side("before", before_py, os.path.abspath(args.before), inputs_path)
    after = Side("after", after_py, here, inputs_path)

    load0 = _load()
    start = datetime.datetime.now(datetime.timezone.utc)
    print(f"before: {before.path} at {_git(before.path, 'rev-parse', '--short', 'HEAD')} ({before.python})")
    modified = " (modified)" if _git(after.path, "status", "--porcelain", "--untracked-files=no") else ""
    print(f"after:  {after.path} at {_git(after.path, 'rev-parse', '--short', 'HEAD')}{modified} "
          f"({after.python})")
    print(f"{start:%Y-%m-%d %H:%M} UTC, {os.cpu_count()} cores, load average at start {load0}, "
          f"{args.rounds} rounds")

    # inputs: computed by both sides, the after side's copy used by both
    in_digest = {}
    for side, save in ((before, False), (after, True)):
        side.start()
        r = side.ask(op="prepare", save=save)
        in_digest[side.label] = r["inputs"]
        print(f"  {side.label} imports {r['module']}; Fig. 4a states + demo state digest {r['inputs']}")
        side.stop()
    print(f"  inputs computed by before and after identical: {in_digest['before'] == in_digest['after']} "
          "(both sides run from the after side's copy)")

    walls = {s: {n: [] for n in names} for s in ("before", "after")}
    cpus = {s: {n: [] for n in names} for s in ("before", "after")}
    digests = {s: {n: set() for n in names} for s in ("before", "after")}
    for rnd in range(args.rounds):
        order = (before, after) if rnd % 2 == 0 else (after, before)
        for side in order:
            side.start()
            w = side.ask(op="warmup")
            assert w["inputs"] == in_digest["after"]
        for name in names:
            for _ in range(MEASUREMENTS[name][1]):
                for side in order:
                    r = side.ask(op="run", name=name)
                    walls[side.label][name].append(r["wall"])
                    cpus[side.label][name].append(r["cpu"])
                    digests[side.label][name].add(r["digest"])
        for side in order:
            side.stop()
        print(f"  round {rnd + 1}/{args.rounds} done ({order[0].label} first), load average {_load()}",
              flush=True)
    load1 = _load()

    print(f"\nload average at start {load0}, at end {load1}")
    print("best-of / median wall seconds over all rounds and inner repeats; ratio = after / before")
    print("paired = median over samples of after/before, the two measured back to back in the same round;")
    print("CPU = after/before of the best-of CPU time of the process (all its threads; less sensitive "
          "to load)")
    hdr = ("| measurement | before best (s) | after best (s) | after/before best | before median (s) "
           "| after median (s) | after/before median | paired | CPU | bit-identical |")
    print(hdr)
    print("|---|---|---|---|---|---|---|---|---|---|")
    all_same = True
    for name in names:
        b, a = walls["before"][name], walls["after"][name]
        db, da = digests["before"][name], digests["after"][name]
        same = len(db) == 1 and db == da
        all_same &= same
        verdict = f"yes ({next(iter(da))})" if same else f"NO: before {sorted(db)}, after {sorted(da)}"
        print(f"| {MEASUREMENTS[name][0]} (n={len(b)}) | {min(b):.4f} | {min(a):.4f} | {min(a) / min(b):.3f} "
              f"| {statistics.median(b):.4f} | {statistics.median(a):.4f} "
              f"| {statistics.median(a) / statistics.median(b):.3f} "
              f"| {statistics.median(x / y for x, y in zip(a, b)):.3f} "
              f"| {min(cpus['after'][name]) / min(cpus['before'][name]):.3f} | {verdict} |")
    print(f"\nall results bit-identical between before and after: {all_same}")
    return 0 if all_same else 1


if __name__ == "__main__":
    raise SystemExit(main())
