r"""Precision study across number types: ``taylorball verify --precision``.

The same float64 initial condition is integrated by :func:`taylorball.propagate`'s
machinery (:func:`taylorball.make_integrator`) in float64, ``numpy.longdouble`` (x87, 64-bit
significand), ``heyoka.real128`` (113 bits) and ``heyoka.real`` with ``prec = 256`` (the
reference). Each number type projects the float64 numbers onto the constraint manifold in
its own working precision (:func:`taylorball._propagate.start_state`), so the runs differ
at ``t = 0`` only by that snap (of order the type's epsilon) and afterwards by the
integrator's rounding and truncation errors (tolerance = the type's epsilon).

What is measured, per reference orbit (:func:`~taylorball.verify.precision_orbits.reference_orbits`,
with the states on given levels they start from, in :mod:`taylorball.verify.precision_orbits`)
and number type:

* **digits** -- correct decimal digits of the state against the 256-bit run,

  .. math:: D(t) = -\log_{10} \max_g \max_{i \in g} \frac{|x_i(t) - x^{\rm ref}_i(t)|}{s_g},

  where ``g`` runs over the physical vectors of the layout (``omega``, ``alpha``, ``beta``,
  ``gamma``, the contact point ``(x, y)``, ``R``, ``K``) and ``s_g`` is the largest
  Euclidean norm of that vector along the reference samples. So ``D`` counts digits of a
  vector relative to its size (a component passing through zero does not inflate the
  error), and unit vectors (``gamma``, ``alpha``, ``beta``) have ``s_g = 1``;
* **growth** -- least-squares fits of ``ln err(t)`` against ``t`` (exponential growth,
  rate ``lambda`` per time unit: a finite-time Lyapunov-like exponent for a chaotic orbit)
  and against ``ln t`` (power law ``t^p``; ``p ~ 1`` is the linear phase-error growth of
  a regular orbit), over the unsaturated samples (:class:`GrowthFit`);
* **integral drift** -- ``max_t |I(t) - I(0)| / s_I`` for each first integral of
  :func:`taylorball._integrals` (evaluated in the working precision), with ``s_I`` the
  largest value of :func:`taylorball.integral_scales` along the samples; also in units of
  that type's epsilon;
* **cost** -- wall time per simulated time unit (compilation excluded; best of a few
  repeats for the cheap types), steps per time unit and the Taylor order ``ta.order``.

The 256-bit reference is itself checked against a 320-bit run (3.3x its cost) on the
first tenth of the time span (quick mode) or the first quarter (``--full``): its own digits
are reported.

:func:`precision_study` returns a :class:`PrecisionReport` (reusable by later studies:
longer runs, chaos indicators); :func:`format_report` and :func:`report_markdown` render it;
:func:`run_precision` is what ``taylorball verify --precision`` runs.
"""

from __future__ import annotations

import datetime
import math
import platform
import sys
import time
import warnings
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
from numpy.typing import ArrayLike

from ..errors import UsageError
from ..params import UnphysicalParametersWarning
from .precision_orbits import (
    Orbit,
    mparallel_state_on_levels,
    reduced_state_on_levels,
    reference_orbits,
    time_grid,
)

__all__ = [
    "Orbit",
    "TypeRun",
    "GrowthFit",
    "OrbitResult",
    "PrecisionReport",
    "NUMBER_TYPES",
    "REFERENCE_TYPE",
    "CHECK_TYPE",
    "reference_orbits",
    "reduced_state_on_levels",
    "mparallel_state_on_levels",
    "time_grid",
    "run_type",
    "state_digits",
    "fit_growth",
    "study_orbit",
    "precision_study",
    "format_report",
    "report_markdown",
    "run_precision",
]

#: Number types compared against the reference: (label, fp_type name, prec).
NUMBER_TYPES: Tuple[Tuple[str, str, Optional[int]], ...] = (
    ("float64", "float", None),
    ("longdouble", "longdouble", None),
    ("real128", "real128", None),
)
#: The reference run.
REFERENCE_TYPE: Tuple[str, str, Optional[int]] = ("real256", "real", 256)
#: The run that checks the reference.
CHECK_TYPE: Tuple[str, str, Optional[int]] = ("real320", "real", 320)

