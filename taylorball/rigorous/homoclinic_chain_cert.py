r"""Certificates of a transversal homoclinic point proved by a chain of covering relations
(claim ``transversal_homoclinic_point``, :mod:`taylorball.rigorous.homoclinic_chain`), and the
resumable run that proves the relations one by one.

A certificate stores the map (as the ``homoclinic_point`` certificates do: the Henon map's
exact parameter, or the symmetric ball's section map with one energy root and return time per
relation), the start set of the section maps, the precision of each relation, the local h-set
``N_0`` with its cone constant ``c`` and precision (its local unstable manifold is re-proved by
the checker), the chain's h-sets (every number ``float.hex``), the reversor, and the claimed
orientations and sides. :func:`check_chain` re-runs everything from scratch: the local
manifold, every relation (independent: in ``workers`` processes), the start and the end.

**The run** (:func:`run_chain`): the same record, filled in relation by relation; each
finished relation is written to the state file at once (atomically), so a run that is
stopped resumes where it was, a state file made from another design is refused, and a second
run on the same state file is refused while the first is alive (a lock file beside it).
"""

from __future__ import annotations

import json
import logging
import os
import time
from fractions import Fraction
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

from ..errors import UsageError
from ._cert_json import FORMAT, CheckResult

__all__ = ["chain_record", "check_chain", "run_chain", "finish_chain", "STATEMENT"]

STATEMENT = (
    "f has a hyperbolic fixed point p, the unique fixed point in the local h-set N_0, with R p = p, and the "
    "points of N_0 with a full backward orbit in N_0 form a curve W^u_N0 in W^u(p); the chain of covering "
    "relations N_0 => N_1 => ... => N_n with cone conditions carries W^u_N0 to a horizontal disc of N_n, "
    "whose exit edges lie on opposite sides of Fix(R): it meets Fix(R) at a point q, a homoclinic point of "
    "p (q in W^u(p), R q = q in W^s(p)), where W^u(p) and W^s(p) = R W^u(p) intersect transversally. For a "
    "section map the relations use the local section maps f_i near the design's return times (each crossing "
    "proved unique and transversal in its time window, not proved to be a first return): q then lies on an "
    "orbit of the flow homoclinic to p's periodic orbit, whose unstable and stable manifolds meet "
    "transversally in the section at q")

_RECORD_KEYS = ("map", "start", "prec", "local", "sets", "reversor")


def chain_record(f: Any, sets: Sequence[Any], precs: Sequence[int], local: Dict[str, Any],
                 reversor: Sequence[Sequence[int]], *, start: str = "box", title: str = "") -> Dict[str, Any]:
    """The certificate's data before any proof (``relations`` empty, ``proved`` false).
    ``local``: ``{"frame": Frame, "a", "b", "c", "prec"}`` of the local h-set."""
    from ._cert_json import _exact as _ex
    from .homoclinic_check import homoclinic_map_json as _map_json

    if len(precs) != len(sets) - 1:
        raise UsageError(f"one precision per relation: {len(sets) - 1} relations, {len(precs)} precisions")
    fr = local["frame"]
    return {"format": FORMAT, "claim": "transversal_homoclinic_point", "title": title, "statement": STATEMENT,
            "map": _map_json(f), "start": start, "prec": [int(p) for p in precs],
            "local": {"frame": {"center": [_ex(v) for v in fr.center], "T": [[_ex(v) for v in r] for r in fr.T]},
                      "a": _ex(local["a"]), "b": _ex(local["b"]), "c": _ex(local["c"]), "prec": int(local["prec"])},
            "sets": [s.as_json() for s in sets], "reversor": [[int(v) for v in r] for r in reversor],
            "relations": {}, "local_result": None, "proved": False, "message": "not run"}


def _design_hash(rec: Dict[str, Any]) -> str:
    from ._run_state import design_hash

    return design_hash(rec, _RECORD_KEYS, "chain")


def _parse(rec: Dict[str, Any]) -> Dict[str, Any]:
    """The record's objects: the map (one per relation precision), the sets, the local frame."""
    from ._cert_json import _read_exact
    from .homoclinic import Frame
    from .homoclinic_chain import ChainSet

    try:
        sets = [ChainSet.from_json(d) for d in rec["sets"]]
        precs = [int(p) for p in rec["prec"]]
        lo = rec["local"]
        frame = Frame(tuple(_read_exact(v, "local.frame.center") for v in lo["frame"]["center"]),  # type: ignore[arg-type]
                      tuple(tuple(_read_exact(v, "local.frame.T") for v in r) for r in lo["frame"]["T"]))  # type: ignore[arg-type]
        local = (frame, _read_exact(lo["a"], "local.a"), _read_exact(lo["b"], "local.b"), _read_exact(lo["c"], "local.c"))
        R = [[int(v) for v in r] for r in rec["reversor"]]
        start = str(rec.get("start", "box"))
        mapd = rec["map"]
    except (KeyError, TypeError, ValueError) as exc:
        raise UsageError(f"chain certificate: a field is missing or malformed ({exc!r})") from None
    if len(sets) < 2 or len(precs) != len(sets) - 1:
        raise UsageError(f"chain certificate: {len(sets)} h-sets need {len(sets) - 1} precisions, got {len(precs)}")
    if mapd.get("kind") == "reduced" and len(mapd.get("K_guesses", [])) < len(sets) - 1:
        raise UsageError(f"chain certificate: {len(sets) - 1} relations but {len(mapd.get('K_guesses', []))} "
                         "return-time guesses")
    if start not in ("box", "doubleton"):
        raise UsageError(f"chain certificate: start must be 'box' or 'doubleton', got {start!r}")
    return {"sets": sets, "precs": precs, "local": local, "local_prec": int(lo["prec"]), "R": R, "start": start,
            "map": mapd}


