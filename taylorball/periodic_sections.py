r"""The same periodic orbit on another section ``g = g0`` of the reduced system, and the
choice of that section.

:func:`section_windows` lists the sections an orbit crosses cleanly (away from the extremum
values of ``g``, where a pair of crossings appears or vanishes); :func:`on_section` solves the
orbit on one of them. :func:`crossing_transversality` and :func:`section_scan` measure how
the orbit crosses every section and how near it passes the chart's singular point ``M ||
e3``; :class:`SectionSwitch` holds the thresholds by which
:func:`taylorball.periodic_continuation.continue_arclength` leaves a section that degrades
(docs/skeleton.md, "Continuation that switches sections").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np
from numpy.typing import ArrayLike

from ._problem import Problem
from ._propagate import internal_f64
from .errors import IntegrationError, StateError, UsageError
from .levels import Levels
from .periodic import PeriodicOrbit, _eval_geo, _f64

__all__ = ["section_windows", "on_section", "crossing_transversality", "SectionScan", "section_scan",
           "SectionSwitch", "chart_regularity"]

# ---------------------------------------------------------------------------------------
# The same orbit on another section g = g0.
# ---------------------------------------------------------------------------------------
def _g_along(prob, state, ts: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Along the orbit from the public ``state`` at times ``ts``: the internal states
    (float64), the chart angle ``g = atan2(num, den)`` (wrapped) and the chart's regularity
    ``sqrt(num^2 + den^2) / C^2`` (0 where ``M`` passes along the body axis 3)."""
    from ._propagate import propagate

    Xi = internal_f64(prob, np.asarray(propagate(prob, state, ts), dtype=float))
    num, den, rho = _chart_parts(Xi)
    return Xi, np.arctan2(num, den), rho