#: Physical vectors of each public layout (index ranges), for the per-vector scales.
GROUPS: Dict[str, Tuple[Tuple[str, slice], ...]] = {
    "full": (("omega", slice(0, 3)), ("alpha", slice(3, 6)), ("beta", slice(6, 9)),
             ("gamma", slice(9, 12)), ("xy", slice(12, 14))),
    "reduced": (("omega", slice(0, 3)), ("gamma", slice(3, 6)), ("R", slice(6, 9))),
    "mparallel": (("K", slice(0, 3)), ("gamma", slice(3, 6))),
}

#: Errors at or above this fraction of the scale count as saturated (no digit left).
SATURATION = 1e-2


# ---------------------------------------------------------------------------------------
# Runs
# ---------------------------------------------------------------------------------------
@dataclass
class TypeRun:
    """One integration of an orbit in one number type, sampled on a time grid.

    Attributes
    ----------
    label : str
        ``"float64"``, ``"longdouble"``, ``"real128"``, ``"real256"``, ...
    eps : float
        Machine epsilon of the type, ``2^(1 - digits)``.
    order : int
        Taylor order of the integrator (``ta.order``).
    times : numpy.ndarray
        Sample times (float).
    states : list of numpy.ndarray
        Public states at ``times``, in the working number type.
    steps : numpy.ndarray of int
        Cumulative number of Taylor steps at each sample.
    wall : float
        Seconds spent integrating over the whole grid (compilation excluded; best of
        ``repeats``).
    integrals : dict of str -> list
        Values of each first integral at ``times`` (working number type).
    integral_scales : dict of str -> float
        Largest :func:`taylorball.integral_scales` value along the samples.
    """

    label: str
    eps: float
    order: int
    times: np.ndarray
    states: List[np.ndarray]
    steps: np.ndarray
    wall: float
    integrals: Dict[str, list]
    integral_scales: Dict[str, float]

    @property
    def t_end(self) -> float:
        return float(self.times[-1])

    @property
    def wall_per_time(self) -> float:
        """Seconds of wall time per simulated time unit."""
        return self.wall / self.t_end

    @property
    def steps_per_time(self) -> float:
        return float(self.steps[-1]) / self.t_end

    def drift(self) -> Dict[str, np.ndarray]:
        """``|I(t) - I(0)| / s_I`` at every sample, per integral (float)."""
        out = {}
        for k, vals in self.integrals.items():
            i0 = vals[0]
            out[k] = np.array([abs(float(v - i0)) for v in vals]) / self.integral_scales[k]
        return out

    def max_drift(self) -> Tuple[str, float]:
        """The integral with the largest drift over the run and that drift (relative to its
        scale)."""
        d = {k: float(np.max(v)) for k, v in self.drift().items()}
        k = max(d, key=d.__getitem__)
        return k, d[k]


def run_type(orbit: Orbit, times: ArrayLike, fp: str, prec: Optional[int] = None, *,
             label: Optional[str] = None, repeats: int = 1) -> TypeRun:
    """Integrate ``orbit`` in one number type and sample it on ``times``.

    The integrator steps exactly onto each sample time (``propagate_until``); the initial
    float64 state is projected in the working precision (see :mod:`taylorball._propagate`).

    Parameters
    ----------
    fp : {"float", "longdouble", "real128", "real"}
    prec : int, optional
        Bits, for ``"real"``.
    repeats : int
        Integrate this many times and keep the fastest wall time (results are identical).
    """
    from .._integrals import integral_scales, integrals
    from .._propagate import make_integrator, public_state

    grid = np.asarray(times, dtype=float)
    if grid.ndim != 1 or grid.size < 2 or grid[0] != 0.0 or np.any(np.diff(grid) <= 0):
        raise UsageError(f"times must be an increasing 1-D grid starting at 0, got {times!r}")
    best = math.inf
    for _ in range(max(1, int(repeats))):
        ta, system, spec = make_integrator(orbit.kind, orbit.params, orbit.state, fp_type=fp, prec=prec)
        pars = np.array(ta.pars)
        states = [public_state(system, pars, ta.state, spec)]
        steps = [0]
        tk = [spec.scalar(t) for t in grid[1:]]
        wall = 0.0
        for t in tk:
            t0 = time.perf_counter()
            res = ta.propagate_until(t)
            wall += time.perf_counter() - t0
            if res[0] != _time_limit():
                from ..errors import IntegrationError

                raise IntegrationError(f"{orbit.name} in {spec}: integration stopped at t={ta.time} with {res[0]}")
            steps.append(steps[-1] + int(res[3]))
            states.append(public_state(system, pars, ta.state, spec))
        best = min(best, wall)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnphysicalParametersWarning)
        vals = [integrals(orbit.kind, orbit.params, s, check=False) for s in states]
        scs = [integral_scales(orbit.kind, orbit.params, s, check=False) for s in states]
    names = list(vals[0])
    return TypeRun(
        label=label or str(spec),
        eps=spec.eps,
        order=int(ta.order),
        times=grid,
        states=states,
        steps=np.array(steps),
        wall=best,
        integrals={k: [v[k] for v in vals] for k in names},
        integral_scales={k: max(float(s[k]) for s in scs) for k in names},
    )


