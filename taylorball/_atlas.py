r"""The chaotic fraction of a level: :func:`chaotic_fraction`.

On a level ``|M| = C``, ``(M, gamma) = M_gamma``, ``E = h`` of the reduced system, ``n`` initial
conditions are drawn uniformly in the admissible region of the section-4 map
(:func:`taylorball.section_admissible_sample`); each orbit's MEGNO ``<Y>`` at ``t_end`` is
computed in the SIMD lanes (:func:`taylorball.megno_many`, by default with ``norm="compact"``
so that the contact point's shear at small ``Omega`` does not count as chaos) and the orbit
is called chaotic when ``<Y> > threshold`` (4: twice the torus value 2). The fraction of
chaotic orbits estimates the chaotic share of the region (measured uniformly in the chart
``(l, r1, r2)``); its binomial uncertainty is the Wilson score interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from statistics import NormalDist
from typing import Optional, Tuple

import numpy as np

from ._typing import ProgressLike
from ._deprecation import moved, options_of
from .chaos import MegnoOptions
from .errors import ParameterError, UsageError
from .levels import Levels
from .numbers import count, real_number
from .palette import CHAOTIC_MEGNO
from .params import BallParams

__all__ = ["ChaoticFraction", "chaotic_fraction", "wilson_interval"]


def wilson_interval(k: int, n: int, level: float = 0.95) -> Tuple[float, float]:
    """Wilson score interval of a binomial proportion ``k / n`` at confidence ``level``.

    Unlike the normal (Wald) interval it stays inside ``[0, 1]`` and is not empty at
    ``k = 0`` or ``k = n`` (there its far end is ``z^2 / (n + z^2)`` from the edge).

    Parameters
    ----------
    k : int
        Successes, ``0 <= k <= n``.
    n : int
        Trials, ``>= 1``.
    level : float
        Confidence level in ``(0, 1)``.

    Returns
    -------
    (float, float)
        Lower and upper end.

    Raises
    ------
    UsageError
        ``k``, ``n`` or ``level`` out of range.

    Examples
    --------
    >>> from taylorball._atlas import wilson_interval
    >>> [round(v, 4) for v in wilson_interval(0, 100)]       # none of 100: up to 3.7 %
    [0.0, 0.037]
    >>> [round(v, 4) for v in wilson_interval(50, 100)]
    [0.4038, 0.5962]
    """
    n = count("n", n, lo=1)
    k = count("k", k, lo=0)
    if k > n:
        raise UsageError(f"k must be at most n = {n} (successes among n trials), got {k!r}")
    level = real_number("level", level, lo=0.0, lo_open=True)
    if not level < 1.0:
        raise UsageError(f"level must be a confidence level in (0, 1), e.g. 0.95, got {level!r}")
    z = NormalDist().inv_cdf((1.0 + level) / 2.0)
    p = k / n
    den = 1.0 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, mid - half) if k else 0.0, min(1.0, mid + half) if k < n else 1.0


@dataclass(frozen=True, eq=False)
class ChaoticFraction:
    """The chaotic share of a level's admissible region (see :func:`chaotic_fraction`).

    Attributes
    ----------
    fraction : float
        ``n_chaotic / n``.
    n_chaotic, n : int
        Orbits with ``<Y> > threshold``, and orbits run.
    ci : (float, float)
        Wilson score interval of the fraction at confidence ``level``.
    level, threshold, t_end : float
    mean_megno : ndarray, shape (n,)
        ``<Y>`` of each orbit at its last time (``t_end``, or earlier where the run passed
        ``stop_above``).
    t : ndarray, shape (n,)
        That time per orbit.
    points : ndarray, shape (n, 3)
        Chart points ``(l, r1, r2)`` of the initial conditions.
    r_box : float
        Half-width of the sampler's ``(r1, r2)`` box.
    """

    fraction: float
    n_chaotic: int
    n: int
    ci: Tuple[float, float]
    level: float
    threshold: float
    t_end: float
    mean_megno: np.ndarray = field(repr=False)
    t: np.ndarray = field(repr=False)
    points: np.ndarray = field(repr=False)
    r_box: float = field(repr=False, default=math.nan)


@moved(MegnoOptions, "t0", "compact_mode", renamed={"threads": "workers"})
def chaotic_fraction(params: BallParams, levels: Levels, *, n: int, t_end: float, seed: int = 0,
                     threshold: float = CHAOTIC_MEGNO, stop_above: Optional[float] = 10.0,
                     norm: str = "compact",
                     level: float = 0.95, workers: Optional[int] = None, progress: ProgressLike = False,
                     options: Optional[MegnoOptions] = None) -> ChaoticFraction:
    """The fraction of a reduced level's admissible region whose orbits are chaotic by MEGNO.

    ``n`` chart points are drawn uniformly in the admissible region of the section ``g = 0``
    (crossing upward) with :func:`taylorball.section_admissible_sample` (``seed``); where the
    energy equation has several roots successive points take successive roots. Each orbit's
    ``<Y>`` at ``t_end`` comes from :func:`taylorball.megno_many` (``norm``,
    ``stop_above``, ``workers``, ``progress``, ``options`` as there); an orbit is
    chaotic when ``<Y> > threshold``. A run stopped at ``stop_above`` counts as chaotic (it
    has passed the threshold and MEGNO of a chaotic orbit keeps growing), which saves most of
    the time of chaotic orbits.

    Parameters
    ----------
    params : BallParams or Problem
        The ball; or a reduced :class:`taylorball.Problem` (float64, default tolerance) in
        its place.
    levels : Levels
        ``C``, ``M_gamma``, ``h`` (it must have admissible points: an empty level raises).
    n : int
        Orbits (``1 .. 10^6``).
    t_end : float
        MEGNO time (``> t0``).
    seed : int
        Seed of the sample (the tangent vectors' seed is ``options.seed``, default 0).
    threshold : float
        ``<Y>`` above which an orbit is chaotic (finite, ``> 0``; default 4, twice the
        torus value 2).
    stop_above : float or None
        Passed to :func:`taylorball.megno_many`; must exceed ``threshold``.
    norm : {"compact", "full"}
        As for :func:`taylorball.megno`: ``"compact"`` (default) leaves out the contact
        point's shear, which at ``Omega = 0`` puts tori at ``<Y> -> 4``.
    level : float
        Confidence level of :attr:`ChaoticFraction.ci`.
    options : MegnoOptions, optional
        As for :func:`taylorball.megno_many` (``t0``, ``chunk``, the tangent vectors'
        ``seed``, ``compact_mode``); the keywords ``t0=`` and ``compact_mode=`` are their
        deprecated old form.

    Returns
    -------
    ChaoticFraction

    Raises
    ------
    UsageError
        Bad ``levels``, ``n``, times, ``threshold``, ``stop_above``, ``level`` or ``norm``.
    ParameterError
        ``params`` not a :class:`BallParams`.
    EmptyLevelError
        No admissible point on the level.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> cf = tb.chaotic_fraction(FIG4_BALL, FIG4A_LEVELS, n=2, t_end=200.0, workers=1)
    >>> cf.n_chaotic, cf.n                         # the Fig. 4a level is one chaotic sea
    (2, 2)
    >>> [round(v, 3) for v in cf.ci]
    [0.342, 1.0]
    """
    from ._problem import Problem, lane_problem, params_problem
    from .chaos import _check_args, megno_many
    from .charts import section_admissible_sample

    if not isinstance(levels, Levels):
        raise UsageError(f"levels must be a taylorball.Levels(C=..., M_gamma=..., h=...), got {levels!r}")
    prob = None
    if isinstance(params, Problem):
        prob = lane_problem("chaotic_fraction", params_problem("chaotic_fraction", "reduced", params))
        params = prob.params
    if not isinstance(params, BallParams):
        raise ParameterError(f"params must be BallParams(inertia=(I1, I2, I3), mass=m, radius=a, plane_rate=Omega), "
                             f"got {params!r}")
    opts = options_of(options, MegnoOptions, "chaotic_fraction")
    t0 = opts.t0
    n = count("n", n, lo=1, hi=1_000_000)
    count("seed", seed, lo=0)
    _check_args("reduced", t0, t_end, opts.chunk, stop_above, norm, opts.jacobian)
    threshold = real_number("threshold", threshold, lo=0.0, lo_open=True)
    if stop_above is not None and not float(stop_above) > threshold:
        raise UsageError(f"stop_above must exceed threshold = {threshold!r} (a run stopped there is counted "
                         f"chaotic), got {stop_above!r}")
    wilson_interval(0, 1, level)  # checks level before any work
    region = section_admissible_sample(params, **levels.as_kwargs(), n=n, seed=seed, direction=1)
    states = [roots[i % len(roots)] for i, roots in enumerate(region["states"])]
    res = megno_many(prob or "reduced", None if prob else params, states, t_end, stop_above=stop_above,
                     norm=norm, workers=workers, progress=progress, options=opts)
    Y = np.array([r.mean_megno for r in res])
    T = np.array([r.t for r in res])
    k = int(np.count_nonzero(Y > threshold))
    m = len(states)
    return ChaoticFraction(fraction=k / m, n_chaotic=k, n=m, ci=wilson_interval(k, m, level), level=float(level),
                           threshold=threshold, t_end=float(t_end), mean_megno=Y, t=T,
                           points=np.asarray(region["points"], dtype=float), r_box=float(region["r_box"]))
