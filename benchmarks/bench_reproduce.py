"""Wall time of ``taylorball reproduce`` (all five figures) against the one-minute target.

Runs the command as a user would (a fresh process, output into a temporary folder) and
prints, all measured in this run (the machine is shared: compare the ratios):

* a warm-up run first (unless ``--no-warmup``), so heyoka's compile cache is warm, as the
  target assumes; its time is printed as the cold-ish time (it is only cold on a machine
  that never compiled these integrators);
* the run with figures in worker processes (``--workers`` = cores, the default) and, as the
  peer, the same figures one at a time (``--workers 1``), each with its per-figure times;
* the ratios: parallel / serial, and the parallel time / 60 s (the issue's target for
  ``--full``: under a minute on this 2-core machine with a warm cache).

Run: ``python benchmarks/bench_reproduce.py [--quick] [--no-warmup]`` (``--quick`` times
the quick default instead of ``--full``). Exit status 1 if a run fails.

``--quick-cold [N]``: the quick default as a new user meets
it, ``N`` times (default 1): first with an empty compile cache (``HOME`` a fresh folder, so
heyoka's disk cache ``~/.cache/heyoka`` is empty), then warm (the same ``HOME`` again). For
each run: wall time, the process tree's CPU time (user + sys: comparable on a loaded
machine), maximum RSS, the load average before and after, and each study's data and plot
times with their CPU seconds in its worker (from ``taylorball -v``), and the workers' compiled
builds: how many, their wall seconds (on an idle machine about their CPU seconds; under load
inflated like every wall time), how many heyoka's disk cache served and how many waited for
the other worker's compile of the same key; the target is 30 CPU s cold on 2 cores.

``--per-study [HOME]``: where the quick default's CPU goes: every quick study in one
process (``HOME`` a fresh folder unless given, so heyoka's disk cache starts empty), each
study's CPU seconds (data and plots) and, of them, the CPU seconds of each compiled build
(every ``taylorball._cache.compiled`` build is timed with ``time.process_time``; a build
that asks for another counts it too).

``--per-study --against DIR``: the same for another checkout ``DIR`` of the package (its
``taylorball`` imported from there, e.g. an earlier commit's ``git archive``) and this one,
alternately, ``--rounds`` times each (default 1), every run with an empty compile cache; a
table of both sides' CPU seconds per study from the same run of the benchmark (the load
applies to both alike).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

TARGET_S = 60.0
QUICK_COLD_TARGET_S = 30.0


def run(full: bool, jobs: int):
    """One ``taylorball reproduce`` in a fresh process; returns (wall seconds, {figure: s}, ok)."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "taylorball.cli", "reproduce", "--out", out, "--workers", str(jobs)]
        if full:
            cmd.append("--full")
        env = dict(os.environ, TQDM_DISABLE="1")
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
    figs = {m.group(1): float(m.group(2)) for m in re.finditer(r"^(fig\w+): data .*?\(([\d.]+) s\)", p.stdout, re.M)}
    if p.returncode != 0:
        print(p.stdout[-2000:], p.stderr[-2000:], file=sys.stderr)
    return wall, figs, p.returncode == 0


STUDY_LINE = re.compile(r"^.*?: debug: (\w+): data ([\d.]+) s \(([\d.]+) s CPU\), plots ([\d.]+) s \(([\d.]+) s CPU\)",
                        re.M)


def run_quick(home: str):
    """The quick ``taylorball -v reproduce`` with ``HOME=home``, one worker per core; returns
    (wall s, CPU s of the process tree, max RSS MB, load before, load after, {study: (data s,
    data CPU s, plots s, plots CPU s)}, ok)."""
    import resource

    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "taylorball.cli", "-v", "reproduce", "--out", out]
        env = dict(os.environ, TQDM_DISABLE="1", HOME=home)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        load0 = os.getloadavg()[0]
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    studies = {m.group(1): tuple(float(m.group(k)) for k in range(2, 6)) for m in STUDY_LINE.finditer(p.stderr)}
    if p.returncode != 0:
        print(p.stdout[-2000:], p.stderr[-2000:], file=sys.stderr)
    return wall, cpu, after.ru_maxrss / 1024, load0, os.getloadavg()[0], studies, p.returncode == 0, builds(p.stderr)