def _time_limit():
    import heyoka as hy

    return hy.taylor_outcome.time_limit


def _exact(v, bits=512):
    """A value of any supported number type as an exact ``heyoka.real`` (512 bits hold
    float64, long double, real128 and real up to 512 bits exactly)."""
    import heyoka as hy

    if isinstance(v, (float, np.floating)) and not isinstance(v, np.longdouble):
        return hy.real(float(v), bits)
    return hy.real(v, bits)


def group_scales(kind: str, states: Sequence[np.ndarray]) -> Dict[str, float]:
    """Largest Euclidean norm of each physical vector of the layout over ``states`` (1.0
    for a vector that vanishes along all of them)."""
    out = {}
    for name, sl in GROUPS[kind]:
        s = max(math.sqrt(sum(float(x) ** 2 for x in st[sl])) for st in states)
        out[name] = s if s > 0 else 1.0
    return out


def state_digits(kind: str, states: Sequence[np.ndarray], reference: Sequence[np.ndarray],
                 scales: Dict[str, float], cap: float = 80.0) -> Tuple[np.ndarray, np.ndarray]:
    r"""Relative errors and correct digits of ``states`` against ``reference``.

    ``err = max_g max_{i in g} |x_i - ref_i| / s_g`` (differences taken exactly in
    512-bit arithmetic), ``digits = -log10(err)`` capped at ``cap`` (for ``err = 0``) and
    floored at 0.

    Returns
    -------
    (err, digits) : numpy.ndarray, numpy.ndarray
    """
    errs = []
    for x, r in zip(states, reference):
        e = 0.0
        for name, sl in GROUPS[kind]:
            for xi, ri in zip(x[sl], r[sl]):
                e = max(e, abs(float(_exact(xi) - _exact(ri))) / scales[name])
        errs.append(e)
    err = np.array(errs)
    with np.errstate(divide="ignore"):
        dig = np.clip(-np.log10(err), 0.0, cap)
    return err, dig


# ---------------------------------------------------------------------------------------
# Growth fits
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GrowthFit:
    """Fits of the error growth over the unsaturated samples (``t > 0``,
    ``err < SATURATION``).

    Attributes
    ----------
    rate : float
        ``lambda`` of ``err ~ exp(lambda t)`` (per time unit), from the samples with ``t``
        in the last decade of the unsaturated range (the asymptotic regime).
    power : float
        ``p`` of ``err ~ t^p`` over all unsaturated samples.
    rms_exp, rms_pow : float
        Residuals (in ``log10`` units) of the two fits over the samples each used.
    rms_pow_late : float
        Residual of a power-law fit over the same late samples as ``rate``.
    power_late : float
        Exponent of that late power-law fit.
    n : int
        Number of samples used (NaN fits below 3).
    model : str
        ``"exponential"`` if over the late samples the error grew by more than 100x and
        faster than any power a regular orbit shows (``power_late > 3``: rounding errors
        on a torus grow at most like ``t^2``, a linear phase drift from a random walk of
        the actions), ``"power"`` otherwise, ``"-"`` without enough samples. Residuals of
        the two fits over a short late window are not a reliable discriminator (a steep
        power law mimics an exponential there), hence the exponent test.
    """

    rate: float
    power: float
    rms_exp: float
    rms_pow: float
    n: int
    model: str
    rms_pow_late: float = math.nan
    power_late: float = math.nan


