r"""A resumable multiple-shooting proof of a periodic orbit: :func:`run_periodic_orbit`.

The proof of :func:`taylorball.rigorous.proofs.krawczyk_periodic_orbit` is ``2 m``
independent section-map enclosures (a point and a box per segment,
:func:`~taylorball.rigorous.proofs.shooting_jobs`) and a cheap Krawczyk step on their results
(:func:`~taylorball.rigorous.proofs.shooting_verdict`). On the Fig. 4a level one segment's
box costs minutes to an hour (docs/rigorous.md), so the run keeps one JSON state file: the
``periodic_orbit`` certificate's data (:func:`~taylorball.rigorous.certificates.periodic_orbit_design`)
with each finished job's result under ``"jobs"``, written atomically as soon as the job ends.
A run that is stopped resumes where it was (the finished jobs are not redone); a state file
made from another design, or changed after it was made (its design sha256), is refused; a
second run on the same state file is refused while the first is alive (a lock file beside
it). When every job is done the file is a ``periodic_orbit`` certificate with the verdict,
which ``taylorball prove --check`` re-proves from scratch (the stored job results are not
trusted by the checker).
"""

from __future__ import annotations

import json
import logging
import os
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

from ..errors import UsageError
from ._run_state import check_workers

__all__ = ["run_periodic_orbit", "check_periodic_orbit", "certificate_from_run", "record_jobs", "record_verdict",
           "fig4a_saddle_design"]

_DESIGN_KEYS = ("kind", "params", "levels", "centers", "radius", "K_guesses", "tau_guesses", "l_branches", "method")


def _design_hash(rec: Dict[str, Any]) -> str:
    from ._run_state import design_hash

    return design_hash(rec, _DESIGN_KEYS, "periodic-orbit")


def record_jobs(rec: Dict[str, Any]) -> List[tuple]:
    """The section-map jobs of a ``periodic_orbit`` record, read from its exact numbers."""
    from ._cert_json import _levels_from_json, _params_from_json, _read_exact
    from .certificates import _BRANCH_NAMES, _read_center
    from .proofs import shooting_jobs

    kind = str(rec["kind"])
    meth = rec["method"]
    branches = {v: k for k, v in _BRANCH_NAMES.items()}
    try:
        lbs = None if kind == "reduced3" else [branches[b] for b in rec["l_branches"]]
    except KeyError:
        raise UsageError(f"l_branches must be among {sorted(branches)}, got {rec['l_branches']!r}") from None
    return shooting_jobs(_params_from_json(rec["params"]),
                         _levels_from_json("reduced" if kind == "reduced3" else kind, rec["levels"]),
                         [[_read_center(v) for v in c] for c in rec["centers"]], _read_exact(rec["radius"], "radius"),
                         [_read_exact(v, "K_guesses") for v in rec["K_guesses"]],
                         [_read_exact(v, "tau_guesses") for v in rec["tau_guesses"]], prec=int(meth["prec"]),
                         order=int(meth["order"]), delta=_read_exact(meth["delta"], "method.delta"), kind=kind,
                         l_branches=lbs)


def record_verdict(rec: Dict[str, Any], jobs: Sequence[tuple]) -> Any:
    """The Krawczyk verdict (:func:`~taylorball.rigorous.proofs.shooting_verdict`) of the job
    results stored in ``rec["jobs"]``, or ``None`` while a job is missing and none has failed
    (no new work)."""
    from .proofs import shooting_verdict

    done = rec.get("jobs", {})
    failed = sorted(int(k) for k, o in done.items() if not o["ok"])
    if failed:  # the first failed job decides (the verdict reads the list only up to it)
        outs = [{"ok": True}] * failed[0] + [done[str(failed[0])]]
    elif len(done) < len(jobs):
        return None
    else:
        outs = [done[str(k)] for k in range(len(jobs))]
    cpu = sum(float(o.get("cpu", 0.0)) for o in done.values())
    centers = [j[2] for j in jobs[::2]]
    return shooting_verdict(outs, centers, jobs[0][3], prec=jobs[0][6], kind=jobs[0][10], cpu=cpu)


