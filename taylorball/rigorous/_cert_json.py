r"""The exact JSON forms shared by every certificate kind: floats as ``float.hex`` strings (with
a decimal rendering for people), parameters as ``"p/q"`` rationals, levels, and the
checker's verdict :class:`CheckResult`. The writers and checkers
(:mod:`taylorball.rigorous.certificates`, :mod:`taylorball.rigorous.homoclinic_check`) build
on it; it imports none of them.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any, Dict

from ..errors import UsageError
from ..params import BallParams, MParallelParams

FORMAT = "taylorball-certificate/1"


def _exact(x: float) -> Dict[str, str]:
    x = float(x)
    return {"hex": x.hex(), "decimal": repr(x)}


def _read_exact(d: Any, what: str) -> float:
    try:
        return float.fromhex(d["hex"])
    except (TypeError, KeyError, ValueError):
        raise UsageError(f"certificate: {what} must be {{'hex': float.hex string, ...}}, got {d!r}") from None


def _rational(x: float) -> str:
    q = Fraction(float(x))
    return f"{q.numerator}/{q.denominator}"


def _params_json(params: Any) -> Dict[str, Any]:
    if isinstance(params, BallParams):
        return {"type": "BallParams", "inertia": [_rational(v) for v in params.inertia],
                "mass": _rational(params.mass), "radius": _rational(params.radius),
                "plane_rate": _rational(params.plane_rate)}
    if isinstance(params, MParallelParams):
        return {"type": "MParallelParams", "a": [_rational(v) for v in params.a], "d": _rational(params.d),
                "plane_rate": _rational(params.plane_rate)}
    raise UsageError(f"params must be BallParams or MParallelParams, got {params!r}")


def _exact_float(s: str, what: str) -> float:
    try:
        q = Fraction(s)
    except (TypeError, ValueError):
        raise UsageError(f"certificate: {what} must be an exact rational 'p/q', got {s!r}") from None
    if Fraction(float(q)) != q:
        raise UsageError(f"certificate: {what} = {s} is not a binary64 number; the checker takes exact floats")
    return float(q)


def _params_from_json(d: Dict[str, Any]) -> Any:
    if d.get("type") == "BallParams":
        i1, i2, i3 = (_exact_float(v, "inertia") for v in d["inertia"])
        return BallParams(inertia=(i1, i2, i3),
                          mass=_exact_float(d["mass"], "mass"), radius=_exact_float(d["radius"], "radius"),
                          plane_rate=_exact_float(d["plane_rate"], "plane_rate"))
    if d.get("type") == "MParallelParams":
        a1, a2, a3 = (_exact_float(v, "a") for v in d["a"])
        return MParallelParams(a=(a1, a2, a3), d=_exact_float(d["d"], "d"),
                               plane_rate=_exact_float(d["plane_rate"], "plane_rate"))
    raise UsageError(f"certificate: params.type must be 'BallParams' or 'MParallelParams', got {d.get('type')!r}")


def _levels_json(kind: str, levels: Any) -> Dict[str, Any]:
    if kind == "mparallel":
        return {"lam": _exact(levels.lam), "h": _exact(levels.h)}
    return {"C": _exact(levels.C), "M_gamma": _exact(levels.M_gamma), "h": _exact(levels.h)}


def _levels_from_json(kind: str, lv: Dict[str, Any]) -> Any:
    from ..levels import Levels, MParallelLevels

    if kind == "mparallel":
        return MParallelLevels(lam=_read_exact(lv["lam"], "levels.lam"), h=_read_exact(lv["h"], "levels.h"))
    return Levels(C=_read_exact(lv["C"], "levels.C"), M_gamma=_read_exact(lv["M_gamma"], "levels.M_gamma"),
                  h=_read_exact(lv["h"], "levels.h"))


class CheckResult:
    """The verdict of :func:`check_certificate`: ``ok`` and a message saying why."""

    def __init__(self, ok: bool, message: str, cpu_seconds: float) -> None:
        self.ok, self.message, self.cpu_seconds = ok, message, cpu_seconds

    def __bool__(self) -> bool:
        return self.ok

    def __repr__(self) -> str:
        return f"CheckResult(ok={self.ok}, message={self.message!r})"