def fit_growth(times, err) -> GrowthFit:
    """Fit ``ln err`` against ``t`` (late samples) and ``ln t`` (all unsaturated samples).
    See :class:`GrowthFit`."""
    t = np.asarray(times, dtype=float)
    e = np.asarray(err, dtype=float)
    ok = (t > 0) & (e > 0) & (e < SATURATION)
    # samples after the first saturated one are excluded too
    sat = np.nonzero((t > 0) & (e >= SATURATION))[0]
    if sat.size:
        ok &= np.arange(t.size) < sat[0]
    t, e = t[ok], e[ok]
    nan = math.nan
    if t.size < 3:
        return GrowthFit(nan, nan, nan, nan, int(t.size), "-")
    le = np.log(e)
    p, c = np.polyfit(np.log(t), le, 1)
    rms_pow = float(np.sqrt(np.mean((np.polyval([p, c], np.log(t)) - le) ** 2)) / math.log(10))
    late = t >= t[-1] / 10
    if late.sum() < 3:
        late = np.arange(t.size) >= t.size - 3
    tl, ll = t[late], le[late]
    lam, c2 = np.polyfit(tl, ll, 1)
    rms_exp = float(np.sqrt(np.mean((np.polyval([lam, c2], tl) - ll) ** 2)) / math.log(10))
    pl, cl = np.polyfit(np.log(tl), ll, 1)
    rms_pow_late = float(np.sqrt(np.mean((np.polyval([pl, cl], np.log(tl)) - ll) ** 2)) / math.log(10))
    grew = (ll.max() - ll.min()) / math.log(10) > 2
    model = "exponential" if (grew and pl > 3.0 and lam > 0) else "power"
    return GrowthFit(float(lam), float(p), rms_exp, rms_pow, int(t.size), model, rms_pow_late, float(pl))


# ---------------------------------------------------------------------------------------
# One orbit, many types
# ---------------------------------------------------------------------------------------
@dataclass
class OrbitResult:
    """Everything measured on one orbit.

    Attributes
    ----------
    orbit : Orbit
    times : numpy.ndarray
    runs : dict of str -> TypeRun
        Keyed by label; includes the reference (``REFERENCE_TYPE[0]``).
    reference : str
        Label of the reference run.
    scales : dict of str -> float
        Per-vector scales ``s_g`` of the digits (from the reference).
    errors, digits : dict of str -> numpy.ndarray
        Per compared type, at ``times``.
    growth : dict of str -> GrowthFit
    reference_check : dict or None
        ``{"label", "times", "digits"}``: digits of the reference against a higher
        precision run on (part of) the grid.
    """

    orbit: Orbit
    times: np.ndarray
    runs: Dict[str, TypeRun]
    reference: str
    scales: Dict[str, float]
    errors: Dict[str, np.ndarray]
    digits: Dict[str, np.ndarray]
    growth: Dict[str, GrowthFit]
    reference_check: Optional[dict] = None

    @property
    def compared(self) -> List[str]:
        return list(self.digits)

    def time_to_digits(self, label: str, k: float) -> float:
        """First time at which ``label`` keeps fewer than ``k`` digits (linear
        interpolation in ``t`` between samples); ``inf`` if it never drops below."""
        d, t = self.digits[label], self.times
        below = np.nonzero(d < k)[0]
        if below.size == 0:
            return math.inf
        j = int(below[0])
        if j == 0:
            return 0.0
        return float(t[j - 1] + (d[j - 1] - k) / (d[j - 1] - d[j]) * (t[j] - t[j - 1]))

    def cost_ratio(self, label: str) -> float:
        """Wall time per time unit relative to float64."""
        return self.runs[label].wall_per_time / self.runs["float64"].wall_per_time

    def as_dict(self) -> dict:
        """A JSON-friendly summary (no states)."""
        runs = {}
        for lab, r in self.runs.items():
            k, dmax = r.max_drift()
            runs[lab] = {
                "eps": r.eps, "order": r.order, "wall_s": r.wall, "wall_per_time": r.wall_per_time,
                "steps_per_time": r.steps_per_time, "max_drift": dmax, "max_drift_integral": k,
                "max_drift_eps": dmax / r.eps,
                "drift": {n: v.tolist() for n, v in r.drift().items()},
            }
        return {
            "orbit": {"name": self.orbit.name, "kind": self.orbit.kind, "params": repr(self.orbit.params),
                      "state": self.orbit.state.tolist(), "description": self.orbit.description},
            "times": self.times.tolist(),
            "scales": self.scales,
            "digits": {k: v.tolist() for k, v in self.digits.items()},
            "errors": {k: v.tolist() for k, v in self.errors.items()},
            "growth": {k: vars(g) for k, g in self.growth.items()},
            "runs": runs,
            "reference_check": None if self.reference_check is None else {
                "label": self.reference_check["label"], "times": list(map(float, self.reference_check["times"])),
                "digits": list(map(float, self.reference_check["digits"]))},
        }


