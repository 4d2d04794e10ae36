r"""Certificates: a claim, everything needed to re-prove it, and the checker.

A certificate is a JSON file. The claim proved so far is an **enclosure**: "for the system
``kind`` with parameters ``params`` (exact rationals), every solution starting in the box
``state +- radius`` (exact binary numbers) lies at time ``t`` (exact) in the box
``[lower, upper]`` (exact binary numbers)". :func:`check_certificate` re-computes the
enclosure from scratch with the certificate's method (precision, order, tolerance, wrapping)
and accepts only if the recomputed balls lie inside the claimed box; the search that
produced the claim is not part of the check.

Every number is stored exactly: floats as ``float.hex`` strings (with a decimal rendering for
people), parameters as ``"p/q"`` rationals.
"""

from __future__ import annotations

import json
import logging
import math
import os
import tempfile
import time
from fractions import Fraction
from pathlib import Path
from typing import Any, Dict, List, Sequence, Tuple

import numpy as np

from ..errors import UsageError
from ..params import BallParams
from ._cert_json import (FORMAT, CheckResult, _exact, _exact_float, _levels_from_json, _levels_json,  # noqa: F401
                         _params_from_json, _params_json, _rational, _read_exact)
from ._run_state import check_workers, run_jobs

__all__ = ["CERT_DIR", "enclosure_certificate", "fixed_point_certificate", "periodic_orbit_certificate", "periodic_orbit_design", "check_periodic_orbit_certificate", "fig1_fixed_point_certificate", "fig1_shooting_certificate", "tzenoff_certificate", "fig3_enclosure_certificate", "covering_certificate", "hsets_disjoint", "load_certificate", "check_certificate", "write_certificate", "list_certificates",
           "CheckResult"]

#: The certificates shipped with the package.
CERT_DIR = Path(__file__).with_name("certificates")


def _widen(lo: float, hi: float, side: int) -> float:
    """``lo - (hi - lo)`` (side -1) or ``hi + (hi - lo)`` (side +1), rounded outward."""
    import math

    w = hi - lo
    v = lo - w if side < 0 else hi + w
    return math.nextafter(v, -math.inf if side < 0 else math.inf)


def enclosure_certificate(kind: str, params: Any, state: Sequence[float], t: float, *, radius: float = 0.0,
                          prec: int = 53, order: int | None = None, tol: float | None = None,
                          wrapping: str = "qr", title: str = "") -> Dict[str, Any]:
    """Prove an enclosure and return its certificate (a JSON-able dict)."""
    from .enclosure import enclose

    e = enclose(kind, params, state, t, radius, prec=prec, order=order, tol=tol, wrapping=wrapping)
    return {
        "format": FORMAT,
        "claim": "enclosure",
        "title": title or f"enclosure of the {kind} system at t = {t!r}",
        "statement": (f"every solution of the {kind} system (taylorball.model, public layout) starting in the box "
                      "state +- radius lies at time t in the box [lower, upper]"),
        "kind": kind,
        "params": _params_json(params),
        "state": [_exact(v) for v in state],
        "radius": _exact(radius),
        "t": _exact(t),
        # the claim: the enclosure widened by its own width on each side (rounded outward), so
        # that a re-check with another FLINT build or step sequence still fits inside it
        "box": {"lower": [_exact(_widen(lo, hi, -1)) for lo, hi in zip(e.lower, e.upper)],
                "upper": [_exact(_widen(lo, hi, +1)) for lo, hi in zip(e.lower, e.upper)]},
        "method": {"prec": prec, "order": e.order, "tol": _exact(2.0 ** (-prec) if tol is None else tol),
                   "wrapping": wrapping, "steps": e.steps},
        "proved_cpu_seconds": round(e.cpu_seconds, 2),
        "proved_on": time.strftime("%Y-%m-%d"),
    }


def check_certificate(cert: Dict[str, Any], *, workers: int = 1) -> CheckResult:
    """Re-prove a certificate from scratch. ``ok`` only if every recomputed ball lies inside
    the claimed box; otherwise the message names the first component that fails and by how
    much. ``workers``: processes for the independent covering relations of a
    ``covering_relations`` certificate, for the segments of a ``periodic_orbit`` one and for
    the relations of a ``transversal_homoclinic_point`` one (the
    other claims run in the calling process; the verdict does not depend on it). A
    ``periodic_orbit`` certificate's check can also keep its jobs in a state file and be
    resumed: :func:`~taylorball.rigorous.periodic_orbit_run.check_periodic_orbit`."""
    check_workers(workers)
    from ._balls import exact_arb, working_precision
    from .enclosure import enclose

    cpu0 = time.process_time()
    if not isinstance(cert, dict) or cert.get("format") != FORMAT:
        raise UsageError(f"not a taylorball certificate (format must be {FORMAT!r})")
    if cert.get("claim") == "fixed_point":
        return _check_fixed_point(cert, cpu0)
    if cert.get("claim") == "covering_relations":
        return _check_covering(cert, cpu0, workers)
    if cert.get("claim") == "periodic_orbit":
        return check_periodic_orbit_certificate(cert, workers=workers, cpu0=cpu0)
    if cert.get("claim") in ("homoclinic_point", "local_unstable_manifold"):
        from .homoclinic_check import check_homoclinic

        return check_homoclinic(cert, cpu0)
    if cert.get("claim") == "transversal_homoclinic_point":
        from .homoclinic_chain_cert import check_chain

        return check_chain(cert, workers=workers)
    if cert.get("claim") != "enclosure":
        raise UsageError(f"certificate claim {cert.get('claim')!r} is not known to this checker "
                         "(known: 'enclosure', 'fixed_point', 'periodic_orbit', 'covering_relations', "
                         "'homoclinic_point', 'local_unstable_manifold', 'transversal_homoclinic_point')")
    kind = cert["kind"]
    params = _params_from_json(cert["params"])
    x0 = [_read_exact(v, "state") for v in cert["state"]]
    radius = _read_exact(cert["radius"], "radius")
    t = _read_exact(cert["t"], "t")
    lower = [_read_exact(v, "box.lower") for v in cert["box"]["lower"]]
    upper = [_read_exact(v, "box.upper") for v in cert["box"]["upper"]]
    m = cert["method"]
    prec, order, wrapping = int(m["prec"]), int(m["order"]), str(m["wrapping"])
    tol = _read_exact(m["tol"], "method.tol")
    if len(lower) != len(x0) or len(upper) != len(x0):
        return CheckResult(False, "not proved: the claimed box has the wrong dimension", time.process_time() - cpu0)
    e = enclose(kind, params, x0, t, radius, prec=prec, order=order, tol=tol, wrapping=wrapping)
    with working_precision(prec):
        for i, (b, lo, hi) in enumerate(zip(e.balls, lower, upper)):
            if not (exact_arb(lo) <= b and b <= exact_arb(hi)):
                over = max(float(exact_arb(lo).mid()) - float(b.lower().mid()),
                           float(b.upper().mid()) - float(exact_arb(hi).mid()))
                return CheckResult(False, f"not proved: component {i} of the recomputed enclosure "
                                   f"[{float(b.lower().mid())!r}, {float(b.upper().mid())!r}] is not inside the claimed "
                                   f"[{lo!r}, {hi!r}] (outside by {over:.3g})", time.process_time() - cpu0)
    return CheckResult(True, f"proved: {cert.get('title', '')} ({e.steps} validated steps at {prec} bits)",
                       time.process_time() - cpu0)