BUILT_LINE = re.compile(r": debug: built (.+) in ([\d.]+) s$", re.M)


def builds(log: str) -> str:
    """What a run's workers built (from ``taylorball -v``'s log): the compiled builds, their
    wall seconds (the CPU seconds of a build on an idle core), how many of them heyoka's disk
    cache served and how many waited for another worker's compile of the same key."""
    built = [float(m.group(2)) for m in BUILT_LINE.finditer(log)]
    loaded = len(re.findall(r"loaded .+ from heyoka's disk cache", log))
    waited = len(re.findall(r"waiting for another process compiling", log))
    return (f"{len(built)} builds in the workers, {sum(built):.1f} s wall ({loaded} loaded from heyoka's disk cache, "
            f"{waited} waited for the other worker's compile)")


def quick_cold(n: int) -> int:
    """``--quick-cold``: ``n`` pairs of runs, cold (fresh ``HOME``) then warm."""
    print(f"taylorball reproduce (quick), {os.cpu_count()} cores: cold (fresh HOME, empty compile cache) then warm; "
          f"target {QUICK_COLD_TARGET_S:.0f} s cold")
    ok = True
    for k in range(n):
        with tempfile.TemporaryDirectory() as home:
            for label in ("cold", "warm"):
                wall, cpu, rss, l0, l1, studies, good, built = run_quick(home)
                ok &= good
                print(f"  run {k + 1} {label}: {wall:6.1f} s wall, {cpu:6.1f} s CPU (user + sys), max RSS {rss:.0f} MB, "
                      f"load average {l0:.2f} -> {l1:.2f}{'' if good else ', FAILED'}")
                print(f"      {built}")
                for name, (d, dc, pl, pc) in sorted(studies.items(), key=lambda kv: -(kv[1][1] + kv[1][3])):
                    print(f"      {name:<22} data {d:5.1f} s ({dc:5.1f} CPU)   plots {pl:5.1f} s ({pc:5.1f} CPU)")
    return 0 if ok else 1


def per_study(home=None, against=None, quiet=False):
    """``--per-study``: run :func:`_per_study_child` in a fresh process with ``HOME=home``
    (with ``taylorball`` from the checkout ``against`` if given); returns (exit status,
    {study: CPU s}, total CPU s)."""
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, TQDM_DISABLE="1", HOME=home or tmp)
        if against:
            env.update(PYTHONPATH=os.path.abspath(against), PYTHONDONTWRITEBYTECODE="1")
        p = subprocess.run([sys.executable, __file__, "--per-study-child", os.path.join(tmp, "out")], env=env,
                           capture_output=True, text=True)
    if not quiet:
        print(p.stdout)
    if p.returncode != 0:
        print(p.stderr[-3000:], file=sys.stderr)
    cpu = {m.group(1): float(m.group(2)) for m in re.finditer(r"^  (\w+)\s+([\d.]+) CPU s, of which", p.stdout, re.M)}
    total = re.search(r"^all studies ([\d.]+) CPU s", p.stdout, re.M)
    return p.returncode, cpu, float(total.group(1)) if total else float("nan")


def per_study_against(base: str, rounds: int) -> int:
    """``--per-study --against DIR``: both checkouts alternately, ``rounds`` times each."""
    import taylorball

    here = os.path.dirname(os.path.dirname(os.path.abspath(taylorball.__file__)))
    sides = {"before": base, "after": None}
    got = {k: [] for k in sides}
    print(f"quick studies per study, CPU s, empty compile cache each run: before = {os.path.abspath(base)}, "
          f"after = {here}; {rounds} round(s), alternating")
    status = 0
    for r in range(rounds):
        for side, path in sides.items():
            load = os.getloadavg()[0]
            rc, cpu, total = per_study(against=path, quiet=True)
            status |= rc
            got[side].append(cpu)
            print(f"  round {r + 1} {side:<6} {total:6.1f} CPU s (load average {load:.1f} at the start)", flush=True)
    import statistics

    names = list(got["after"][0]) if got["after"] and got["after"][0] else list(got["before"][0])
    print(f"  {'study':<22} {'before':>8} {'after':>8}   (median over rounds; each round's before/after)")
    med = {side: {n: statistics.median(c.get(n, float("nan")) for c in runs) for n in names}
           for side, runs in got.items()}
    for n in names:
        each = "  ".join(f"{b.get(n, float('nan')):.1f}/{a.get(n, float('nan')):.1f}"
                         for b, a in zip(got["before"], got["after"]))
        print(f"  {n:<22} {med['before'][n]:8.1f} {med['after'][n]:8.1f}   {each}")
    print(f"  {'all':<22} {sum(med['before'].values()):8.1f} {sum(med['after'].values()):8.1f}")
    return status