def _finish(rec: Dict[str, Any], jobs: Sequence[tuple]) -> None:
    """Set the verdict of a record from its stored job results (no new work)."""
    from .certificates import _krawczyk_outcome

    r = record_verdict(rec, jobs)
    if r is None:
        done = rec.get("jobs", {})
        cpu = sum(float(o.get("cpu", 0.0)) for o in done.values())
        rec.update(proved=False, message=f"not proved: {len(done)} of the {len(jobs)} section-map enclosures done",
                   proved_cpu_seconds=round(cpu, 2))
        return
    rec["validated_steps"] = r.steps
    for key in ("periodic_box", "multiplier_trace"):
        rec.pop(key, None)
    rec.update(_krawczyk_outcome(r, "periodic_box"))


def run_periodic_orbit(state: str | os.PathLike, *, record: Optional[Dict[str, Any]] = None,
                       only: Optional[Sequence[int]] = None, workers: int = 1) -> Dict[str, Any]:
    """Run the section-map jobs of the record in the state file ``state`` that are not done
    yet, writing each result there as it finishes. A new state file is made from ``record``
    (from :func:`~taylorball.rigorous.certificates.periodic_orbit_design`); an existing one is
    resumed, and refused if ``record`` is given and is another design. ``only``: these job
    numbers only, in this order (``2 i``: segment ``i``'s point, ``2 i + 1``: its box).
    ``workers``: with one, the jobs run here in order and the run stops at the first that
    fails (its reason is the verdict); with more, they run in that many worker processes,
    started in order, and every job runs. Returns the record (a ``periodic_orbit``
    certificate once every job is done)."""
    return _run(state, record, only, workers, "run")


#: The fields a proof adds to a ``periodic_orbit`` design (dropped to re-prove a certificate).
_OUTCOME_KEYS = ("jobs", "design_sha256", "role", "proved", "orbit_type", "message", "proved_cpu_seconds", "proved_on",
                 "periodic_box", "multiplier_trace", "validated_steps")


def certificate_from_run(state: str | os.PathLike) -> Dict[str, Any]:
    """The ``periodic_orbit`` certificate of the finished run in the state file ``state``: its
    design and its verdict, without the stored job results, the design's sha256 and the role
    (a check recomputes every job and reads none of them). Write it with
    :func:`~taylorball.rigorous.certificates.write_certificate`. :class:`UsageError` for a
    state file that a check made, or one with jobs not done yet (a failed run gives a
    certificate that says "not proved" and why)."""
    from .certificates import load_certificate

    rec = load_certificate(state)
    if rec.get("claim") != "periodic_orbit" or "jobs" not in rec:
        raise UsageError(f"state: {str(state)!r} is not the state file of a periodic-orbit run")
    if rec.get("role", "run") != "run":
        raise UsageError(f"state: {str(state)!r} was made by a {rec['role']}, not a run")
    jobs = record_jobs(rec)
    if record_verdict(rec, jobs) is None:
        raise UsageError(f"state: the run in {str(state)!r} has {len(rec['jobs'])} of its {len(jobs)} jobs done; "
                         f"resume it with run_periodic_orbit first")
    _finish(rec, jobs)
    return {k: v for k, v in rec.items() if k not in ("jobs", "design_sha256", "role")}


def check_periodic_orbit(cert: Dict[str, Any], state: str | os.PathLike, *, workers: int = 1) -> Any:
    """Re-prove a ``periodic_orbit`` certificate from its design alone, resumably (``taylorball
    prove --check CERT --state FILE``): the section-map jobs run as in
    :func:`run_periodic_orbit`, with their results in the state file ``state`` (made here,
    marked as a check's; a run's state file, or one of another design, is refused), so a check
    of hours can be stopped and resumed. The job results stored in ``cert`` are not read; the
    verdict is compared with the certificate's claims as by
    :func:`~taylorball.rigorous.certificates.check_certificate`. Returns its
    :class:`~taylorball.rigorous._cert_json.CheckResult` ("not proved yet" while jobs are
    missing)."""
    from .certificates import check_periodic_orbit_certificate

    if not isinstance(cert, dict) or cert.get("claim") != "periodic_orbit":
        raise UsageError(f"state: only a periodic_orbit certificate's check keeps a state file, got claim "
                         f"{cert.get('claim') if isinstance(cert, dict) else type(cert).__name__!r}")
    check_workers(workers)

    def prove(w: int) -> Any:
        design = {k: v for k, v in cert.items() if k not in _OUTCOME_KEYS}
        design.update(proved=False, message="not run")
        rec = _run(state, design, None, w, "check")
        jobs = record_jobs(rec)
        r = record_verdict(rec, jobs)
        return r if r is not None else (f"not proved yet: {len(rec['jobs'])} of the {len(jobs)} section-map enclosures "
                                        f"done; run the check again with the same state file to go on")

    return check_periodic_orbit_certificate(cert, workers=workers, prove=prove)