def write_certificate(cert: Dict[str, Any], path: str | os.PathLike) -> Path:
    """Write ``cert`` atomically to ``path`` (JSON)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".", prefix=".tmp_cert_", suffix=".json")
    with os.fdopen(fd, "w") as f:
        json.dump(cert, f, indent=1)
        f.write("\n")
    os.chmod(tmp, 0o644)  # mkstemp makes it private; a certificate is for others to read
    os.replace(tmp, path)
    return path


def load_certificate(path: str | os.PathLike) -> Dict[str, Any]:
    """Read a certificate file; :class:`UsageError` if it is missing or not JSON."""
    try:
        with open(path) as f:
            return json.load(f)
    except FileNotFoundError:
        raise UsageError(f"certificate file {str(path)!r} does not exist") from None
    except json.JSONDecodeError as exc:
        raise UsageError(f"certificate file {str(path)!r} is not JSON: {exc}") from None


def list_certificates(folder: str | os.PathLike | None = None) -> List[Tuple[str, str, str]]:
    """``(file name, claim, title)`` of every ``*cert*.json`` in ``folder`` (default: the
    package's certificates)."""
    folder = Path(folder) if folder is not None else CERT_DIR
    out = []
    for p in sorted(folder.glob("*cert*.json")):
        try:
            c = load_certificate(p)
        except UsageError:
            continue
        out.append((p.name, str(c.get("claim", "?")), str(c.get("title", ""))))
    return out


def fig3_enclosure_certificate(t: float = 0.5, prec: int = 53) -> Dict[str, Any]:
    """The shipped certificate ``fig3_enclosure_cert.json``: the dynamically symmetric ball
    of Fig. 3 from a state on its section (level ``C = 10, M_gamma = 6, h = 5``, chart point
    ``(l, r1, r2) = (0, 1, 0.5)``, the first root ``K``), enclosed to time ``t``."""
    from ..charts import states_on_section
    from ..paper import FIG3_BALL, FIG3_LEVELS

    x0 = states_on_section(FIG3_BALL, **FIG3_LEVELS.as_kwargs(), point=(0.0, 1.0, 0.5), direction=1)[0]
    return enclosure_certificate("reduced", FIG3_BALL, [float(v) for v in x0], t, prec=prec,
                                 title=f"Fig. 3 ball (I1 = I2): a section state enclosed to t = {t!r} at {prec} bits")


_FP_STATEMENT = {
    "reduced": ("the 2D section map (r1, r2) -> (r1', r2') of the reduced system with I1 = I2 on the level "
                "(C, M_gamma, h), section g = 0 with g increasing, l = 0, near return time tau_guess and energy "
                "root K = M3 near K_guess, has exactly one fixed point in the box center +- radius (Krawczyk); "
                "it lies in fixed_point_box"),
    "mparallel": ("the section map (l, L/G) -> (l', L'/G') of the M||gamma system (paper section 5) on the level "
                  "(lambda, Etilde = h), section g = 0 with g increasing, near return time tau_guess and "
                  "G = |K| near K_guess (l' taken in l_branch + (-pi/2, pi/2)), has exactly one fixed point in "
                  "the box center +- radius (Krawczyk): a periodic orbit of the flow; it lies in fixed_point_box"),
}


_BRANCH_NAMES = {0.0: "0", math.pi / 2: "pi/2", math.pi: "pi", 3 * math.pi / 2: "3pi/2"}
L_BRANCH_INDEX = {0.0: 0, math.pi / 2: 1, math.pi: 2, 3 * math.pi / 2: 3}


def fixed_point_certificate(params: Any, levels: Any, center: Sequence[float], radius: float, K_guess: float,
                            tau_guess: float, *, prec: int = 128, delta: float = 1e-3, title: str = "",
                            kind: str = "reduced", l_branch: float = 0.0) -> Dict[str, Any]:
    """Run the Krawczyk proof (:func:`taylorball.rigorous.proofs.krawczyk_fixed_point`) and
    return its certificate; ``"proved": false`` with the reason if it did not close. The
    claimed ``fixed_point_box`` is ``K(X)`` rounded outward and widened by its own width on
    each side (so that a re-check with another FLINT build still fits)."""
    from .proofs import krawczyk_fixed_point

    r = krawczyk_fixed_point(params, levels, list(center), radius, K_guess, tau_guess, prec=prec, delta=delta,
                             kind=kind, l_branch=l_branch)
    cert: Dict[str, Any] = {
        "format": FORMAT,
        "claim": "fixed_point",
        "title": title or f"a {r.kind} fixed point of the {kind} system's 2D section map",
        "statement": _FP_STATEMENT[kind],
        "kind": kind,
        "params": _params_json(params),
        "levels": _levels_json(kind, levels),
        "center": [_exact(v) for v in center],
        "radius": _exact(radius),
        "K_guess": _exact(K_guess),
        "tau_guess": _exact(tau_guess),
        "l_branch": _BRANCH_NAMES[l_branch],
        "method": {"prec": prec, "delta": _exact(delta), "c1": "lohner"},
    }
    cert.update(_krawczyk_outcome(r, "fixed_point_box"))
    return cert


def _krawczyk_outcome(r: Any, box_name: str) -> Dict[str, Any]:
    """The outcome part of a Krawczyk certificate: verdict, orbit type, message, cost, date
    and, if proved, the claimed box ``box_name`` (:func:`_claimed_box`) and an enclosure of
    the trace of the map's Jacobian (``multiplier_trace``; for people, not re-checked)."""
    from .enclosure import outward_float

    out: Dict[str, Any] = {"proved": bool(r.proved), "orbit_type": r.kind, "message": r.message,
                           "proved_cpu_seconds": round(r.cpu_seconds, 2), "proved_on": time.strftime("%Y-%m-%d")}
    if r.proved:
        out[box_name] = _claimed_box(r.K)
        out["multiplier_trace"] = {"lower": _exact(outward_float(r.trace, -1)),
                                   "upper": _exact(outward_float(r.trace, +1))}
    return out


def _check_fixed_point(cert: Dict[str, Any], cpu0: float) -> CheckResult:
    from .proofs import krawczyk_fixed_point

    kind = str(cert.get("kind", "reduced"))
    if kind not in _FP_STATEMENT:
        raise UsageError(f"certificate: kind must be one of {sorted(_FP_STATEMENT)}, got {kind!r}")
    if cert.get("proved") is not True:
        return CheckResult(False, f"not proved: the certificate itself records a failed attempt ({cert.get('message')})",
                           time.process_time() - cpu0)
    params = _params_from_json(cert["params"])
    levels = _levels_from_json(kind, cert["levels"])
    center = [_read_exact(v, "center") for v in cert["center"]]
    lb = cert.get("l_branch", "0")
    branches = {v: k for k, v in _BRANCH_NAMES.items()}
    if lb not in branches:
        raise UsageError(f"certificate: l_branch must be one of {sorted(branches)}, got {lb!r}")
    m = cert["method"]
    r = krawczyk_fixed_point(params, levels, center, _read_exact(cert["radius"], "radius"),
                             _read_exact(cert["K_guess"], "K_guess"), _read_exact(cert["tau_guess"], "tau_guess"),
                             prec=int(m["prec"]), delta=_read_exact(m["delta"], "method.delta"), kind=kind,
                             l_branch=branches[lb], c1=str(m.get("c1", "lohner")))
    if not r.proved:
        return CheckResult(False, r.message, time.process_time() - cpu0)
    if cert.get("orbit_type") != r.kind:
        return CheckResult(False, f"not proved: the orbit type is {r.kind}, the certificate says {cert.get('orbit_type')}",
                           time.process_time() - cpu0)
    box = cert.get("fixed_point_box")
    if box is not None:
        bad = _outside_claimed_box(r.K, box, "fixed_point_box", int(m["prec"]))
        if bad:
            return CheckResult(False, bad, time.process_time() - cpu0)
    return CheckResult(True, r.message, time.process_time() - cpu0)


def _claimed_box(K: Sequence[Any]) -> Dict[str, Any]:
    """The claimed location of a Krawczyk zero: ``K(X)`` rounded outward and widened by its
    own width on each side (so that a re-check with another FLINT build still fits)."""
    from .enclosure import outward_float

    lo = [outward_float(k, -1) for k in K]
    hi = [outward_float(k, +1) for k in K]
    return {"lower": [_exact(_widen(a, b, -1)) for a, b in zip(lo, hi)],
            "upper": [_exact(_widen(a, b, +1)) for a, b in zip(lo, hi)]}


def _outside_claimed_box(K: Sequence[Any], box: Dict[str, Any], name: str, prec: int) -> str:
    """``""`` if every recomputed ball of ``K`` lies in the claimed ``box``, else the "not
    proved" message naming the first component outside and by how much."""
    from ._balls import exact_arb, working_precision

    try:
        if len(box["lower"]) != len(K) or len(box["upper"]) != len(K):
            return f"not proved: the claimed {name} has {len(box['lower'])} components, the proof {len(K)}"
    except (KeyError, TypeError):
        raise UsageError(f"certificate: {name} must be {{'lower': [...], 'upper': [...]}}, got {box!r}") from None
    with working_precision(prec):
        for i, k in enumerate(K):
            lo = _read_exact(box["lower"][i], f"{name}.lower")
            hi = _read_exact(box["upper"][i], f"{name}.upper")
            if not (exact_arb(lo) <= k and k <= exact_arb(hi)):
                over = max(lo - float(k.lower().mid()), float(k.upper().mid()) - hi)
                return (f"not proved: component {i} of the recomputed K(X) {k.str(10)} is not "
                        f"inside the claimed {name} [{lo!r}, {hi!r}] (outside by {over:.3g})")
    return ""


# ---------------------------------------------------------------------------------------
# Periodic orbits by multiple shooting
# ---------------------------------------------------------------------------------------
_PO_STATEMENT = {
    "reduced": ("the 2D section map P (r1, r2) -> (r1', r2') of the reduced system with I1 = I2 on the level "
                "(C, M_gamma, h), section g = 0 with g increasing, l = 0, has exactly one periodic orbit "
                "p_0 -> p_1 -> ... -> p_{m-1} -> p_0 (m = segments) with p_i in the box centers[i] +- radius, "
                "where step i is the local section map near return time tau_guesses[i] on the energy root "
                "K = M3 near K_guesses[i] (Krawczyk on the multiple-shooting map); the points lie in "
                "periodic_box (p_0, then p_1, ..., two components each): a relative periodic orbit of the flow"),
    "mparallel": ("the section map P (l, L/G) -> (l', L'/G') of the M||gamma system (paper section 5) on the "
                  "level (lambda, Etilde = h), section g = 0 with g increasing, has exactly one periodic orbit "
                  "p_0 -> p_1 -> ... -> p_{m-1} -> p_0 (m = segments) with p_i in the box centers[i] +- radius, "
                  "where step i is the local section map near return time tau_guesses[i] with G = |K| near "
                  "K_guesses[i] and l' taken in l_branches[i] + (-pi/2, pi/2) (Krawczyk on the "
                  "multiple-shooting map); the points lie in periodic_box (p_0, then p_1, ..., two components "
                  "each): a periodic orbit of the flow"),
    "reduced3": ("the 3D section map P (l, r1, r2) -> (l', r1', r2') of the reduced system (any inertia) on the "
                 "level (C, M_gamma, h), section g = 0 with g increasing, has exactly one periodic orbit "
                 "p_0 -> p_1 -> ... -> p_{m-1} -> p_0 (m = segments) with p_i in the box centers[i] +- radius, "
                 "where step i is the local section map near return time tau_guesses[i] on the energy root "
                 "K = M3 near K_guesses[i], l' taken near l_branches[i] pi/2 (Krawczyk on the "
                 "multiple-shooting map); the points lie in periodic_box (p_0, then p_1, ..., three components "
                 "each): a periodic orbit of the flow"),
}


def _exact_center(v: Any) -> Dict[str, str]:
    """A float as ``float.hex``; a dyadic :class:`~fractions.Fraction` (a centre refined
    beyond float64) as the exact rational ``"p/q"``."""
    if isinstance(v, Fraction):
        if v.denominator & (v.denominator - 1):
            raise UsageError(f"a centre given as a Fraction must be dyadic (denominator a power of 2), got {v}")
        return {"rational": f"{v.numerator}/{v.denominator}", "decimal": repr(float(v))}
    return _exact(v)


def _read_center(d: Any) -> Any:
    if isinstance(d, dict) and "rational" in d:
        try:
            q = Fraction(d["rational"])
        except (TypeError, ValueError):
            raise UsageError(f"certificate: a centre's 'rational' must be 'p/q', got {d['rational']!r}") from None
        if q.denominator & (q.denominator - 1):
            raise UsageError(f"certificate: a centre's rational must be dyadic, got {d['rational']!r}")
        return q
    return _read_exact(d, "centers")


def periodic_orbit_design(params: Any, levels: Any, centers: Sequence[Sequence[Any]], radius: float,
                          K_guesses: Sequence[float], tau_guesses: Sequence[float], *, prec: int = 128,
                          order: int | None = None, delta: float = 1e-3, kind: str = "reduced",
                          l_branches: Sequence[float] | None = None, title: str = "") -> Dict[str, Any]:
    """The ``periodic_orbit`` certificate's data before any proof (``"proved": false``): what
    :func:`periodic_orbit_certificate` fills in, and what a resumable run
    (:func:`taylorball.rigorous.periodic_orbit_run.run_periodic_orbit`) starts from. The
    arguments are checked here (:func:`~taylorball.rigorous.proofs.shooting_jobs`)."""
    from ._taylor import default_order
    from .proofs import MAP_DIM, shooting_jobs

    if kind not in _PO_STATEMENT:
        raise UsageError(f"kind must be one of {sorted(_PO_STATEMENT)}, got {kind!r}")
    jobs = shooting_jobs(params, levels, centers, radius, K_guesses, tau_guesses, prec=prec, order=order, delta=delta,
                         kind=kind, l_branches=l_branches)
    m = len(centers)
    order = default_order(prec) if order is None else int(order)
    branches = [str(int(j[11])) for j in jobs[::2]] if kind == "reduced3" else [_BRANCH_NAMES[j[11]] for j in jobs[::2]]
    return {
        "format": FORMAT,
        "claim": "periodic_orbit",
        "title": title or f"a periodic orbit of period {m} of the {kind} system's {MAP_DIM[kind]}D section map",
        "statement": _PO_STATEMENT[kind],
        "kind": kind,
        "params": _params_json(params),
        "levels": _levels_json("reduced" if kind == "reduced3" else kind, levels),
        "segments": m,
        "centers": [[_exact_center(v) for v in c] for c in centers],
        "radius": _exact(radius),
        "K_guesses": [_exact(v) for v in K_guesses],
        "tau_guesses": [_exact(v) for v in tau_guesses],
        "l_branches": branches,
        "method": {"prec": prec, "order": order, "delta": _exact(delta), "c1": "lohner"},
        "proved": False,
        "message": "not run",
    }


def periodic_orbit_certificate(params: Any, levels: Any, centers: Sequence[Sequence[Any]], radius: float,
                               K_guesses: Sequence[float], tau_guesses: Sequence[float], *, prec: int = 128,
                               order: int | None = None, delta: float = 1e-3, kind: str = "reduced",
                               l_branches: Sequence[float] | None = None, workers: int = 1,
                               title: str = "") -> Dict[str, Any]:
    """Run the multiple-shooting Krawczyk proof
    (:func:`taylorball.rigorous.proofs.krawczyk_periodic_orbit`) and return its certificate
    (claim ``periodic_orbit``; ``"proved": false`` with the reason if it did not close). The
    claimed ``periodic_box`` is ``K(X)`` rounded outward and widened by its own width on each
    side; ``multiplier_trace`` encloses the trace of ``D(P^m)`` at the orbit."""
    from .proofs import krawczyk_periodic_orbit

    cert = periodic_orbit_design(params, levels, centers, radius, K_guesses, tau_guesses, prec=prec, order=order,
                                 delta=delta, kind=kind, l_branches=l_branches, title=title)
    r = krawczyk_periodic_orbit(params, levels, centers, radius, K_guesses, tau_guesses, prec=prec,
                                order=cert["method"]["order"], delta=delta, workers=workers, kind=kind,
                                l_branches=l_branches)
    if not title:
        cert["title"] = f"a {r.kind} periodic orbit of period {len(centers)} of the {kind} system's " \
                        f"{len(centers[0])}D section map"
    cert["validated_steps"] = r.steps
    cert.update(_krawczyk_outcome(r, "periodic_box"))
    return cert


def check_periodic_orbit_certificate(cert: Dict[str, Any], *, workers: int = 1, cpu0: float | None = None,
                                     prove: Any = None) -> CheckResult:
    """Check a ``periodic_orbit`` certificate (:func:`check_certificate`). ``prove``: a function
    of ``workers`` that returns the Krawczyk verdict
    (:class:`~taylorball.rigorous.proofs.ShootingResult`) of the certificate's design, or
    a message (a string) while it is unfinished; default: :func:`~taylorball.rigorous.proofs.krawczyk_periodic_orbit`
    from scratch here (the resumable check passes its own)."""
    from .proofs import MAP_DIM, krawczyk_periodic_orbit

    cpu0 = time.process_time() if cpu0 is None else cpu0

    def fail(msg: str) -> CheckResult:
        return CheckResult(False, f"not proved: {msg}", time.process_time() - cpu0)

    kind = str(cert.get("kind", "reduced"))
    if kind not in _PO_STATEMENT:
        raise UsageError(f"certificate: kind must be one of {sorted(_PO_STATEMENT)}, got {kind!r}")
    if cert.get("proved") is not True:
        return fail(f"the certificate itself records a failed attempt ({cert.get('message')})")
    try:
        m = int(cert["segments"])
        centers = [[_read_center(v) for v in c] for c in cert["centers"]]
        K_guesses = [_read_exact(v, "K_guesses") for v in cert["K_guesses"]]
        tau_guesses = [_read_exact(v, "tau_guesses") for v in cert["tau_guesses"]]
        names = list(cert["l_branches"])
        meth = cert["method"]
        prec, order, delta = int(meth["prec"]), int(meth["order"]), _read_exact(meth["delta"], "method.delta")
    except (KeyError, TypeError, ValueError) as exc:
        raise UsageError(f"certificate: a periodic_orbit certificate needs segments, centers, K_guesses, "
                         f"tau_guesses, l_branches and method (prec, order, delta); {exc!r}") from None
    lens = {"centers": len(centers), "K_guesses": len(K_guesses), "tau_guesses": len(tau_guesses),
            "l_branches": len(names)}
    if m < 1 or any(n != m for n in lens.values()):
        return fail(f"the certificate claims {m} segments but lists {lens}")
    d = MAP_DIM[kind]
    if any(len(c) != d for c in centers):
        return fail(f"every centre must have {d} components")
    branches = {v: k for k, v in _BRANCH_NAMES.items()}
    if kind != "reduced3" and any(b not in branches for b in names):
        raise UsageError(f"certificate: l_branches must be among {sorted(branches)}, got {names!r}")
    if "periodic_box" not in cert:
        return fail("the certificate has no periodic_box")
    if prove is not None:
        r = prove(workers)
        if isinstance(r, str):
            return CheckResult(False, r, time.process_time() - cpu0)
    else:
        r = krawczyk_periodic_orbit(_params_from_json(cert["params"]),
                                    _levels_from_json("reduced" if kind == "reduced3" else kind, cert["levels"]), centers,
                                    _read_exact(cert["radius"], "radius"), K_guesses, tau_guesses, prec=prec, order=order,
                                    delta=delta, workers=workers, kind=kind,
                                    l_branches=None if kind == "reduced3" else [branches[b] for b in names])
    cpu = r.cpu_seconds
    if not r.proved:
        return CheckResult(False, r.message, cpu)
    if cert.get("orbit_type") != r.kind:
        return CheckResult(False, f"not proved: the orbit type is {r.kind}, the certificate says "
                           f"{cert.get('orbit_type')}", cpu)
    bad = _outside_claimed_box(r.K, cert["periodic_box"], "periodic_box", prec)
    if bad:
        return CheckResult(False, bad, cpu)
    return CheckResult(True, f"{r.message} ({r.steps} validated steps at {prec} bits, {m} segments)", cpu)


#: The Fig. 1 fixed points' Krawczyk boxes (half-width in (l, L/G)) and the working precision.
#: The elliptic point needs the smaller box: at 1e-7 its existence is proved but the trace
#: enclosure ([-1.69 +- 2.39]) does not decide the type.
FIG1_RADIUS = {"0": 1e-7, "pi": 1e-7, "pi/2": 1e-9}
FIG1_PREC = 53
FIG1_CERT_NAMES = {"0": "fig1_saddle_l0_cert.json", "pi": "fig1_saddle_lpi_cert.json",
                   "pi/2": "fig1_elliptic_lpi2_cert.json"}


def _fig1_candidate(branch: str) -> Tuple[float, List[float], float, float]:
    """The float64 candidate of the Fig. 1 fixed point on ``branch``: ``(l_branch, center,
    G, period)`` (:func:`taylorball.periodic_orbit` from ``(l, L/G) = (l_branch, 0)``; it
    proposes, no proof uses it)."""
    from .._chart_mparallel import mparallel_chart, mparallel_states_on_section
    from ..paper import FIG1_LEVELS, fig1_params
    from ..periodic import periodic_orbit

    branches = {v: k for k, v in _BRANCH_NAMES.items()}
    lb = branches[branch]
    params = fig1_params()
    x0 = mparallel_states_on_section(params, **FIG1_LEVELS.as_kwargs(), point=(lb, 0.0))[0]
    orbit = periodic_orbit("mparallel", params, x0, levels=FIG1_LEVELS)
    ch = mparallel_chart(np.asarray(orbit.state, dtype=float))
    l0 = float(ch["l"])
    if l0 < lb - math.pi:
        l0 += 2 * math.pi
    return lb, [l0, float(ch["L/G"])], float(ch["G"]), float(orbit.period)


def fig1_fixed_point_certificate(branch: str = "0") -> Dict[str, Any]:
    r"""The shipped certificates of the Fig. 1 M||gamma section map (paper's Fig. 1
    parameters and level; file names in :data:`FIG1_CERT_NAMES`): the hyperbolic fixed points
    at ``l = 0`` and ``l = pi`` (``branch="0"``, ``"pi"``) and the elliptic one at
    ``l = pi/2`` (``"pi/2"``).

    The candidate comes from :func:`taylorball.periodic_orbit` (float64 Newton from the
    chart point ``(l, L/G) = (l_branch, 0)``: not part of the proof); the proof is
    :func:`taylorball.rigorous.proofs.krawczyk_fixed_point` on a box of half-width
    ``FIG1_RADIUS[branch]`` at :data:`FIG1_PREC` bits."""
    from ..paper import FIG1_LEVELS, fig1_params

    if branch not in FIG1_RADIUS:
        raise UsageError(f"branch must be one of {sorted(FIG1_RADIUS)}, got {branch!r}")
    lb, center, G, period = _fig1_candidate(branch)
    what = "the elliptic fixed point" if branch == "pi/2" else "the saddle"
    return fixed_point_certificate(
        fig1_params(), FIG1_LEVELS, center, FIG1_RADIUS[branch], G, period,
        prec=FIG1_PREC, kind="mparallel", l_branch=lb,
        title=f"Fig. 1 (M||gamma, a = (1, 2, 3), d = 4, Omega = 1/2; lambda = 2, h = 100): {what} at l = {branch}, "
              f"a periodic orbit of period {period:.6f}")


#: The shipped multiple-shooting certificate of the Fig. 1 saddle at ``l = 0``.
FIG1_SHOOTING_CERT_NAME = "fig1_saddle_l0_2seg_cert.json"


def fig1_shooting_certificate(segments: int = 2, workers: int = 1) -> Dict[str, Any]:
    r"""The shipped certificate :data:`FIG1_SHOOTING_CERT_NAME`: the Fig. 1 saddle at
    ``l = 0`` as a periodic orbit of period ``segments`` of the section map, by multiple
    shooting (:func:`taylorball.rigorous.proofs.krawczyk_periodic_orbit`) through
    ``segments`` boxes of half-width ``FIG1_RADIUS["0"]`` around the same float64 candidate,
    at :data:`FIG1_PREC` bits. Uniqueness in the product of the boxes makes every point of the
    orbit the fixed point of ``fig1_saddle_l0_cert.json``; the certificate is the format's
    working example (each segment's enclosures run in their own worker with ``workers > 1``)."""
    from ..paper import FIG1_LEVELS, fig1_params

    if isinstance(segments, bool) or not isinstance(segments, int) or not 1 <= segments <= 16:
        raise UsageError(f"segments must be an integer in [1, 16], got {segments!r}")
    lb, center, G, period = _fig1_candidate("0")
    return periodic_orbit_certificate(
        fig1_params(), FIG1_LEVELS, [center] * segments, FIG1_RADIUS["0"], [G] * segments, [period] * segments,
        prec=FIG1_PREC, kind="mparallel", l_branches=[lb] * segments, workers=workers,
        title=f"Fig. 1 (M||gamma, a = (1, 2, 3), d = 4, Omega = 1/2; lambda = 2, h = 100): the saddle at l = 0 "
              f"by multiple shooting with {segments} segments (period {segments} of the section map)")


# ---------------------------------------------------------------------------------------
# Covering relations (a topological horseshoe of the M||gamma map)
# ---------------------------------------------------------------------------------------
_HS_STATEMENT = (
    "for the section map P (l, L/G) -> (l', L'/G') of the M||gamma system on the level (lambda, Etilde = h), "
    "section g = 0 with g increasing, each listed relation N => M (P taken as the local section map near "
    "the relation's tau_guess) is a covering relation of the h-sets N = center + B [-1, 1]^2 (first column "
    "of B the exit direction; Zgliczynski & Gidea 2004, one exit direction); loops and paths are chains of "
    "listed relations, and the pairs of h-sets listed in 'disjoint' are disjoint")


def _hset_json(N: Any) -> Dict[str, Any]:
    return {"name": N.name, "center": [_exact(v) for v in N.center],
            "B": [[_exact(v) for v in row] for row in N.B], "l_branch": _BRANCH_NAMES[N.l_branch],
            "G_guess": _exact(N.G_guess)}


def _hset_from_json(d: Dict[str, Any]) -> Any:
    from .covering import HSet

    branches = {v: k for k, v in _BRANCH_NAMES.items()}
    try:
        lb = branches[d["l_branch"]]
        B = [[_read_exact(v, "B") for v in row] for row in d["B"]]
        return HSet(str(d["name"]), tuple(_read_exact(v, "center") for v in d["center"]),  # type: ignore[arg-type]
                    ((B[0][0], B[0][1]), (B[1][0], B[1][1])), lb, _read_exact(d["G_guess"], "G_guess"))
    except (KeyError, IndexError, TypeError):
        raise UsageError(f"certificate: an h-set must have name, center (2), B (2 x 2), l_branch and G_guess, got {d!r}") from None


def _corners(N: Any) -> List[Tuple[Fraction, Fraction]]:
    c = [Fraction(v) for v in N.center]
    B = [[Fraction(v) for v in row] for row in N.B]
    return [(c[0] + B[0][0] * x + B[0][1] * y, c[1] + B[1][0] * x + B[1][1] * y)
            for x, y in ((-1, -1), (1, -1), (1, 1), (-1, 1))]


#: A rational lower bound of pi/2 (1.5707963...): the l-interval of every corner of an h-set
#: read on the branch l_branch lies in l_branch + (-HALF_PI_LO, HALF_PI_LO).
HALF_PI_LO = Fraction(157, 100)


def _within_branch(N: Any) -> bool:
    lb = Fraction(N.l_branch)
    return all(abs(x - lb) < HALF_PI_LO for x, _ in _corners(N))


def hsets_disjoint(N: Any, M: Any) -> bool:
    """True only if the parallelograms ``N`` and ``M`` of the chart are disjoint: on the same
    branch of ``l``, a separating axis among their edge normals (exact rational arithmetic);
    on opposite branches (``pi`` apart), every corner of each within ``+-1.57`` of its branch
    (so the two lie in disjoint arcs of the circle of ``l``). Other pairs: False."""
    if N.l_branch != M.l_branch:
        opposite = abs(L_BRANCH_INDEX[N.l_branch] - L_BRANCH_INDEX[M.l_branch]) == 2
        return opposite and _within_branch(N) and _within_branch(M)
    P, R = _corners(N), _corners(M)
    for poly in (P, R):
        for k in range(4):
            (x0, y0), (x1, y1) = poly[k], poly[(k + 1) % 4]
            nx, ny = y1 - y0, x0 - x1
            a = [nx * x + ny * y for x, y in P]
            b = [nx * x + ny * y for x, y in R]
            if max(a) < min(b) or max(b) < min(a):
                return True
    return False


def covering_certificate(params: Any, levels: Any, hsets: Sequence[Any], relations: Sequence[Any], *,
                         loops: Sequence[Sequence[str]], paths: Sequence[Sequence[str]],
                         disjoint: Sequence[Sequence[str]], prec: int = 53, delta: float = 1e-3,
                         title: str = "", workers: int = 1) -> Dict[str, Any]:
    """Check every covering relation (:func:`taylorball.rigorous.covering.check_relation`) and
    return the certificate (``"proved": false`` with the first failure if one does not
    close)."""
    cert: Dict[str, Any] = {
        "format": FORMAT, "claim": "covering_relations",
        "title": title or "covering relations of the M||gamma section map",
        "statement": _HS_STATEMENT, "kind": "mparallel", "params": _params_json(params),
        "levels": _levels_json("mparallel", levels), "h_sets": [_hset_json(N) for N in hsets],
        "relations": [{"source": r.source, "target": r.target, "tau_guess": _exact(r.tau_guess),
                       "n_pieces": r.n_pieces, "n_edge": r.n_edge} for r in relations],
        "loops": [list(x) for x in loops], "paths": [list(x) for x in paths],
        "disjoint": [list(x) for x in disjoint],
        "method": {"prec": prec, "delta": _exact(delta)},
    }
    res = check_certificate(dict(cert, proved=True), workers=workers)
    cert["proved"] = bool(res.ok)
    cert["message"] = res.message
    cert["proved_cpu_seconds"] = round(res.cpu_seconds, 2)
    cert["proved_on"] = time.strftime("%Y-%m-%d")
    return cert


def _check_covering(cert: Dict[str, Any], cpu0: float, workers: int = 1) -> CheckResult:
    from .covering import Relation

    def fail(msg: str) -> CheckResult:
        return CheckResult(False, f"not proved: {msg}", time.process_time() - cpu0)

    if cert.get("kind") != "mparallel":
        raise UsageError(f"certificate: covering relations are checked for kind 'mparallel', got {cert.get('kind')!r}")
    if cert.get("proved") is not True:
        return fail(f"the certificate itself records a failed attempt ({cert.get('message')})")
    params = _params_from_json(cert["params"])
    levels = _levels_from_json("mparallel", cert["levels"])
    sets = {}
    for d in cert["h_sets"]:
        N = _hset_from_json(d)
        if N.name in sets:
            raise UsageError(f"certificate: two h-sets are named {N.name!r}")
        sets[N.name] = N
    rels = []
    for d in cert["relations"]:
        if d.get("source") not in sets or d.get("target") not in sets:
            raise UsageError(f"certificate: relation {d.get('source')!r} => {d.get('target')!r} names an unknown h-set")
        rels.append(Relation(str(d["source"]), str(d["target"]), _read_exact(d["tau_guess"], "tau_guess"),
                             int(d.get("n_pieces", 1)), int(d.get("n_edge", 1))))
    pairs = {(r.source, r.target) for r in rels}
    for chain in list(cert.get("loops", [])) + list(cert.get("paths", [])):
        for a, b in zip(chain[:-1], chain[1:]):
            if (a, b) not in pairs:
                return fail(f"the chain {chain[0]} ... {chain[-1]} uses {a} => {b}, which is not a listed relation")
    for pair in cert.get("disjoint", []):
        if not (isinstance(pair, list) and len(pair) == 2 and all(x in sets for x in pair)):
            raise UsageError(f"certificate: 'disjoint' must list pairs of h-set names, got {pair!r}")
        if not hsets_disjoint(sets[pair[0]], sets[pair[1]]):
            return fail(f"the h-sets {pair[0]} and {pair[1]} are not proved disjoint")
    m = cert["method"]
    prec, delta = int(m["prec"]), _read_exact(m["delta"], "method.delta")
    log = logging.getLogger(__name__)
    jobs = [(params, levels, sets[r.source], sets[r.target], r, prec, delta) for r in rels]
    got: Dict[int, Any] = {}  # independent relations, in worker processes if workers > 1; the verdict is the same
    run_jobs(_check_one, jobs, workers, lambda k, res: got.setdefault(k, res).proved)
    results = [got[k] for k in sorted(got)]
    child_cpu = sum(res.cpu_seconds for res in results) if workers > 1 and len(jobs) > 1 else 0.0
    for k, res in enumerate(results):
        log.info("covering relation %d/%d: %s [%.1f CPU s]", k + 1, len(rels), res.message, res.cpu_seconds)
        if not res.proved:
            return CheckResult(False, res.message, time.process_time() - cpu0 + child_cpu)
    return CheckResult(True, f"proved: {cert.get('title', '')} ({len(rels)} covering relations at {prec} bits)",
                       time.process_time() - cpu0 + child_cpu)


def _check_one(job: Tuple[Any, ...]) -> Any:
    """One covering relation (a worker's job): :func:`~taylorball.rigorous.covering.check_relation`."""
    from .covering import check_relation

    params, levels, N, M, r, prec, delta = job
    return check_relation(params, levels, N, M, r, prec=prec, delta=delta)


#: The Fig. 1 heteroclinic chain's design (:func:`taylorball.rigorous.search.fig1_heteroclinic_chain`):
#: the attempt of docs/rigorous.md.
FIG1_CHAIN: Dict[str, Any] = {"i_lo": -9, "i_hi": 10, "a_saddle": 1.5e-5, "s_mid": 3e-6, "b_min": 2e-7, "alpha": 1.6,
              "pieces": 2, "skew_deg": 10.0, "skew_pieces": 24}


def fig1_horseshoe_certificate(workers: int = 1) -> Dict[str, Any]:
    r"""The attempted horseshoe of the Fig. 1 M||gamma section map: covering relations along
    the heteroclinic cycle of its saddles at ``l = 0`` and ``l = pi`` (``N0 => N0``,
    ``Npi => Npi``, ``N0 => up-9 => ... => up10 => Npi``, ``Npi => down-9 => ... => down10 =>
    N0``) with the disjoint pairs the entropy argument needs (docs/rigorous.md). The h-sets
    come from :func:`taylorball.rigorous.search.fig1_heteroclinic_chain` with
    :data:`FIG1_CHAIN` (float64: not part of the proof). Not proved yet: the certificate
    returned records ``"proved": false`` and the first relation that fails (about 20 CPU
    minutes at 53 bits; ``workers`` processes share the relations)."""
    from ..paper import FIG1_LEVELS, fig1_params
    from .search import fig1_heteroclinic_chain

    d = fig1_heteroclinic_chain(**FIG1_CHAIN)
    rels = d["relations"]
    disjoint = []
    for chain, sad in (("up", "N0"), ("down", "Npi")):
        for other in [sad] + [f"{chain}{i}" for i in range(int(FIG1_CHAIN["i_lo"]), 0)]:
            disjoint.append([f"{chain}0", other])
    return covering_certificate(
        fig1_params(), FIG1_LEVELS, d["hsets"], rels, loops=d["loops"], paths=d["paths"], disjoint=disjoint,
        prec=53, workers=workers,
        title="Fig. 1 (M||gamma, a = (1, 2, 3), d = 4, Omega = 1/2; lambda = 2, h = 100): a horseshoe "
                       "of covering relations along the heteroclinic cycle of the saddles at l = 0 and l = pi")


# ---------------------------------------------------------------------------------------
# Tzenoff's case (I1 = I2) on a level where the validated steps are long
# ---------------------------------------------------------------------------------------
def tzenoff_ball() -> BallParams:
    r"""The dynamically symmetric ball of the scouted level (docs/rigorous.md, "Tzenoff's
    case on a tractable level"): ``I = (2, 2, 3)``, ``m = 7/2``, ``a = 1`` (``d = m a^2 =
    7/2``, the smallest ``d`` a body with these moments can have: ``I1 + I2 + I3 = 2 d``, its
    mass on the sphere, heavier at the equator), ``Omega = 3``."""
    return BallParams(inertia=(2.0, 2.0, 3.0), mass=3.5, radius=1.0, plane_rate=3.0)


def tzenoff_levels(h: float = -20.0) -> Any:
    """The scouted levels of :func:`tzenoff_ball`: ``C = 10, M_gamma = 6`` and ``h`` (-20:
    the saddle's level; -30: the elliptic orbit's)."""
    from ..levels import Levels

    return Levels(C=10.0, M_gamma=6.0, h=h)


#: The shipped certificates of :func:`tzenoff_ball`'s relative periodic orbits: name ->
#: (file, level h, float64 Newton seed (r1, r2), energy root K near which the candidate lies).
#: The seeds are the values ``tb.periodic_orbits(..., k_max=1)`` reported (they propose; the
#: proofs do not use them).
TZENOFF_ORBITS: Dict[str, Tuple[str, float, Tuple[float, float], float]] = {
    "saddle": ("tzenoff_d3.5_saddle_cert.json", -20.0, (-0.255048561, 0.0), 6.776545634),
    "elliptic": ("tzenoff_d3.5_elliptic_cert.json", -30.0, (-0.6190156203391771, 0.0), 4.892199108250734),
}
TZENOFF_SADDLE_CERT_NAME = TZENOFF_ORBITS["saddle"][0]
#: The Krawczyk boxes' half-width in ``(r1, r2)`` and the working precision (53 bits do not
#: hold over the saddle's return: its point map's enclosure grows to 4.8e-6).
TZENOFF_RADIUS, TZENOFF_PREC = 1e-13, 128


def tzenoff_certificate(which: str = "saddle", workers: int = 1) -> Dict[str, Any]:
    r"""A relative periodic orbit of the dynamically symmetric ball :func:`tzenoff_ball`: a
    fixed point of the 2D section map of ``(r1, r2)`` (one crossing of ``g = 0``), proved by
    :func:`taylorball.rigorous.proofs.krawczyk_periodic_orbit` (one segment; ``workers=2``
    runs the point map and the C^1 map in two processes) on the box of half-width
    :data:`TZENOFF_RADIUS` at :data:`TZENOFF_PREC` bits. ``which="saddle"``: on the level
    ``h = -20`` (a reflection saddle, multipliers about ``-3.451``, ``-0.290``, return time
    about 4.7065); ``"elliptic"``: on ``h = -30`` (trace about 1.064, return time about
    4.6304).

    The candidate is float64 Newton (:func:`taylorball.rigorous.search.newton_fixed_point`)
    from the seed of :data:`TZENOFF_ORBITS`; it proposes, the proof does not use it."""
    from ..charts import reduced_chart
    from .search import float_map, newton_fixed_point

    if which not in TZENOFF_ORBITS:
        raise UsageError(f"which must be one of {sorted(TZENOFF_ORBITS)}, got {which!r}")
    _, h, seed, K_near = TZENOFF_ORBITS[which]
    P, L = tzenoff_ball(), tzenoff_levels(h)
    p, _, _ = newton_fixed_point(P, L, seed, K_near=K_near)
    _, tau, x0 = float_map(P, L, p, K_near=K_near)
    K = float(reduced_chart(P, x0[None])["K"][0])
    return periodic_orbit_certificate(
        P, L, [[float(p[0]), float(p[1])]], TZENOFF_RADIUS, [K], [tau], prec=TZENOFF_PREC, kind="reduced",
        workers=workers,
        title=f"Tzenoff's case (I = (2, 2, 3), m = 7/2, a = 1, Omega = 3; C = 10, M_gamma = 6, h = {h:g}): "
              f"a relative periodic orbit ({which}), one crossing of g = 0, return time {tau:.6f}")