def _per_study_child(out: str) -> int:
    import importlib
    import pkgutil

    import taylorball
    import taylorball._cache as cache

    original = cache.compiled
    builds = []

    def compiled(key, build):
        def timed():
            c = time.process_time()
            obj = build()
            builds.append((cache._describe(key, brief=True), time.process_time() - c))
            return obj

        return original(key, timed)

    cache.compiled = compiled
    for m in pkgutil.walk_packages(taylorball.__path__, "taylorball."):
        if any(x in m.name for x in ("explore", "__main__")):
            continue
        try:
            mod = importlib.import_module(m.name)
        except Exception:  # an optional extra missing: that module compiles nothing here
            continue
        if getattr(mod, "compiled", None) is original:
            mod.compiled = compiled
    from taylorball.figures import runner

    print(f"quick studies in one process, HOME={os.environ.get('HOME')}, load average {os.getloadavg()[0]:.2f}")
    c0 = time.process_time()
    for name in runner.figure_studies():
        n0, c = len(builds), time.process_time()
        runner.run(runner.load_study(name), outdir=out, log=lambda *a: None)
        print(f"  {name:22s} {time.process_time() - c:6.1f} CPU s, of which compiling "
              f"{sum(b[1] for b in builds[n0:]):5.1f}", flush=True)
    print(f"all studies {time.process_time() - c0:.1f} CPU s (the process: {time.process_time():.1f}); "
          f"compiled builds {sum(b[1] for b in builds):.1f}:")
    for k, sec in builds:
        print(f"  {sec:6.2f}  {k}")
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="time the quick default instead of --full")
    ap.add_argument("--no-warmup", action="store_true", help="skip the warm-up run")
    ap.add_argument("--quick-cold", type=int, nargs="?", const=1, default=None, metavar="N",
                    help="the quick default N times (default 1), each cold (fresh HOME) then warm")
    ap.add_argument("--per-study", nargs="?", const="", default=None, metavar="HOME",
                    help="CPU seconds per quick study and per compiled build, in one process (fresh HOME)")
    ap.add_argument("--against", default=None, metavar="DIR",
                    help="with --per-study: also the checkout DIR (before), alternately with this one (after)")
    ap.add_argument("--rounds", type=int, default=1, help="with --per-study --against: runs of each side")
    ap.add_argument("--per-study-child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.per_study_child is not None:
        return _per_study_child(args.per_study_child)
    if args.per_study is not None and args.against:
        return per_study_against(args.against, args.rounds)
    if args.per_study is not None:
        return per_study(args.per_study or None)[0]
    if args.quick_cold is not None:
        return quick_cold(args.quick_cold)
    full = not args.quick
    cores = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except OSError:
        load = float("nan")
    print(f"taylorball reproduce {'--full' if full else '(quick)'}; {cores} cores; load average {load:.2f} "
          "(shared machine: compare the ratios, measured in one run)")
    ok = True
    if not args.no_warmup:
        w, _, good = run(full, cores)
        ok &= good
        print(f"  {'warm-up (fills the compile cache if needed)':<46}{w:7.1f} s")
    wp, fp, good = run(full, cores)
    ok &= good
    ws, fs, good = run(full, 1)
    ok &= good
    for label, w, f in ((f"figures in {cores} worker processes (--workers {cores})", wp, fp),
                        ("one figure at a time (--workers 1, the peer)", ws, fs)):
        print(f"  {label:<46}{w:7.1f} s   " + ", ".join(f"{k.split('_')[0]} {v:.1f}" for k, v in sorted(f.items())))
    print("ratios:")
    print(f"  parallel / serial                 = {wp / ws:6.2f}")
    if full:
        print(f"  parallel / target ({TARGET_S:.0f} s)          = {wp / TARGET_S:6.2f}   (target < 1)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