def study_orbit(orbit: Orbit, times: ArrayLike, *, types=NUMBER_TYPES, reference=REFERENCE_TYPE,
                check=CHECK_TYPE, check_until: Optional[float] = None, cheap_repeats: int = 3,
                log=None) -> OrbitResult:
    """Integrate ``orbit`` in each of ``types`` and in the reference type, and compare.

    Parameters
    ----------
    times : sequence of float
        Sample grid, increasing from 0 (see :func:`time_grid`).
    types : sequence of (label, fp, prec)
        Compared types (default float64, long double, real128).
    reference, check : (label, fp, prec)
        Reference run, and the higher-precision run that checks it (``check=None`` to skip).
    check_until : float, optional
        Check the reference only on samples ``t <= check_until`` (default: whole grid).
    cheap_repeats : int
        Repeats for the wall time of float64 and long double (fast and noisy).
    """
    grid = np.asarray(times, dtype=float)
    runs: Dict[str, TypeRun] = {}
    for lab, fp, prec in (*types, reference):
        t0 = time.perf_counter()
        rep = cheap_repeats if fp in ("float", "longdouble") else 1
        runs[lab] = run_type(orbit, grid, fp, prec, label=lab, repeats=rep)
        if log:
            log(f"  {orbit.name}: {lab} to t = {grid[-1]:g} in {time.perf_counter() - t0:.1f} s")
    ref = runs[reference[0]]
    scales = group_scales(orbit.kind, ref.states)
    errors, digits, growth = {}, {}, {}
    for lab, _, _ in types:
        e, d = state_digits(orbit.kind, runs[lab].states, ref.states, scales)
        errors[lab], digits[lab] = e, d
        growth[lab] = fit_growth(grid, e)
    refcheck = None
    if check is not None:
        sub = grid[grid <= (grid[-1] if check_until is None else check_until)]
        if sub.size >= 2:
            t0 = time.perf_counter()
            chk = run_type(orbit, sub, check[1], check[2], label=check[0])
            _, d = state_digits(orbit.kind, ref.states[: sub.size], chk.states, scales)
            refcheck = {"label": check[0], "times": sub, "digits": d}
            if log:
                log(f"  {orbit.name}: {check[0]} check to t = {sub[-1]:g} in {time.perf_counter() - t0:.1f} s")
    return OrbitResult(orbit, grid, runs, reference[0], scales, errors, digits, growth, refcheck)


# ---------------------------------------------------------------------------------------
# The whole study
# ---------------------------------------------------------------------------------------
@dataclass
class PrecisionReport:
    """Results of :func:`precision_study` and where they were measured."""

    mode: str
    date: str
    machine: str
    wall: float
    results: List[OrbitResult] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"mode": self.mode, "date": self.date, "machine": self.machine, "wall_s": self.wall,
                "results": [r.as_dict() for r in self.results]}


def _machine() -> str:
    import heyoka as hy

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import os

    return (f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, "
            f"Python {platform.python_version()}, heyoka {hy.__version__}, numpy {np.__version__}")