def _map_at(p: Dict[str, Any], prec: int, start: str) -> Any:
    from .homoclinic import SectionBallMap
    from .homoclinic_check import _homoclinic_map_from_json

    f = _homoclinic_map_from_json(p["map"], prec)
    if isinstance(f, SectionBallMap):
        f.start = start
    return f


def _relation_job(job: tuple) -> Dict[str, Any]:
    """One job (a worker's): relation ``i`` (``i >= 0``) or the local manifold (``i = -1``)."""
    from ..errors import IntegrationError
    from ._balls import working_precision
    from .homoclinic import local_unstable_manifold
    from .homoclinic_chain import check_relation
    from .section import NotProved

    rec, i = job
    p = _parse(rec)
    cpu0 = time.process_time()
    if i < 0:
        f = _map_at(p, p["local_prec"], "box")  # the local manifold's proof as certified
        try:
            with working_precision(p["local_prec"]):
                man = local_unstable_manifold(f, *p["local"], reversor=p["R"])
            ok, msg = man.ok, man.message
        except (NotProved, IntegrationError) as exc:
            ok, msg = False, f"not proved: the section map: {exc}"
        return {"i": -1, "ok": ok, "message": msg, "cpu_seconds": round(time.process_time() - cpu0, 2),
                "steps": getattr(f, "steps", 0), "on": time.strftime("%Y-%m-%d %H:%M", time.gmtime())}
    f = _map_at(p, p["precs"][i], p["start"])
    try:
        with working_precision(p["precs"][i]):
            r = check_relation(f, None if i == 0 else i, p["sets"][i], p["sets"][i + 1])
    except (NotProved, IntegrationError) as exc:  # an inclusion of the section map failed
        return {"i": i, "ok": False, "message": f"not proved: the section map: {exc}", "orientation": 0,
                "margins": {}, "enclosures": {}, "prec": p["precs"][i],
                "cpu_seconds": round(time.process_time() - cpu0, 2), "steps": getattr(f, "steps", 0),
                "on": time.strftime("%Y-%m-%d %H:%M", time.gmtime())}
    return {"i": i, "ok": r.ok, "message": r.message, "orientation": r.orientation, "margins": r.margins,
            "enclosures": r.enclosures, "prec": p["precs"][i], "cpu_seconds": round(time.process_time() - cpu0, 2),
            "steps": getattr(f, "steps", 0), "on": time.strftime("%Y-%m-%d %H:%M", time.gmtime())}


def _end_and_start(rec: Dict[str, Any]) -> Dict[str, Any]:
    from ._balls import working_precision
    from .homoclinic_chain import check_end, check_start

    p = _parse(rec)
    ok_s, msg_s = check_start(p["sets"][0], *p["local"])
    with working_precision(max(p["precs"])):
        e = check_end(p["sets"][-1], p["R"])
    return {"start_ok": ok_s, "start": msg_s, "end_ok": e.ok, "end": e.message, "sides": list(e.sides)}


def _run_jobs(rec: Dict[str, Any], idx: Sequence[int], workers: int, on_result: Any) -> None:
    from ._run_state import run_jobs

    run_jobs(_relation_job, [(rec, i) for i in idx], workers, lambda k, r: on_result(r))


def _verdict(rec: Dict[str, Any], res: Dict[int, Dict[str, Any]], ends: Dict[str, Any]) -> tuple:
    n = len(rec["sets"]) - 1
    if not ends["start_ok"]:
        return False, f"start: {ends['start']}"
    if not ends["end_ok"]:  # checked before any job runs: no job ran
        return False, f"end: {ends['end']}"
    loc = res.get(-1)
    if loc is None or not loc["ok"]:
        return False, f"local manifold: {loc['message'] if loc else 'not run'}"
    for i in range(n):
        r = res.get(i)
        if r is None:
            return False, f"relation {i} => {i + 1}: not run"
        if not r["ok"]:
            return False, f"relation {i} => {i + 1}: {r['message']}"
    return True, (f"proved: the local unstable manifold, {n} covering relations with cone conditions and the end "
                  f"({ends['end']})")