def _chart_parts(Xi: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(num, den, regularity)`` of internal rows: ``g = atan2(num, den)`` and the chart's
    regularity ``sqrt(num^2 + den^2) / C^2`` (0 where ``M`` lies along the body axis 3)."""
    from ._chart_reduced import g_angle_parts

    num, den = g_angle_parts(tuple(Xi[:, 0:3].T), tuple(Xi[:, 3:6].T))
    return num, den, np.hypot(num, den) / np.sum(Xi[:, 0:3] ** 2, axis=1)


def chart_regularity(prob: Problem, states: ArrayLike) -> np.ndarray:
    r"""The chart's regularity ``sqrt(num^2 + den^2) / C^2`` (``g = atan2(num, den)``) at
    public states of the reduced system (rows): 1 far from the chart's singular point, 0 where
    ``M`` lies along the body axis 3 and ``l, g`` are undefined. On the Fig. 4a level, of the
    8000 section points of 40 orbits of 200 crossings, 0.7 % had regularity below 0.1 (the
    least 2.7e-4; docs/skeleton.md, "Segments chosen automatically")."""
    X = np.atleast_2d(np.asarray(states, dtype=float))
    return _chart_parts(internal_f64(prob, X))[2]


def _extremum_values(g: np.ndarray) -> np.ndarray:
    """The local extremum values of the unwrapped ``g`` samples, mod ``2 pi``."""
    dg = np.diff(g)
    ext = np.where(np.sign(dg[1:]) != np.sign(dg[:-1]))[0] + 1
    return np.mod(g[ext], 2 * np.pi)


def _crossings_and_margin(g: np.ndarray, ev: np.ndarray, g0: float) -> Tuple[np.ndarray, np.ndarray, float]:
    """For the section ``g = g0`` and the unwrapped samples ``g``: the sample indices ``i``
    with an increasing crossing between ``i`` and ``i + 1``, ``sin(g - g0)`` at the samples,
    and the distance of ``g0`` from the extremum values ``ev``."""
    s, c = np.sin(g - g0), np.cos(g - g0)
    idx = np.where((s[:-1] < 0) & (s[1:] >= 0) & (c[1:] > 0))[0]
    margin = float(np.min(np.abs(np.angle(np.exp(1j * (ev - g0)))))) if len(ev) else float(np.pi)
    return idx, s, margin


def section_windows(orbit: PeriodicOrbit, *, n_samples: int = 20000, step: float = 0.01) -> np.ndarray:
    r"""How the orbit crosses each section ``g = g0`` (reduced system): rows
    ``(g0, crossings, margin)`` for ``g0`` on a grid of ``step`` in ``[0, 2 pi)``.

    ``crossings`` counts the increasing crossings of ``g = g0`` per period (the ``k`` of
    the orbit as a fixed point of that section's map); ``margin`` is the distance of ``g0``
    from every local extremum value of ``g`` along the orbit (mod ``2 pi``): near an
    extremum value the crossing grazes the section and the count changes with the
    parameters, where continuation on that section stalls. From a propagation sampled at
    ``n_samples`` points over one period; a ``UsageError`` if ``g`` changes by more than
    ``pi/2`` between two samples (near ``M || e3``, where ``g`` is undefined, it turns
    fast). The counts are of the samples: :func:`on_section` confirms a choice.
    """
    prob = orbit.problem
    if prob is None or prob.kind != "reduced":
        raise UsageError("section_windows takes a PeriodicOrbit of kind='reduced'")
    if not isinstance(n_samples, (int, np.integer)) or n_samples < 100:
        raise UsageError(f"n_samples must be an integer >= 100, got {n_samples!r}")
    # one period exactly, the grid offset by half a step (no sample on the orbit's own section)
    ts = float(orbit.period) * (np.arange(int(n_samples) + 1) + 0.5) / int(n_samples)
    g = np.unwrap(_g_along(prob, orbit.state, ts)[1])
    dg = np.diff(g)
    if float(np.max(np.abs(dg))) > 0.5 * np.pi:
        raise UsageError(f"g changes by {float(np.max(np.abs(dg))):.2f} between two samples (the orbit passes near "
                         f"the chart's singular point M || e3): n_samples = {n_samples} is too small to count "
                         f"crossings")
    ev = _extremum_values(g)
    rows = []
    for g0 in np.arange(0.0, 2 * np.pi, float(step)):
        idx, _, margin = _crossings_and_margin(g, ev, g0)
        rows.append((float(g0), len(idx), margin))
    return np.array(rows)


def on_section(orbit: PeriodicOrbit, g0: float, *, levels: Optional[Levels] = None) -> PeriodicOrbit:
    r"""The same (relative) periodic orbit as a fixed point of the map of the section ``g = g0``.

    The section integrator runs from ``orbit.state`` to its first crossing of ``g = g0`` and
    counts the increasing crossings over one period from there (``k``); Newton
    (:func:`taylorball.periodic_orbit`) solves again from that state with that ``k`` and
    the orbit's shift. The multipliers are those of a conjugate map (the same), the period
    the same.

    Raises
    ------
    IntegrationError
        If the orbit does not cross ``g = g0``, or Newton converged to an orbit of another
        period (by more than 1e-9 relative).
    """
    from .periodic import NewtonOptions, periodic_orbit
    from .sections import poincare_section

    prob = orbit.problem
    if prob is None:
        raise UsageError("on_section takes a PeriodicOrbit from periodic_orbit")
    T = float(orbit.period)
    first = poincare_section(prob, orbit.state, n_points=1, g0=float(g0), t_end=1.01 * T,
                             direction=1 if orbit.direction == 1 else -1)
    if not len(first.states):
        raise IntegrationError(f"the orbit does not cross the section g = {g0!r} in one period")
    run = poincare_section(prob, first.states[-1], n_points=4096, g0=float(g0), t_end=T * (1 + 1e-6),
                           direction=1 if orbit.direction == 1 else -1)
    k = int(sum(1 for t in run.times if 1e-6 < float(t) <= T * (1 + 1e-6)))
    if k < 1:
        raise IntegrationError(f"the orbit does not come back to the section g = {g0!r} within its period")
    o = periodic_orbit(prob, state=first.states[-1], k=k, g0=float(g0), direction=orbit.direction,  # type: ignore[arg-type]
                       levels=levels, options=NewtonOptions(shift=orbit.shift if orbit.shift else None))
    if abs(o.period - T) > 1e-9 * T:
        raise IntegrationError(f"Newton on g = {g0!r} found an orbit of period {o.period!r}, not {T!r}")
    return o


# ---------------------------------------------------------------------------------------
# Automatic section switching: transversality of the crossings, regularity of the chart.
# ---------------------------------------------------------------------------------------
def crossing_transversality(orbit: PeriodicOrbit) -> np.ndarray:
    r"""How transversally the orbit crosses its own section: at each of its ``k`` crossings
    ``|de/dt| / (|grad e| |f|)`` (the cosine of the angle between the flow ``f`` and the
    section's normal; 1 for a perpendicular crossing, 0 for a tangency).

    Newton's Jacobian carries :math:`\Pi = I - f\,\nabla e^T/(\nabla e\cdot f)`, which grows
    like the inverse of this number: a continuation on a section the orbit starts to graze
    stalls (the Fig. 3 saddle branch on ``g = 0`` near ``Omega = 1.8897``). The crossing
    states are those of the section integrator run afresh from ``orbit.state``.
    """
    from ._propagate import start_state
    from .sections import poincare_section

    prob = orbit.problem
    if prob is None:
        raise UsageError("crossing_transversality takes a PeriodicOrbit from periodic_orbit")
    run = poincare_section(prob, orbit.state, n_points=orbit.k, g0=orbit.g0, t_end=1.01 * float(orbit.period),
                           direction=1 if orbit.direction == 1 else -1)
    out = []
    for s in run.states:
        x = prob.spec.array(_f64(start_state(prob, s, project_state=True)))
        geo = _eval_geo(prob, orbit.g0, x)
        ge, f = _f64(geo.grad_e), _f64(geo.f)
        out.append(abs(float(np.dot(ge, f))) / (float(np.linalg.norm(ge)) * float(np.linalg.norm(f))))
    if len(out) < orbit.k:
        raise IntegrationError(f"the orbit crossed g = {orbit.g0!r} only {len(out)} times in 1.01 periods, not "
                               f"k = {orbit.k}")
    return np.array(out)


@dataclass(frozen=True)
class SectionScan:
    r"""How an orbit of the reduced system crosses every section ``g = g0`` (:func:`section_scan`).

    Attributes
    ----------
    g0 : ndarray
        The grid of sections in ``[0, 2 pi)``.
    crossings : ndarray of int
        Increasing crossings per period (the orbit's ``k`` on that section).
    margin : ndarray
        Distance of ``g0`` from every local extremum value of ``g`` (as :func:`section_windows`).
    transversality : ndarray
        The least ``|de/dt| / (|grad e| |f|)`` over the increasing crossings (at the nearest
        sample; ``nan`` where there is none).
    chart : float
        ``min sqrt(num^2 + den^2) / C^2`` along the orbit (``g = atan2(num, den)``): 0 where
        ``M`` passes along the body axis 3 and the chart angles ``l, g`` are undefined.
    flips : tuple of (float, float)
        One ``(g_start, delta)`` per close passage of the orbit by that singular point (a
        local minimum of the regularity below ``chart_window``), the closest first: over the passage's fast part
        ``g`` sweeps from ``g_start`` by ``delta`` (unwrapped, monotone). As the parameters
        carry ``M`` across the axis the sweep becomes ``delta -+ 2 pi``: the sections the
        sweep passes *decreasingly* (before or after) keep their count of increasing
        crossings, the others gain or lose one.
    unresolved : int
        Close passages whose sweep was not monotone on the fine samples (not judged).
    """

    g0: np.ndarray
    crossings: np.ndarray
    margin: np.ndarray
    transversality: np.ndarray
    chart: float
    flips: Tuple[Tuple[float, float], ...]
    unresolved: int = 0

    def flip_safe(self, g0: float, margin: float = 0.1, closest: Optional[int] = None) -> bool:
        """Whether the section ``g = g0`` keeps its count of increasing crossings when any of
        the orbit's close passages by ``M || e3`` (or only the ``closest`` ones) flips to the
        other side of the axis (``True`` without one)."""
        for gs, delta in self.flips[:closest]:
            # distance of g0 from g_start along the sweep's sense
            d = (float(g0) - gs) % (2 * np.pi) if delta > 0 else (gs - float(g0)) % (2 * np.pi)
            inside = margin < d < abs(delta) - margin
            outside = abs(delta) + margin < d < 2 * np.pi - margin
            if not (inside if delta < 0 else outside):
                return False
        return True


def section_scan(orbit: PeriodicOrbit, *, n_samples: int = 4000, step: float = 0.01,
                 chart_window: float = 0.02) -> SectionScan:
    r"""Every section ``g = g0`` (a grid of ``step``) as seen by the orbit: crossings,
    margin, transversality, and the orbit's passage near the chart's singular point.

    From a propagation of one period sampled at ``n_samples`` points (refined to 1001
    samples over each close passage by ``M || e3``, where the chart's regularity has a
    local minimum below ``chart_window``). Used by :func:`continue_arclength` (``switch=SectionSwitch()``) to
    choose a new section; :func:`on_section` confirms a choice.
    """
    prob = orbit.problem
    if prob is None or prob.kind != "reduced":
        raise UsageError("section_scan takes a PeriodicOrbit of kind='reduced'")
    if not isinstance(n_samples, (int, np.integer)) or n_samples < 100:
        raise UsageError(f"n_samples must be an integer >= 100, got {n_samples!r}")
    if not (isinstance(step, (int, float)) and 0 < step < 1):
        raise UsageError(f"step must be a float in (0, 1), got {step!r}")
    T = float(orbit.period)
    ts = T * (np.arange(int(n_samples) + 1) + 0.5) / int(n_samples)
    Xi, graw, rho = _g_along(prob, orbit.state, ts)
    chart = float(np.min(rho))
    flips: List[Tuple[float, float, float]] = []  # (closest regularity, g_start, delta)
    unresolved = 0
    # every close passage (a local minimum of rho below chart_window): the sweep of g over
    # its fast part (rho < 3 x its minimum), on 1001 fine samples
    for i in range(len(rho)):
        r = rho[i]
        if not (r < chart_window and (i == 0 or r <= rho[i - 1]) and (i == len(rho) - 1 or r <= rho[i + 1])):
            continue
        lo, hi = i, i
        while lo > 0 and rho[lo - 1] < 3 * r:
            lo -= 1
        while hi < len(rho) - 1 and rho[hi + 1] < 3 * r:
            hi += 1
        lo, hi = max(lo - 1, 0), min(hi + 1, len(rho) - 1)
        _, gf, rf = _g_along(prob, orbit.state, np.linspace(ts[lo], ts[hi], 1001))
        chart = min(chart, float(np.min(rf)))
        gu = np.unwrap(gf)
        dgf = np.diff(gu)
        if float(np.max(np.abs(dgf))) < 0.5 * np.pi and (np.all(dgf > 0) or np.all(dgf < 0)):
            flips.append((float(np.min(rf)), float(np.mod(gu[0], 2 * np.pi)), float(gu[-1] - gu[0])))
        else:
            unresolved += 1
    g = np.unwrap(graw)
    ev = _extremum_values(g)
    # gradients of e_{g0} = cos(g0) e_0 + sin(g0) e_{pi/2} and the field at every sample
    G0, Gp, F = [], [], []
    for x in Xi:
        xs = prob.spec.array(x)
        a, b = _eval_geo(prob, 0.0, xs), _eval_geo(prob, 0.5 * np.pi, xs)
        G0.append(_f64(a.grad_e))
        Gp.append(_f64(b.grad_e))
        F.append(_f64(a.f))
    G0a, Gpa, Fa = np.array(G0), np.array(Gp), np.array(F)
    fn = np.linalg.norm(Fa, axis=1)
    grid = np.arange(0.0, 2 * np.pi, float(step))
    cross = np.zeros(len(grid), dtype=int)
    marg = np.zeros(len(grid))
    trans = np.full(len(grid), np.nan)
    for j, g0 in enumerate(grid):
        idx, s, marg[j] = _crossings_and_margin(g, ev, g0)
        cross[j] = len(idx)
        if len(idx):
            near = np.where(np.abs(s[idx]) < np.abs(s[idx + 1]), idx, idx + 1)
            ge = np.cos(g0) * G0a[near] + np.sin(g0) * Gpa[near]
            de = np.abs(np.sum(ge * Fa[near], axis=1))
            trans[j] = float(np.min(de / (np.linalg.norm(ge, axis=1) * fn[near])))
    flips.sort()  # closest passage first
    return SectionScan(grid, cross, marg, trans, chart, tuple((a, b) for _, a, b in flips), unresolved)


@dataclass(frozen=True)
class SectionSwitch:
    r"""When and how :func:`continue_arclength` moves the branch to another section ``g = g0``.

    Attributes
    ----------
    min_transversality : float
        Switch when the least :func:`crossing_transversality` of the current orbit falls
        below this. Newton's Jacobian grows like its inverse; measured on the Fig. 3 saddle
        branch: 0.0014 on ``g = 0`` at ``Omega = 1.88679`` (steps already ~1e-5 there) and
        0 at 1.8900.
    accept_transversality : float
        A new section is taken only if the orbit crosses it at least this transversally
        (all ``k`` crossings; more than ``min_transversality``, so that the branch does not
        switch back at once).
    min_margin : float
        Switch when ``g0`` comes this close (radians) to a local extremum value of ``g``
        along the orbit: there a pair of crossings appears or vanishes and ``k`` changes.
        A new section must be at least ``4 min_margin`` from every extremum value.
    min_chart : float
        Switch, when the orbit passes this close to the chart's singular point ``M || e3``
        (:attr:`SectionScan.chart`), to a section whose count of increasing crossings the
        passage cannot change (:meth:`SectionScan.flip_safe`), unless the current one is.
    candidates : int
        Sections tried (largest margin first) before the switch is given up.
    n_samples : int
        Samples per period of :func:`section_scan`.
    """

    min_transversality: float = 0.005
    accept_transversality: float = 0.02
    min_margin: float = 0.02
    min_chart: float = 0.02
    candidates: int = 6
    n_samples: int = 4000

    def __post_init__(self) -> None:
        for name in ("min_transversality", "accept_transversality", "min_margin", "min_chart"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0 < v < 1):
                raise UsageError(f"SectionSwitch.{name} must be a float in (0, 1), got {v!r}")
        if self.accept_transversality <= self.min_transversality:
            raise UsageError(f"SectionSwitch.accept_transversality ({self.accept_transversality!r}) must exceed "
                             f"min_transversality ({self.min_transversality!r})")
        if not isinstance(self.candidates, int) or self.candidates < 1:
            raise UsageError(f"SectionSwitch.candidates must be an integer >= 1, got {self.candidates!r}")
        if not isinstance(self.n_samples, int) or self.n_samples < 100:
            raise UsageError(f"SectionSwitch.n_samples must be an integer >= 100, got {self.n_samples!r}")


def _chart_regularity(o: PeriodicOrbit, n_samples: int) -> Tuple[float, float]:
    """``min sqrt(num^2 + den^2) / C^2`` over ``n_samples`` samples of one period (cheap
    screen; :func:`section_scan` refines it near the minimum), and the margin of the
    orbit's own ``g0`` (its distance from every local extremum value of ``g``)."""
    from ._propagate import propagate

    ts = float(o.period) * (np.arange(int(n_samples) + 1) + 0.5) / int(n_samples)
    X = internal_f64(o.problem, np.asarray(propagate(o.problem, o.state, ts), dtype=float))  # internal (M, gamma, R)
    num, den, rho = _chart_parts(X)
    g = np.unwrap(np.arctan2(num, den))
    dg = np.diff(g)
    ext = np.where(np.sign(dg[1:]) != np.sign(dg[:-1]))[0] + 1
    ev = np.mod(g[ext], 2 * np.pi)
    margin = float(np.min(np.abs(np.angle(np.exp(1j * (ev - o.g0)))))) if len(ev) else float(np.pi)
    return float(np.min(rho)), margin


def _switch_reason(o: PeriodicOrbit, sw: SectionSwitch) -> Tuple[Optional[str], Optional[SectionScan], float]:
    """Why ``o`` should move to another section (or ``None``), the scan if one was made, and
    the orbit's least transversality."""
    tr = float(np.min(crossing_transversality(o)))
    if tr < sw.min_transversality:
        return f"transversality {tr:.3g} < {sw.min_transversality}", section_scan(o, n_samples=sw.n_samples), tr
    chart, margin = _chart_regularity(o, sw.n_samples)
    if margin < sw.min_margin:
        return (f"g0 = {o.g0} is {margin:.3g} from an extremum value of g (< {sw.min_margin}): a pair of "
                f"crossings is about to appear or vanish"), section_scan(o, n_samples=sw.n_samples), tr
    if chart < 2 * sw.min_chart:
        scan = section_scan(o, n_samples=sw.n_samples)
        # the closest passage decides (the next to flip); a switch prefers sections safe for all
        if scan.chart < sw.min_chart and not scan.flip_safe(o.g0, closest=1):
            return (f"chart regularity {scan.chart:.3g} < {sw.min_chart} and the passage near M || e3 would change "
                    f"the crossings of g0 = {o.g0}"), scan, tr
    return None, None, tr


def _switch(o: PeriodicOrbit, levels, scan: SectionScan, sw: SectionSwitch) -> Tuple[PeriodicOrbit, float]:
    """The orbit on the best new section (largest margin among the flip-safe ones with
    transversal crossings), and its least transversality."""
    ok = (scan.crossings >= 1) & np.isfinite(scan.transversality) & (scan.transversality >= sw.accept_transversality)
    ok &= np.abs(np.angle(np.exp(1j * (scan.g0 - o.g0)))) > 0.05
    ok &= scan.margin >= 4 * sw.min_margin
    safe_all = np.array([scan.flip_safe(g) for g in scan.g0])
    safe = safe_all if np.any(ok & safe_all) else np.array([scan.flip_safe(g, closest=1) for g in scan.g0])
    ok &= safe  # safe for every close passage, else (none is) for the closest one
    order = [int(i) for i in np.argsort(-scan.margin) if ok[i]][: sw.candidates]
    errors = []
    for i in order:
        g0 = float(np.round(scan.g0[i], 10))
        try:
            new = on_section(o, g0, levels=levels)
            tr = float(np.min(crossing_transversality(new)))
        except (IntegrationError, StateError) as exc:
            errors.append(f"g0 = {g0}: {exc}")
            continue
        if tr >= sw.accept_transversality:
            return new, tr
        errors.append(f"g0 = {g0}: transversality {tr:.3g}")
    raise StateError(f"no section to switch to among {len(order)} candidates ({'; '.join(errors)[:400]})")