def precision_study(full: bool = False, *, only: Optional[Sequence[str]] = None, orbits=None,
                    t_end: Optional[float] = None, types=NUMBER_TYPES, log=None) -> PrecisionReport:
    """Run the precision study on the reference orbits.

    Parameters
    ----------
    full : bool
        Long runs (each orbit's ``t_full``) with the reference checked on the first
        quarter of the grid; quick mode uses ``t_quick`` and checks the first tenth.
    only : sequence of str, optional
        Orbit names to run (see :func:`reference_orbits`).
    orbits : list of Orbit, optional
        Custom orbits instead of :func:`reference_orbits`.
    t_end : float, optional
        Override every orbit's final time.

    Raises
    ------
    UsageError
        For an unknown orbit name in ``only``.
    """
    allorb = list(orbits) if orbits is not None else reference_orbits()
    if only:
        names = [o.name for o in allorb]
        bad = [n for n in only if n not in names]
        if bad:
            raise UsageError(f"only: unknown orbit(s) {bad}; valid names are {names}")
        allorb = [o for o in allorb if o.name in only]
    t0 = time.perf_counter()
    results = []
    for o in allorb:
        T = t_end if t_end is not None else (o.t_full if full else o.t_quick)
        results.append(study_orbit(o, time_grid(T), types=types, check_until=T / 4 if full else T / 10,
                                   log=log))
    return PrecisionReport(
        mode="full" if full else "quick",
        date=datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        machine=_machine(),
        wall=time.perf_counter() - t0,
        results=results,
    )


# ---------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------
def _row_times(times: np.ndarray) -> List[int]:
    """Indices of the samples shown in tables: t = 0, decades, and the last one."""
    idx = [0]
    for j, t in enumerate(times):
        if t > 0 and abs(math.log10(t) - round(math.log10(t))) < 1e-9:
            idx.append(j)
    if len(times) - 1 not in idx:
        idx.append(len(times) - 1)
    return idx


def _fmt_t(x: float, t_end: float) -> str:
    return f"> {t_end:g}" if math.isinf(x) else f"{x:.3g}"


def _tables(res: OrbitResult):
    """(title, header, rows) of the three tables of one orbit."""
    labs = res.compared
    head = ["t"] + labs + ([f"{res.reference} vs {res.reference_check['label']}"] if res.reference_check else [])
    rows = []
    chk = res.reference_check
    for j in _row_times(res.times):
        row = [f"{res.times[j]:g}"] + [f"{res.digits[lab][j]:.1f}" for lab in labs]
        if chk is not None:
            k = np.nonzero(np.asarray(chk["times"]) == res.times[j])[0]
            row.append(f"{chk['digits'][k[0]]:.1f}" if k.size else "-")
        rows.append(row)
    digits = ("correct digits", head, rows)
    ghead = ["type", "growth", "lambda (1/time)", "power p (all/late)", "late rms exp/pow", "t(<10 dig)",
             "t(<3 dig)"]
    grows = []
    for lab in labs:
        g = res.growth[lab]
        grows.append([lab, g.model, f"{g.rate:.3g}", f"{g.power:.2f}/{g.power_late:.2f}", f"{g.rms_exp:.2f}/{g.rms_pow_late:.2f}",
                      _fmt_t(res.time_to_digits(lab, 10), res.times[-1]),
                      _fmt_t(res.time_to_digits(lab, 3), res.times[-1])])
    growth = ("error growth", ghead, grows)
    chead = ["type", "order", "steps/time", "wall s/time", "cost vs float64", "worst integral",
             "max drift/scale", "drift in eps"]
    crows = []
    for lab, r in res.runs.items():
        worst, d = r.max_drift()
        crows.append([lab, str(r.order), f"{r.steps_per_time:.1f}", f"{r.wall_per_time:.2e}",
                      f"{res.cost_ratio(lab):.0f}x" if lab != "float64" else "1x", worst, f"{d:.1e}",
                      f"{d / r.eps:.0f}"])
    cost = ("cost and integral drift", chead, crows)
    return [digits, growth, cost]


def _text_table(header, rows) -> str:
    w = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    lines = ["  ".join(str(c).rjust(w[i]) for i, c in enumerate(header)),
             "  ".join("-" * n for n in w)]
    lines += ["  ".join(str(c).rjust(w[i]) for i, c in enumerate(r)) for r in rows]
    return "\n".join(lines)


def _md_table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---:" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _orbit_heading(res: OrbitResult) -> str:
    o = res.orbit
    return (f"{o.name} ({o.kind}; {o.description})\n"
            f"  params: {o.params!r}\n"
            f"  digit scales s_g: " + ", ".join(f"{k} {v:.3g}" for k, v in res.scales.items()))


