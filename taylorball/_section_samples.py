r"""Crossings of the paper's section ``g = g0`` from the run's sample grid, without the
section's event during the run (``sections_method = "samples"`` of
:class:`taylorball.observables.Sections`).

The section event ``e = (num cos g0 - den sin g0) / C^2`` (:func:`taylorball.charts.section_event_function`)
and the branch function ``b = num sin g0 + den cos g0`` (a crossing of ``g = g0``, not
``g0 + pi``, has ``b > 0``) are replaced between two consecutive samples ``t_j``,
``t_j + h`` by their quintic Hermite interpolants ``p(s)``, ``s = (t - t_j) / h``
(values and first two time derivatives along the flow at both samples,
:func:`section_jets`; the polynomial of :func:`taylorball._angle_lift.hermite_coefficients`).
``margin`` is, as for the lifted angle (:func:`taylorball._angle_lift.interval_margins`), ``E_SAFETY`` times
the interpolation error estimated from the change of the interpolant's fifth-degree
coefficient between neighbouring intervals plus a rounding term; the interpolant of
``de/ds`` is given ``DERIV_FACTOR`` times that margin (the error term of Hermite
interpolation, ``h^6 e^(6) s^3 (1 - s)^3 / 720``, has a derivative in ``s`` at most 3.43
times its maximum). The tests use the Bernstein coefficients ``beta_0 .. beta_5`` of the
polynomial on the interval (or piece), whose convex hull holds it (``beta_0``, ``beta_5``
are its end values), and those of its derivative, ``5 (beta_(i+1) - beta_i)``. Each
interval is:

1. **without an upward crossing**, if every ``beta_i`` is above ``margin`` (or every one
   below ``-margin``): the orbit's ``e`` stays off 0; or if the derivative's coefficients
   are all below ``-margin`` of ``de/ds`` (the orbit's ``e`` decreases), or all above it
   while ``e`` starts above 0 or ends below 0;
2. **with exactly one upward crossing**, if ``e`` goes from below 0 to above 0 (at a
   whole interval's ends the samples' own values; at a piece's by more than ``margin``)
   and the derivative's coefficients are all above its margin (the orbit's ``e``
   increases). Its time is the interpolant's root (Newton from the chord's root); it is
   on the branch if ``b``'s interpolant there is farther from 0 than ``b``'s margin plus
   ``b``'s possible change over the root's uncertainty (``margin`` over the least slope),
   else the interval is undecided;
3. **cut into quarters** (down to ``4**-PIECE_LEVELS`` of it; each piece's polynomial
   re-expanded, the same tests on each) if neither; **undecided** if a piece still does
   not pass (a crossing near a tangency of the orbit with the section, a sample within the
   margin of it, the start of an orbit): the interval is integrated again from its first
   sample's state with a scalar integrator carrying the event method's section event
   (:func:`reintegrate`), whose crossings count.

The counted crossings thin the records exactly as the event method does (every
``every``-th crossing on the branch, by the running count); the interval of a crossing
that is recorded is integrated again in the same way, and the record is that
integration's crossing: heyoka's root, Newton-refined in time as by the event method's
collector. The record's steps are not the run's (a new integration from the sample's
state), so times and states differ from the event method's by the integration's
rounding (measured in ``tests/test_section_samples.py``); which crossings are recorded
rests on the interpolation error estimate (not a proof). A re-integration that finds another count of
crossings on the branch than the interpolant's certified one raises
:class:`SectionSamplesError` (the estimate was wrong there; the event method is the
remedy) rather than recording a wrong thinning.

The edges of a chunk: a crossing at a sample time exactly belongs to the interval it ends
(``t_j < t <= t_j + h``); one within rounding of a sample time is found by the
re-integration of the interval whose sample is within the margin of it, which is
undecided, or by neither if heyoka places it just past the end of the interval it
integrates (a crossing within ~1e-15 of a sample time; not observed).
"""

from __future__ import annotations

import math
from typing import Any, Callable, Dict, List, Tuple

