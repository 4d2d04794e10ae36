r"""The checker of the ``homoclinic_point`` and ``local_unstable_manifold`` certificates
(:mod:`taylorball.rigorous.homoclinic`; the writers are in
:mod:`taylorball.rigorous.homoclinic_cert`): the proof re-run from scratch from the
certificate's exact numbers, called by :func:`taylorball.rigorous.certificates.check_certificate`.
"""

from __future__ import annotations

import time
from fractions import Fraction
from typing import Any, Dict

from ..errors import UsageError
from ._cert_json import CheckResult, _exact, _levels_from_json, _levels_json, _params_from_json, _params_json, _read_exact

__all__ = ["check_homoclinic", "homoclinic_map_json"]


def homoclinic_map_json(f: Any) -> Dict[str, Any]:
    """The exact JSON form of a :class:`~taylorball.rigorous.homoclinic.HenonMap` or
    :class:`~taylorball.rigorous.homoclinic.SectionBallMap` (read back by
    :func:`_homoclinic_map_from_json`)."""
    from .homoclinic import HenonMap, SectionBallMap

    if isinstance(f, HenonMap):
        q = Fraction(f.t)
        return {"kind": "henon", "t": f"{q.numerator}/{q.denominator}"}
    if isinstance(f, SectionBallMap):
        return {"kind": "reduced", "params": _params_json(f.params), "levels": _levels_json("reduced", f.levels),
                "K_local": _exact(f.K_local), "tau_local": _exact(f.tau_local),
                "K_guesses": [_exact(v) for v in f.K_guesses], "tau_guesses": [_exact(v) for v in f.tau_guesses],
                "delta": _exact(f.delta), "order": f.order}
    raise UsageError(f"the map must be a HenonMap or a SectionBallMap, got {f!r}")


def _homoclinic_map_from_json(d: Dict[str, Any], prec: int) -> Any:
    from .homoclinic import HenonMap, SectionBallMap

    if d.get("kind") == "henon":
        try:
            return HenonMap(Fraction(d["t"]))
        except (KeyError, ValueError, ZeroDivisionError):
            raise UsageError(f"certificate: map.t must be an exact rational 'p/q', got {d.get('t')!r}") from None
    if d.get("kind") == "reduced":
        Ks = [_read_exact(v, "map.K_guesses") for v in d["K_guesses"]]
        ts = [_read_exact(v, "map.tau_guesses") for v in d["tau_guesses"]]
        if len(Ks) != len(ts):
            raise UsageError(f"certificate: map.K_guesses ({len(Ks)}) and map.tau_guesses ({len(ts)}) must match")
        order = d.get("order")
        return SectionBallMap(_params_from_json(d["params"]), _levels_from_json("reduced", d["levels"]),
                              _read_exact(d["K_local"], "map.K_local"), _read_exact(d["tau_local"], "map.tau_local"), Ks, ts,
                              prec=prec, order=None if order is None else int(order),
                              delta=_read_exact(d["delta"], "map.delta"))
    raise UsageError(f"certificate: map.kind must be 'henon' or 'reduced', got {d.get('kind')!r}")


def check_homoclinic(cert: Dict[str, Any], cpu0: float) -> Any:
    """Re-prove a ``homoclinic_point`` / ``local_unstable_manifold`` certificate from scratch."""
    from ._balls import working_precision
    from .homoclinic import Frame, SectionBallMap, local_unstable_manifold, prove_homoclinic_point

    def fail(msg: str) -> Any:
        return CheckResult(False, f"not proved: {msg}", time.process_time() - cpu0)

    claim = cert.get("claim")
    if not cert.get("proved", False):
        return fail("the certificate records a failed attempt")
    try:
        prec = int(cert["prec"])
        f = _homoclinic_map_from_json(cert["map"], prec)
        fr = cert["frame"]
        frame = Frame(tuple(_read_exact(v, "frame.center") for v in fr["center"]),  # type: ignore[arg-type]
                      tuple(tuple(_read_exact(v, "frame.T") for v in row) for row in fr["T"]))  # type: ignore[arg-type]
        a, b, cq = _read_exact(cert["a"], "a"), _read_exact(cert["b"], "b"), _read_exact(cert["c"], "c")
        R = [[int(v) for v in row] for row in cert["reversor"]]
        if claim == "homoclinic_point":
            us = tuple(_read_exact(v, "us") for v in cert["us"])
            n, pieces, sides = int(cert["n"]), int(cert["pieces"]), [int(s) for s in cert["sides"]]
    except (KeyError, TypeError, ValueError) as exc:
        raise UsageError(f"certificate: a field is missing or malformed ({exc!r})") from None
    if claim == "homoclinic_point" and isinstance(f, SectionBallMap) and len(f.K_guesses) < n:
        return fail(f"n = {n} iterates but only {len(f.K_guesses)} return-time guesses")
    with working_precision(prec):
        if claim == "local_unstable_manifold":
            man = local_unstable_manifold(f, frame, a, b, cq, reversor=R)
            if not man.ok:
                return fail(man.message.removeprefix("not proved: "))
            return CheckResult(True, f"proved: {cert.get('title', '')} ({man.message.removeprefix('proved: ')})",
                               time.process_time() - cpu0)
        r = prove_homoclinic_point(f, frame, a, b, cq, us, n, R, pieces=pieces)  # type: ignore[arg-type]
    if not r.proved:
        return fail(r.message)
    if r.sides != sides:
        return fail(f"the segments' images lie on the sides {r.sides} of Fix(R), the certificate claims {sides}")
    return CheckResult(True, f"proved: {cert.get('title', '')} ({r.message.removeprefix('proved: ')})",
                       time.process_time() - cpu0)