def _run(state: str | os.PathLike, record: Optional[Dict[str, Any]], only: Optional[Sequence[int]], workers: int,
         role: str) -> Dict[str, Any]:
    from .._store_lock import Lock
    from ..io import atomic_write_bytes
    from ._run_state import open_run_state, run_jobs
    from .proofs import _shooting_segment

    if record is not None and record.get("claim") != "periodic_orbit":
        raise UsageError(f"record must be a periodic_orbit design, got claim {record.get('claim')!r}")
    check_workers(workers)
    path = Path(state)
    rec = open_run_state(path, record, _design_hash, jobs={}, role=role)
    if rec.get("role", "run") != role:
        raise UsageError(f"the state file {str(path)!r} was made by a {rec.get('role', 'run')}, not a {role}; a check "
                         f"needs its own new state file")
    jobs = record_jobs(rec)
    if only is not None and any(isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(jobs) for k in only):
        raise UsageError(f"only: job numbers must be integers in 0 .. {len(jobs) - 1}, got {list(only)!r}")
    done = rec.setdefault("jobs", {})
    todo = [k for k in (range(len(jobs)) if only is None else only) if str(k) not in done]
    log = logging.getLogger(__name__)

    def save() -> None:
        atomic_write_bytes(path, (json.dumps(rec, indent=1) + "\n").encode())

    def keep(i: int, out: Dict[str, Any]) -> bool:
        k = todo[i]
        out["cpu"] = round(float(out["cpu"]), 2)
        out["on"] = time.strftime("%Y-%m-%d %H:%M", time.gmtime())
        done[str(k)] = out
        _finish(rec, jobs)
        save()
        log.info("periodic orbit job %d (segment %d, %s): %s [%.1f CPU s]", k, k // 2, "box" if k % 2 else "point",
                 "ok" if out["ok"] else out["message"], out["cpu"])
        return bool(out["ok"])

    with Lock(Path(str(path) + ".lock"), f"the periodic-orbit state {str(path)!r}"):  # one run per state file
        if any(not o["ok"] for o in done.values()):
            todo = []  # a failed job decides the verdict: nothing more to run
        save()
        run_jobs(_shooting_segment, [jobs[k] for k in todo], workers, keep)
        _finish(rec, jobs)
        save()
    return rec


