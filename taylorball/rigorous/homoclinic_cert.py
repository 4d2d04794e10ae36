r"""Certificates of :mod:`taylorball.rigorous.homoclinic`: a transversal homoclinic point
(claim ``homoclinic_point``) or the local unstable manifold alone (claim
``local_unstable_manifold``) of a reversible planar map.

A certificate stores the map (``{"kind": "henon", "t": "p/q"}``, or the symmetric ball's
section map: parameters as exact rationals, the level, the energy root and return time near
the fixed point and one pair per iterate along the orbit, ``delta``, ``order``), the
precision, the frame (``center``, ``T``), the h-set's half-widths ``a``, ``b``, the cone
constant ``c``, the reversor (an integer 2 x 2 involution), and for a homoclinic point the
two unstable coordinates ``us``, the number of iterates ``n``, the number of ``pieces`` and
the claimed ``sides`` of ``Fix(R)`` of the two segments' images. Every number exact
(``float.hex``). :func:`taylorball.rigorous.certificates.check_certificate` re-runs the whole
proof from scratch and accepts only if it closes with the claimed sides.
"""

from __future__ import annotations

import time
from fractions import Fraction
from typing import Any, Dict, Optional, Sequence, Tuple

from ..errors import UsageError

__all__ = ["homoclinic_certificate", "henon_certificate", "henon_frame", "HENON_T", "HENON_PROOF",
           "tzenoff_local_manifold_certificate", "TZENOFF_FRAME", "TZENOFF_HSET", "SIGMA1"]

#: The Henon map's parameter of the shipped certificate (multipliers ``2 +- sqrt 3``).
HENON_T = Fraction(4)

_STATEMENT = {
    "homoclinic_point": (
        "f has a hyperbolic fixed point p, the unique fixed point in the h-set N = center + T ([-a, a] x [-b, b]), "
        "with R p = p; the points of N with a full backward orbit in N form a curve W^u_N in W^u(p), the graph "
        "over u of a 1/c-Lipschitz function; and f^n maps the arc of W^u_N between u = us[0] and us[1] across "
        "Fix(R), at a point q which is a homoclinic point of p (q in W^u(p), R q = q in W^s(p)), where W^u(p) "
        "and W^s(p) = R W^u(p) intersect transversally"),
    "local_unstable_manifold": (
        "f has a hyperbolic fixed point p, the unique fixed point in the h-set N = center + T ([-a, a] x [-b, b]), "
        "with R p = p; the points of N with a full backward orbit in N form a curve W^u_N in W^u(p), the graph "
        "over u of a 1/c-Lipschitz function (covering N => N, cone condition for Q = u^2 - c^2 s^2, expansion "
        "in the cone > 1)"),
}


def _ex(x: float) -> Dict[str, str]:
    from .certificates import _exact

    return _exact(float(x))


def _rd(d: Any, what: str) -> float:
    from .certificates import _read_exact

    return _read_exact(d, what)


def _map_json(f: Any) -> Dict[str, Any]:
    from .homoclinic_check import homoclinic_map_json

    return homoclinic_map_json(f)


def homoclinic_certificate(f: Any, frame: Any, a: float, b: float, cq: float, reversor: Sequence[Sequence[int]], *,
                           prec: int, us: Optional[Tuple[float, float]] = None, n: int = 0, pieces: int = 1,
                           title: str = "") -> Dict[str, Any]:
    """Run the proof (:func:`~taylorball.rigorous.homoclinic.prove_homoclinic_point`, or only
    :func:`~taylorball.rigorous.homoclinic.local_unstable_manifold` when ``us`` is None) and
    return its certificate (``"proved": false`` with the reason if it does not close)."""
    from ._balls import working_precision
    from .certificates import FORMAT
    from .homoclinic import local_unstable_manifold, prove_homoclinic_point

    claim = "local_unstable_manifold" if us is None else "homoclinic_point"
    cpu0 = time.process_time()
    with working_precision(prec):
        if us is None:
            man = local_unstable_manifold(f, frame, a, b, cq, reversor=reversor)
            proved, message, sides = man.ok, man.message, []
        else:
            r = prove_homoclinic_point(f, frame, a, b, cq, us, n, reversor, pieces=pieces)
            proved, message, sides = r.proved, r.message, r.sides
    cert: Dict[str, Any] = {
        "format": FORMAT, "claim": claim, "title": title, "statement": _STATEMENT[claim], "map": _map_json(f),
        "prec": prec, "frame": {"center": [_ex(v) for v in frame.center], "T": [[_ex(v) for v in r] for r in frame.T]},
        "a": _ex(a), "b": _ex(b), "c": _ex(cq), "reversor": [[int(v) for v in r] for r in reversor]}
    if us is not None:
        cert.update({"us": [_ex(u) for u in us], "n": n, "pieces": pieces, "sides": sides})
    cert.update({"proved": proved, "message": message, "proved_cpu_seconds": round(time.process_time() - cpu0, 2),
                 "proved_on": time.strftime("%Y-%m-%d", time.gmtime())})
    steps = getattr(f, "steps", None)
    if steps:
        cert["validated_steps"] = steps
    return cert