def check_chain(cert: Dict[str, Any], *, workers: int = 1) -> CheckResult:
    """Re-prove a ``transversal_homoclinic_point`` certificate from scratch (module docstring):
    ``ok`` only if everything holds with the claimed orientations and sides."""
    cpu0 = time.process_time()
    if cert.get("claim") != "transversal_homoclinic_point":
        raise UsageError(f"not a chain certificate (claim {cert.get('claim')!r})")
    if cert.get("proved") is not True:
        return CheckResult(False, "not proved: the certificate records a failed or unfinished attempt",
                           time.process_time() - cpu0)
    p = _parse(cert)
    n = len(p["sets"]) - 1
    claimed = cert.get("relations", {})
    res: Dict[int, Dict[str, Any]] = {}
    child = [0.0]

    def keep(r: Dict[str, Any]) -> bool:
        res[r["i"]] = r
        child[0] += r["cpu_seconds"]
        logging.getLogger(__name__).info("chain job %d: %s [%.1f CPU s]", r["i"], r["message"], r["cpu_seconds"])
        return bool(r["ok"])

    ends = _end_and_start(cert)
    if ends["start_ok"] and ends["end_ok"]:
        _run_jobs(cert, [-1] + list(range(n)), workers, keep)
    ok, msg = _verdict(cert, res, ends)
    cpu = time.process_time() - cpu0 + (child[0] if workers > 1 else 0.0)
    if not ok:
        return CheckResult(False, f"not proved: {msg}", cpu)
    for i in range(n):
        want = claimed.get(str(i), {}).get("orientation")
        if want != res[i]["orientation"]:
            return CheckResult(False, f"not proved: relation {i} => {i + 1} has orientation {res[i]['orientation']:+d}, "
                                      f"the certificate claims {want!r}", cpu)
    if list(cert.get("sides", [])) != ends["sides"]:
        return CheckResult(False, f"not proved: the exit edges of N_n lie on the sides {ends['sides']} of Fix(R), the "
                                  f"certificate claims {cert.get('sides')}", cpu)
    return CheckResult(True, f"proved: {cert.get('title', '')} ({msg.removeprefix('proved: ')})", cpu)


def finish_chain(rec: Dict[str, Any]) -> Dict[str, Any]:
    """Set ``proved``/``message``/``sides`` of a record from its stored results (no new work)."""
    res = {int(k): v for k, v in rec.get("relations", {}).items()}
    if rec.get("local_result") is not None:
        res[-1] = rec["local_result"]
    ends = _end_and_start(rec)
    ok, msg = _verdict(rec, res, ends)
    rec["proved"], rec["message"], rec["sides"] = ok, msg if ok else f"not proved: {msg}", ends["sides"]
    rec["cpu_seconds"] = round(sum(r["cpu_seconds"] for r in res.values()), 2)
    return rec


def run_chain(state: str | os.PathLike, *, workers: int = 1, record: Optional[Dict[str, Any]] = None,
              only: Optional[Sequence[int]] = None) -> Dict[str, Any]:
    """Prove the relations (and the local manifold, job ``-1``) of the record in the state
    file ``state`` that are not done yet, writing each result there as it finishes. A new
    state file is made from ``record``; an existing one is resumed, and refused if ``record``
    is given and is another design. ``only``: these jobs only, in this order. Returns the record."""
    from .._store_lock import Lock
    from ..io import atomic_write_bytes
    from ._run_state import check_workers, open_run_state

    check_workers(workers)
    path = Path(state)
    rec = open_run_state(path, record, _design_hash)
    n = len(rec["sets"]) - 1
    done = {int(k) for k in rec.get("relations", {})} | ({-1} if rec.get("local_result") else set())
    todo = [i for i in (list(range(n)) + [-1] if only is None else list(only)) if i not in done]
    if any(not -1 <= i < n for i in todo):
        raise UsageError(f"only: job numbers must be -1 (the local manifold) or 0 .. {n - 1}, got {list(only or [])}")

    def save() -> None:
        atomic_write_bytes(path, (json.dumps(rec, indent=1) + "\n").encode())

    def keep(r: Dict[str, Any]) -> bool:
        if r["i"] < 0:
            rec["local_result"] = r
        else:
            rec.setdefault("relations", {})[str(r["i"])] = r
        finish_chain(rec)
        save()
        logging.getLogger(__name__).info("chain job %d: %s [%.1f CPU s]", r["i"], r["message"], r["cpu_seconds"])
        return True

    with Lock(Path(str(path) + ".lock"), f"the chain state {str(path)!r}"):  # one run per state file
        save()
        _run_jobs(rec, todo, workers, keep)
        finish_chain(rec)
        save()
    return rec