import numpy as np

from ._angle_lift import hermite_coefficients, interval_margins, quarters, reexpand
from ._cfunc_columns import along_flow, cfunc_columns
from .errors import IntegrationError

__all__ = ["section_jets", "classify", "reintegrate", "crossings", "SectionSamplesError", "DERIV_FACTOR"]

#: Factor on the margin of ``e`` for the margin of its derivative ``de/ds`` (module notes).
DERIV_FACTOR = 4.0
#: Levels of quartering of an interval the whole-interval tests leave open (pieces down to
#: ``4**-PIECE_LEVELS`` of it) before it is integrated again.
PIECE_LEVELS = 2
#: Intervals starting before this time are integrated again (the start of an orbit on the
#: section: a root within ``START_TOL`` of ``t = 0`` is no crossing, as in the event method).
_NEAR_START = 1e-6
#: Monomial to Bernstein coefficients of a quintic on ``[0, 1]``: ``beta_i = sum_k C(i, k) / C(5, k) a_k``.
_BERNSTEIN = np.array([[math.comb(i, k) / math.comb(5, k) if k <= i else 0.0 for k in range(6)] for i in range(6)])

class SectionSamplesError(IntegrationError):
    """A re-integrated interval disagrees with the interpolant's certified crossing count."""


def section_jets(prob: Any, g0: float) -> Callable[[np.ndarray], np.ndarray]:
    """Compiled float64 ``internal states (n, dim) -> (6, n)``: ``e``, ``b`` (module
    notes), their first and their second time derivatives along the problem's vector field
    (heyoka's symbolic differentiation); cached per system, formulation and ``g0``."""
    from ._chart_reduced import g_angle_parts, section_event_function

    system = prob.system

    def graph():
        import heyoka as hy

        xs = hy.make_vars(*system.internal_names)
        rhs = [f for _, f in system.equations()]
        ddt = along_flow(xs, rhs)
        e = section_event_function(xs[0:3], xs[3:6], g0)
        num, den = g_angle_parts(xs[0:3], xs[3:6])
        b = num * math.sin(g0) + den * math.cos(g0)
        de, db = ddt(e), ddt(b)
        return [e, b, de, db, ddt(de), ddt(db)], xs

    cf = cfunc_columns(("cfunc", "section jets", system.kind, system.formulation, float(g0)), graph,
                       compact_mode=True)
    p = np.asarray(prob.pars, dtype=float)

    def evaluate(X: np.ndarray) -> np.ndarray:
        return cf(np.asarray(X).astype(float), p)

    return evaluate