def fig4a_saddle_design(*, prec: int = 80, radius: float = 1e-10, centers: str = "float64") -> Dict[str, Any]:
    """The design of the multiple-shooting proof of ``periodic_catalog.FIG4A_SADDLE_K10``
    (the Fig. 4 ball on the Fig. 4a level, 10 crossings of ``g = 0``, period 25.30): one
    segment per crossing, the centres its 10 section points in the chart ``(l, r1, r2)``
    (segment 0 from its 10th crossing after the catalogued state), ``K_guesses`` their ``M3`` and ``tau_guesses``
    the return times, all from a run of the section integrator (not part of the proof).

    ``centers="float64"``: the float64 run's points (the orbit closes to ~1e-12, so the
    Krawczyk radius must be ~1e-11 or more). ``"real128"``: the orbit refined in real128 onto
    the exact level (:func:`taylorball.periodic.refine`, closing to ~1e-30), its points from a
    real128 section run, the chart (:func:`~taylorball.rigorous.section.chart_lr`) evaluated in
    160-bit balls and the centres rounded to 128-bit dyadic rationals (about a minute of CPU; radii down to the enclosures' own ~1e-17 become possible)."""
    import numpy as np

    from ..model import get_system
    from ..periodic_catalog import FIG4A_SADDLE_K10 as E
    from ..sections import chart_points, poincare_section
    from .certificates import periodic_orbit_design

    if centers not in ("float64", "real128"):
        raise UsageError(f"centers must be 'float64' or 'real128', got {centers!r}")
    title = "the saddle FIG4A_SADDLE_K10 of the Fig. 4 ball on the Fig. 4a level (Omega = 2, G = 10, H = 2, h = 5)"
    if centers == "real128":
        pts, Ks, taus = _fig4a_real128_points()
        return periodic_orbit_design(E.ball, E.levels, pts, radius, Ks, taus, prec=prec, kind="reduced3", title=title)
    system = get_system("reduced")
    pars = system.check_params(E.ball).pars
    x0 = np.asarray(E.state, dtype=float)  # public layout
    res = poincare_section("reduced", E.ball, x0, n_points=E.k)
    xs = np.asarray(res.states, dtype=float)
    times = np.asarray(res.times, dtype=float)
    # segment 0 starts at the k-th crossing (the float orbit closes there to ~1e-12; starting
    # at x0 instead would put that whole gap into the last segment's residual)
    pub = np.vstack([xs[-1:], xs[:-1]])
    internal = np.array([np.asarray(system.to_internal(pars, tuple(x)), dtype=float) for x in pub])
    pts = chart_points("reduced", internal)
    taus = [float(times[0])] + [float(times[i] - times[i - 1]) for i in range(1, E.k)]
    return periodic_orbit_design(E.ball, E.levels, [[float(v) for v in p] for p in pts], radius,
                                 [float(x[2]) for x in internal], taus, prec=prec, kind="reduced3", title=title)


def _fig4a_real128_points() -> tuple:
    """The section points of ``FIG4A_SADDLE_K10`` refined in real128 on the exact level: the
    chart points ``(l, r1, r2)`` as 128-bit dyadic :class:`~fractions.Fraction`, ``M3`` and
    the return times as floats (guesses)."""
    import math
    from fractions import Fraction

    import heyoka as hy
    import mpmath
    import numpy as np
    from flint import arb

    from .._problem import problem
    from ..model import get_system
    from ..periodic import refine
    from ..periodic_catalog import FIG4A_SADDLE_K10 as E
    from ..periodic_catalog import catalog_orbit
    from ..sections import poincare_section
    from ._balls import working_precision
    from .section import chart_lr, quarter_turns

    orbit = refine(catalog_orbit(E), ("real128",), levels=E.levels)[-1]
    system = get_system("reduced")
    pars = [hy.real128(float(p)) for p in system.check_params(E.ball).pars]
    x0 = np.asarray(orbit.internal)
    res = poincare_section(problem("reduced", E.ball, fp_type="real128"),
                           state=np.array(system.to_public(pars, tuple(x0))), n_points=E.k)
    times = [float(t) for t in res.times]
    seq = [x0] + [np.array(system.to_internal(pars, tuple(x))) for x in list(res.states)[:-1]]

    def dyadic(b: Any) -> Fraction:  # the ball's midpoint rounded once to 128 bits, exactly
        m, e = b.mid().man_exp()
        with mpmath.workprec(128):
            sign, man, exp, _ = (+mpmath.mpf((int(m), int(e))))._mpf_
        q = Fraction(int(man)) * Fraction(2) ** int(exp)
        return -q if sign else q

    pts, Ks = [], []
    with working_precision(160):  # the rigorous chart (l on chart_points' branch) in 160 bits
        for x in seq:
            turns = quarter_turns(math.atan2(float(x[0]), float(x[1])) % (2 * math.pi))
            lv, r1, r2 = chart_lr([arb(str(v)) for v in x], turns)
            pts.append([dyadic(lv), dyadic(r1), dyadic(r2)])
            Ks.append(float(x[2]))
    return pts, Ks, [times[0]] + [times[i] - times[i - 1] for i in range(1, E.k)]