def henon_frame() -> Any:
    """The eigen-frame of the Henon map :data:`HENON_T` at the origin (unit eigenvectors,
    rounded to floats: any invertible ``T`` is valid, these make the cone narrow)."""
    import math

    from .homoclinic import Frame

    t = float(HENON_T)
    lam = (t + math.sqrt(t * t - 4)) / 2
    nu, ns = math.hypot(1, lam), math.hypot(1, 1 / lam)
    return Frame((0.0, 0.0), ((1 / nu, 1 / ns), (lam / nu, 1 / (lam * ns))))


#: The Henon certificate's numbers: ``a, b, c``, the bracket ``us`` (around the float64
#: root ``u = -0.0056869241877`` of ``x - y`` on ``f^6`` of the unstable eigen-line), ``n``.
HENON_PROOF = {"a": 1e-2, "b": 3e-4, "c": 100.0, "us": (-0.0057169241877, -0.0056569241877), "n": 6, "pieces": 16}


def henon_certificate() -> Dict[str, Any]:
    """A transversal homoclinic point of the area-preserving Henon map
    ``f(x, y) = (y, -x + 4 y + y^2)`` (a known answer; milliseconds at 53 bits)."""
    from .homoclinic import HenonMap

    h = HENON_PROOF
    return homoclinic_certificate(
        HenonMap(HENON_T), henon_frame(), h["a"], h["b"], h["c"], [[0, 1], [1, 0]], prec=53,  # type: ignore[arg-type]
        us=h["us"], n=h["n"], pieces=h["pieces"],  # type: ignore[arg-type]
        title="the area-preserving Henon map f(x, y) = (y, -x + 4 y + y^2), reversible with R(x, y) = (y, x), has a "
              "transversal homoclinic point of its saddle (0, 0) on the line x = y (near (-2.6365, -2.6365))")


#: The frame of the Tzenoff saddle's h-set: the centre of the saddle's certificate box and the
#: unit eigenvectors of the float64 central-difference ``DP`` there (``-3.45114``: unstable,
#: ``-0.28976``: stable; mirror images under ``(r1, r2) -> (r1, -r2)``). A floating-point
#: search proposes them; any invertible ``T`` is valid for the proof.
TZENOFF_FRAME = ((-0.25504856114976504, -2.2117269935563355e-16),
                 ((-0.7889362495820125, 0.7889362588402167), (0.6144750557146064, 0.6144750438278213)))
#: ``a, b, c`` of the Tzenoff h-set (its box hull lies inside the saddle certificate's box of
#: half-width 1e-13) and the reversor ``sigma_1`` of the chart.
TZENOFF_HSET = {"a": 6e-14, "b": 6e-14, "c": 10.0}
SIGMA1 = [[1, 0], [0, -1]]


def tzenoff_local_manifold_certificate(a: Optional[float] = None, b: Optional[float] = None,
                                       cq: Optional[float] = None) -> Dict[str, Any]:
    r"""The local unstable manifold of the proved Tzenoff saddle
    (:func:`taylorball.rigorous.certificates.tzenoff_certificate`, level ``h = -20``) as a
    fixed point of the 2D section map ``F`` itself (multipliers ``-3.451``, ``-0.290``: the
    covering may reverse the exit edges): covering, cone condition and expansion on the
    h-set :data:`TZENOFF_FRAME` ``+-`` (``a``, ``b``) at 128 bits (the point map at the centre
    and the C^1 map on the h-set's box hull, ~350 CPU s). The energy root and return time
    are the saddle certificate's (they place the interval Newton boxes)."""
    from .certificates import CERT_DIR, TZENOFF_PREC, load_certificate, tzenoff_ball, tzenoff_levels
    from .homoclinic import Frame, SectionBallMap

    h = TZENOFF_HSET
    a, b, cq = (h["a"] if a is None else a), (h["b"] if b is None else b), (h["c"] if cq is None else cq)
    sc = load_certificate(CERT_DIR / "tzenoff_d3.5_saddle_cert.json")
    f = SectionBallMap(tzenoff_ball(), tzenoff_levels(-20.0), _rd(sc["K_guesses"][0], "K"),
                       _rd(sc["tau_guesses"][0], "tau"), prec=TZENOFF_PREC)
    frame = Frame(TZENOFF_FRAME[0], TZENOFF_FRAME[1])
    return homoclinic_certificate(
        f, frame, a, b, cq, SIGMA1, prec=TZENOFF_PREC,
        title="Tzenoff's case (I = (2, 2, 3), m = 7/2, a = 1, Omega = 3; C = 10, M_gamma = 6, h = -20): the local "
              f"unstable manifold of the saddle of the section map (r1, r2) near (-0.255049, 0) is a "
              f"1/{cq:g}-Lipschitz graph over |u| <= {a:g} in its eigen-frame, and the saddle is fixed by the "
              "reversor (r1, r2) -> (r1, -r2)")