def _margins(J: np.ndarray, a: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Per component (``e``, ``b``; ``(2, m)``) the lifted angle's margin of each interval
    (:func:`taylorball._angle_lift.interval_margins`), the rounding from each component's
    own jets."""
    a5 = a[5]  # (2, m)
    hm = float(np.max(h))
    scale = np.array([1.0, hm, hm * hm])
    size = 2 * np.sum(np.max(np.abs(J), axis=1).reshape(3, 2) * scale[:, None], axis=0)  # (2,)
    return interval_margins(np.abs(np.diff(a5, axis=1)), np.abs(a5), size[:, None])


def _poly(c: np.ndarray, s: np.ndarray) -> np.ndarray:
    out = c[-1] * np.ones_like(s)
    for k in range(c.shape[0] - 2, -1, -1):
        out = out * s + c[k]
    return out


def _test_pieces(c: np.ndarray, me: np.ndarray, mb: np.ndarray, w: np.ndarray,
                 exact_ends: bool) -> np.ndarray:
    """Pieces with coefficients ``c`` (``(6, 2, p)``: ``e`` and ``b`` re-expanded on
    ``u in [0, 1]``, a piece of width ``w`` of its interval), margins ``me``, ``mb`` of
    their intervals: the upward crossings on the branch of each piece (0 or 1) where the
    tests decide it, else -1 (module notes). ``exact_ends``: the piece is a whole interval,
    whose ends are the samples' own values (no margin at the ends)."""
    q, qb = c[:, 0], c[:, 1]
    beta = _BERNSTEIN @ q  # the polynomial lies in the hull of these (convex hull property)
    d = 5.0 * np.diff(beta, axis=0)  # Bernstein coefficients of dq/du
    md = DERIV_FACTOR * me * w  # the margin of de/ds, in units of u
    up, down = np.min(d, axis=0) > md, np.max(d, axis=0) < -md
    q0, q1 = beta[0], beta[5]
    em = 0.0 if exact_ends else me
    # no upward crossing: e stays off 0 by more than the margin, or the orbit's e decreases, or
    # it increases from above 0 or to below 0
    none = (np.min(beta, axis=0) > me) | (np.max(beta, axis=0) < -me) | down | (up & ((q0 > em) | (q1 < -em)))
    out = np.where(none, 0, -1).astype(np.int64)
    idx = np.flatnonzero(up & (q0 < -em) & (q1 > em))
    if idx.size:
        ce = q[:, idx]
        cd = ce[1:] * np.arange(1, 6)[:, None]
        r = np.clip(q0[idx] / (q0[idx] - q1[idx]), 0.0, 1.0)  # the chord's root
        for _ in range(8):  # Newton on the increasing interpolant
            r = np.clip(r - _poly(ce, r) / _poly(cd, r), 0.0, 1.0)
        # the orbit's root is within me / (its least slope) of the interpolant's; b's change over that
        du = me[idx] / (np.min(d[:, idx], axis=0) - md[idx])
        slope_b = np.max(np.abs(np.diff(_BERNSTEIN @ qb[:, idx], axis=0)), axis=0) * 5.0
        bq = _poly(qb[:, idx], r)
        decided = np.abs(bq) > mb[idx] + slope_b * du
        out[idx[decided]] = (bq[decided] > 0).astype(np.int64)
    return out


def classify(J: np.ndarray, h: np.ndarray, near_start: np.ndarray) -> Tuple[np.ndarray, Dict[str, int]]:
    """Per sample interval of the jets ``J`` (``(6, n)``, :func:`section_jets`) and lengths
    ``h``: the count of upward crossings on the branch where the interpolant decides it,
    -1 where it does not (to be integrated again; also where ``near_start``); and how many
    intervals each stage decided (``whole``, ``pieces``, ``undecided``). An interval the
    whole-interval tests leave open is cut into quarters, sixteenths, ... (down to
    ``4**-PIECE_LEVELS`` of it), each piece tested alike."""
    m = J.shape[1] - 1
    a = hermite_coefficients(J[0:2, :-1], J[2:4, :-1], J[4:6, :-1], J[0:2, 1:], J[2:4, 1:], J[4:6, 1:],
                             h[None, :])  # (6, 2, m)
    mar = _margins(J, a, h)
    me, mb = mar[0], mar[1]
    count = _test_pieces(a, me, mb, np.ones(m), exact_ends=True)
    count[near_start] = -1
    todo = np.flatnonzero((count < 0) & ~near_start)
    stats = {"whole": m - int(np.count_nonzero(count < 0)), "pieces": 0, "undecided": 0}
    # pieces [lo, lo + w] of the open intervals, quartered until they pass (as for the lifted angle)
    idx, lo, w = todo, np.zeros(todo.size), np.ones(todo.size)
    total = np.zeros(m, dtype=np.int64)
    failed = np.zeros(m, dtype=bool)
    for _ in range(PIECE_LEVELS):
        if idx.size == 0:
            break
        idx, lo, w = quarters(idx, lo, w)
        got = _test_pieces(reexpand(a[:, :, idx], lo, w), me[idx], mb[idx], w, exact_ends=False)
        ok = got >= 0
        np.add.at(total, idx[ok], got[ok])
        idx, lo, w = idx[~ok], lo[~ok], w[~ok]
    failed[idx] = True
    decided = todo[~failed[todo]]
    count[decided] = total[decided]
    stats["pieces"] = int(decided.size)
    stats["undecided"] = int(np.count_nonzero(count < 0))
    return count, stats


def reintegrate(ta: Any, x0: Any, t0: Any, t1: Any) -> List[Tuple[Any, np.ndarray]]:
    """The section's crossings ``(t, internal state)`` in ``(t0, t1]`` of a scalar
    integration from ``x0`` at ``t0`` by ``ta`` (times in its number type; an integrator carrying the section's
    event with its collector, :meth:`taylorball.sections.Section.event`; its parameters
    set by the caller), as the event method's collector records them (every root, on the
    branch or not)."""
    cb = ta.nt_events[0].callback
    cb.clear()
    ta.state[:] = x0
    ta.time = t0
    ta.propagate_until(t1)
    lo, hi = float(t0), float(t1)
    out = [(t, x) for t, x in zip(cb.times, cb.states) if lo < float(t) <= hi]
    cb.clear()
    return out


def crossings(prob: Any, section: Any, t: np.ndarray, X: np.ndarray, n0: int,
              every: int) -> Tuple[List[Tuple[Any, np.ndarray]], int, int]:
    """The crossings of one chunk (grid ``t``, internal states ``X``) that the section
    observable records, given the orbit's running count ``n0`` of crossings on the branch
    and the thinning ``every``: ``(records, crossings on the branch in the chunk,
    intervals integrated again)``. ``section``: the :class:`taylorball.sections.Section`."""
    from ._cache import working_copy
    from ._propagate import integrator
    from .sections import START_TOL

    t = np.asarray(t, dtype=float)
    g0 = float(section.g0)
    J = section_jets(prob, g0)(X)
    h = np.diff(t)
    count, _ = classify(J, h, t[:-1] < _NEAR_START)
    undecided = np.flatnonzero(count < 0)
    template = integrator(prob, events_key=("observables", ("sections", g0, 1, "non-deferred")),
                          events=lambda: {"nt_events": [section.event()]})
    records: List[Tuple[Any, np.ndarray]] = []
    with working_copy(template) as ta:
        ta.pars[:] = prob.pars
        sc = float if prob.spec.name == "float" else prob.spec.scalar

        def on_branch(runs):  # the crossings on the branch after START_TOL, of each run, by one branch test
            flat = [r for recs in runs for r in recs]
            keep = section.on_branch([x for _, x in flat]) if flat else []
            ok = iter([bool(k) and float(r[0]) > START_TOL for r, k in zip(flat, keep)])
            return [[r for r in recs if next(ok)] for recs in runs]

        again = dict(zip(undecided.tolist(), on_branch([reintegrate(ta, X[j], sc(t[j]), sc(t[j + 1]))
                                                         for j in undecided])))
        for j, recs in again.items():
            count[j] = len(recs)
        total = int(count.sum())
        # the recorded ones: the crossings whose running index is a multiple of every
        first = np.concatenate([[0], np.cumsum(count)])[:-1] + n0  # running index of each interval's first
        has = (first + count - 1) // every - (first - 1) // every > 0
        picked = np.flatnonzero((count > 0) & has).tolist()
        need = [j for j in picked if j not in again]  # their intervals, integrated again for the records
        again.update(zip(need, on_branch([reintegrate(ta, X[j], sc(t[j]), sc(t[j + 1])) for j in need])))
        for j in picked:
            picks = [q for q in range(int(count[j])) if (first[j] + q) % every == 0]
            recs = again[j]
            if len(recs) != count[j]:
                raise SectionSamplesError(
                    f"sections_method = 'samples': the sample interval [{t[j]!r}, {t[j + 1]!r}] integrated again "
                    f"has {len(recs)} crossing(s) of the section's branch where its interpolant was certain of "
                    f"{int(count[j])}: the interpolation error estimate failed here; use sections_method = "
                    "'events' (or a smaller sample_dt) for this orbit")
            records.extend(recs[q] for q in picks)
    return records, total, int(undecided.size)