def format_report(report: PrecisionReport) -> str:
    """The report as plain-text tables (one block per orbit)."""
    out = [f"taylorball precision study ({report.mode}), {report.date}", f"machine: {report.machine}",
           f"digits = -log10(max_g max_i |x_i - ref_i| / s_g) against {REFERENCE_TYPE[0]}, s_g = largest norm of "
           "each vector along the reference; drift = max_t |I(t) - I(0)| / scale", ""]
    for res in report.results:
        out.append(_orbit_heading(res))
        for title, head, rows in _tables(res):
            out.append(f"  -- {title}")
            out.append("\n".join("  " + line for line in _text_table(head, rows).splitlines()))
        out.append("")
    out.append(f"total wall time {report.wall:.1f} s")
    return "\n".join(out)


def report_markdown(report: PrecisionReport) -> str:
    """The report as markdown tables (for ``docs/precision.md``)."""
    out = [f"Measured {report.date} ({report.mode} mode, total {report.wall:.0f} s) on {report.machine}.", ""]
    for res in report.results:
        o = res.orbit
        out.append(f"### {o.name}")
        out.append("")
        out.append(f"{o.kind}; {o.description}; `{o.params!r}`; initial state "
                   f"`{np.array2string(o.state, precision=17, separator=', ', max_line_width=10**6)}`. "
                   "Digit scales s_g: " + ", ".join(f"{k} {v:.3g}" for k, v in res.scales.items()) + ".")
        out.append("")
        for title, head, rows in _tables(res):
            out.append(f"*{title}*")
            out.append("")
            out.append(_md_table(head, rows))
            out.append("")
    return "\n".join(out)


def run_precision(full: bool = False, *, only: Optional[Sequence[str]] = None, t_end: Optional[float] = None,
                  json_out: Optional[str] = None, markdown_out: Optional[str] = None) -> int:
    """What ``taylorball verify --precision`` does: run :func:`precision_study`, print its
    tables (:func:`format_report`) on stdout, write the numbers (``PrecisionReport.as_dict``)
    as JSON to ``json_out`` and the tables as markdown (:func:`report_markdown`) to
    ``markdown_out``, atomically. ``json_out="-"`` puts the JSON on stdout and everything
    else on stderr. Progress goes to the ``taylorball.verify`` logger. The paths are not
    checked here: the command line checks them before any work.

    Returns the exit status: 2 for an unknown orbit name, 1 unless the reference agreed
    with its check run to more digits than any compared type kept, else 0."""
    import contextlib
    import json
    import logging
    from pathlib import Path

    from ..io import atomic_write_bytes, jsonable

    log = logging.getLogger("taylorball.verify")
    json_stdout = json_out == "-"
    # with the JSON on stdout, nothing else may reach stdout
    with contextlib.redirect_stdout(sys.stderr) if json_stdout else contextlib.nullcontext():
        print(f"taylorball verify --precision ({'full' if full else 'quick'})", flush=True)
        try:
            report = precision_study(full, only=only, t_end=t_end, log=log.info)
        except UsageError as exc:
            print(str(exc), file=sys.stderr)
            return 2
        print()
        print(format_report(report))
        ok = _reference_ok(report)
    if json_out:
        text = json.dumps(_finite_json(jsonable(report.as_dict())), indent=1, allow_nan=False) + "\n"
        if json_stdout:
            sys.stdout.write(text)
        else:
            atomic_write_bytes(Path(json_out), text.encode())
    if markdown_out:
        atomic_write_bytes(Path(markdown_out), (report_markdown(report) + "\n").encode())
    return 0 if ok else 1


def _finite_json(obj):
    """``obj`` (JSON-ready) with every non-finite float replaced by ``None``."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_json(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite_json(v) for v in obj]
    return obj


def _reference_ok(report: PrecisionReport) -> bool:
    """Whether, at every checked sample, the reference agrees with its check run to more
    digits than any compared type agrees with the reference (else the digits measured
    against it are not the compared types' own); prints a warning per failure."""
    ok = True
    for res in report.results:
        chk = res.reference_check
        if chk is None:
            continue
        n = len(chk["times"])
        best = np.max([res.digits[lab][:n] for lab in res.compared], axis=0)
        bad = np.nonzero(np.asarray(chk["digits"]) <= best + 1.0)[0]
        if bad.size:
            j = int(bad[0])
            print(f"WARNING {res.orbit.name}: at t = {chk['times'][j]:g} the reference agrees with "
                  f"{chk['label']} to {chk['digits'][j]:.1f} digits, not clearly more than a compared type "
                  f"({best[j]:.1f})")
            ok = False
    return ok
