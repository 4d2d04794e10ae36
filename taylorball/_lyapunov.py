r"""The Lyapunov spectrum (Benettin et al. 1980, QR re-orthonormalisation):
:func:`lyapunov_spectrum` of one orbit, :func:`lyapunov_spectra` of many in the SIMD
lanes. Public from :mod:`taylorball.chaos` (and ``taylorball``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional, Union

import numpy as np
from numpy.typing import ArrayLike

from ._deprecation import renamed
from ._problem import Problem, at_boundary, lane_problem
from ._typing import FpTypeLike, KindName, ParamsLike, ProgressLike, StatesLike
from ._variational import _check_sample, _check_spectrum_args, _fundamental_lanes, _qr, _run_chunks
from .tangent import TangentSystem


@dataclass(frozen=True)
class LyapunovSpectrum:
    r"""The Lyapunov spectrum of one orbit (:func:`lyapunov_spectrum`).

    Attributes
    ----------
    exponents : ndarray, shape (n,)
        Finite-time exponents ``(1/(t - t0)) sum_k ln |R_k,ii|``, sorted descending, in the
        working number type (``n`` = dimension of the integrated system, constraint
        directions included: see :func:`lyapunov_spectrum`).
    times : ndarray, shape (m,)
        Times of the running estimates (the re-orthonormalisation times, or ``sample``).
    partial : ndarray, shape (m, n)
        Running estimates at ``times``, each row sorted descending.
    sum : scalar
        Sum of the exponents, ``ln |det Phi(t)| / (t - t0)``, in the working type.
    sum_error_bound : float
        Bound on the rounding and truncation error of ``sum`` (see :func:`lyapunov_spectrum`).
    liouville_residual : float
        ``sum + (ln rho(x(t)) - ln rho(x(t0))) / (t - t0)``: zero for exact arithmetic,
        ``rho`` the invariant density in the integrated variables.
    kind : str
    problem : taylorball.Problem
        System, formulation, parameters, number type and tolerance of the run.
    t0, t, renorm : float
    initial_state, final_state : ndarray
        Public states at ``t0`` (as projected in the working type) and ``t``.
    n_chunks, n_steps : int
        Re-orthonormalisations and Taylor steps.
    cond_sum : float
        ``sum_k c_k (1 + sqrt(steps_k))``, ``c_k = max_i |Phi_k e_i| / R_ii`` of chunk ``k``
        (float64): the condition factor of :attr:`sum_error_bound`.
    """

    exponents: np.ndarray
    times: np.ndarray
    partial: np.ndarray
    sum: object
    sum_error_bound: float
    liouville_residual: float
    kind: str
    problem: object
    t0: float
    t: float
    renorm: float
    initial_state: np.ndarray
    final_state: np.ndarray
    n_chunks: int
    n_steps: int
    cond_sum: float

    @property
    def maximal(self) -> float:
        """The largest exponent (float)."""
        return float(self.exponents[0])




def _log_density(prob, public):
    """``ln rho`` of the invariant density in the problem's integrated variables."""
    from ._integrals import density

    info = prob.system.info
    coords = "public" if prob.formulation == info.public_formulation else "internal"
    return np.log(prob.spec.array([density(prob.kind, prob.params, public, coords=coords, check=False)])[0])


@renamed(t="t_end")
def lyapunov_spectrum(kind: Union[KindName, Problem], params: Union[ParamsLike, ArrayLike, None] = None,
                      state: Optional[ArrayLike] = None, t_end: Optional[float] = None, *, t0: float = 0.0,
                      renorm: float = 1.0, fp_type: FpTypeLike = float, prec: Optional[int] = None,
                      tol: Optional[float] = None, sample: Optional[ArrayLike] = None) -> LyapunovSpectrum:
    r"""The full Lyapunov spectrum of an orbit by Benettin's method.

    The system is integrated with its fundamental matrix ``Phi' = J Phi``
    (:class:`taylorball.tangent.TangentSystem`, ``vectors="all"``, compact mode) from
    ``Phi(t0) = E``; every ``renorm`` time units ``Phi`` is replaced by ``Q`` of its QR
    factorisation (``diag R > 0``) and ``ln R_ii`` is added to the running sums. The
    exponents are the sums over ``t - t0``. QR: numpy's Householder (LAPACK) in float64; in
    long double a Householder QR written in the working dtype (not modified Gram--Schmidt:
    Householder keeps ``Q`` orthogonal to ``O(n eps)`` whatever the conditioning).

    **What the spectrum contains.** The tangent vectors span all of the integrated ``R^n``
    (9 for reduced, 14 for full, 6 for M||gamma), including directions off the constraint
    manifold. The constraint functions (``gamma^2`` and ``(R, gamma)`` for reduced; the six
    entries of the frame's Gram matrix for full; ``gamma^2`` for M||gamma) are conserved by
    the equations *everywhere*, not only on the manifold (``v' = v x omega`` for
    ``v = gamma, alpha, beta``, and ``(R, gamma)' = (R x omega, gamma) + (R, gamma x omega)
    = 0`` identically), so ``dg Phi(t) = dg`` for each: the transverse exponents of the
    invariant sets ``|gamma| = 1``, ``(R, gamma) = 0`` are **zero**, one per constraint.
    On the manifold each independent first integral ``F`` (``dF Phi(t) = dF``; reduced:
    ``C2, M_gamma, E``; full: ``F1, F2, F3, E``; M||gamma: ``lambda, E``) gives one zero
    exponent and the flow direction (``Phi(t) X(x0) = X(x(t))``, bounded) one more. Zeros
    imposed by the structure: reduced ``2 + 3 + 1 = 6`` of 9, full ``6 + 4 + 1 = 11`` of 14
    (its symmetry field, rotation of the plane (paper eq. (14) [eq9]), is transverse to the level of
    ``F1, F2`` and so is not an extra one), M||gamma ``1 + 2 + 1 = 4`` of 6. The others are
    the exponents of the Poincaré map on an integral level: ``(lambda, -lambda)`` for the
    area-preserving map of M||gamma, ``(lambda1, lambda2, lambda3)`` with sum 0 for the
    volume-preserving 3D map of reduced and full. The reduced equations are reversible
    (``t -> -t`` with ``(omega, gamma, R) -> (S omega, S gamma, S R)`` for ``S = -E`` or a
    reflection in a principal plane of inertia: any improper ``S`` commuting with ``I``,
    since ``S(u x v) = -(Su x Sv)``; it preserves ``C2, M_gamma, E``), so on a chaotic
    component that the reversal maps to itself the spectrum is symmetric,
    ``lambda3 = -lambda1`` and ``lambda2 = 0``: then 7 of 9 (12 of 14) exponents vanish,
    as measured on the Fig. 4a level (``docs/chaos.md``). At finite ``t`` the zero
    exponents are ``O(ln(t)/t)``.

    **Their sum.** The flow preserves the measure ``rho dx`` (``rho`` =
    :func:`taylorball.density` in the integrated variables), so ``rho(x(t)) det Phi(t) =
    rho(x(t0))`` (Liouville) and, exactly for every finite ``t``,
    ``sum = ln det Phi / (t - t0) = -(ln rho(x(t)) - ln rho(x(t0))) / (t - t0)``:
    :attr:`LyapunovSpectrum.liouville_residual` is the difference, and
    :attr:`~LyapunovSpectrum.sum_error_bound` is the first-order bound
    ``n eps sum_k c_k (1 + sqrt(steps_k)) / (t - t0)`` on it: over chunk ``k`` each of the
    ``n`` tangent vectors carries a relative error ``~ eps`` from each Taylor step (random
    walk over ``steps_k`` steps) and from the QR, and ``R_ii`` is the part of vector ``i``
    orthogonal to the vectors before it, a fraction ``1/c_k`` of it at worst
    (``c_k = max_i |Phi_k e_i| / R_ii``), so ``ln R_ii`` is off by ``~ eps c_k`` per
    error. It is a worst case: measured residuals are ``10^-5 .. 10^-3`` of it.

    Parameters
    ----------
    kind : {"reduced", "full", "mparallel"} or Problem
        A system, or a :class:`taylorball.Problem` with ``params`` left out
        (``lyapunov_spectrum(prob, state, t_end)``; it then fixes ``fp_type``, ``prec``
        and ``tol``).
    params : BallParams or MParallelParams
    state : array_like
        Initial public state on the constraint manifold (within the default
        ``constraint_tol``; it is then projected in the working type).
    t_end : float
        End of the run (finite, > t0; ``t=`` is its deprecated old name).
    t0 : float
        Start of the clock.
    renorm : float
        Time between re-orthonormalisations (> 0; at most :data:`MAX_CHUNKS` of them). The
        last chunk ends at ``t_end``.
    fp_type : float or numpy.longdouble
    prec, tol
        As for :func:`taylorball.propagate`.
    sample : sequence of float, optional
        Increasing times in ``(t0, t]`` at which to record the running estimates (from a QR of
        ``Phi`` on the chunk's continuous output, which leaves the run itself unchanged); default: at
        every re-orthonormalisation.

    Returns
    -------
    LyapunovSpectrum

    Raises
    ------
    UsageError
        Bad kind, times, renorm, sample or number type.
    StateError, ConstraintError
        A state of the wrong shape or off the constraint manifold.
    IntegrationError
        If the integrator stops early.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> spec = tb.lyapunov_spectrum("reduced", FIG4_BALL, demo_reduced_state(), 20.0)
    >>> spec.exponents.shape, spec.n_chunks        # 9 exponents, one QR per unit of time
    ((9,), 20)
    >>> bool(spec.maximal == spec.exponents.max())
    True
    >>> bool(abs(spec.liouville_residual) <= spec.sum_error_bound)   # the sum obeys Liouville
    True
    """
    from ._propagate import start_state

    prob, (state, t_end) = at_boundary("lyapunov_spectrum", kind, params, (state, t_end), ("state", "t_end"),
                                       fp_type=fp_type, prec=prec, tol=tol)
    spec = prob.spec
    t0f, tf, rf, _ = _check_spectrum_args(t0, t_end, renorm, spec)
    samples = _check_sample(sample, t0f, tf)
    internal = start_state(prob, state)
    acc = _Benettin(prob, t0f, rf, internal)
    x_end = _run_chunks(prob, internal, TangentSystem.of(prob, "all").identity(spec), t0f, tf, rf, samples, acc)
    return acc.result(x_end, tf)


class _Benettin:
    """The running sums of one orbit's spectrum: after each chunk :meth:`chunk` takes the
    tangent matrix ``Phi`` and returns ``Q`` to put back (scalar and lane runs share it, so
    their arithmetic is the same)."""

    def __init__(self, prob, t0: float, renorm: float, internal):
        self.prob, self.spec, self.t0, self.renorm, self.internal = prob, prob.spec, t0, renorm, internal
        self.logs = np.zeros(prob.system.dim, dtype=prob.spec.dtype)
        self.times: List[float] = []
        self.partial: List[np.ndarray] = []
        self.cond_sum, self.n_steps, self.n_chunks = 0.0, 0, 0

    def _elapsed(self, t: float):
        """``t - t0`` in the working type: the integrator ran from ``t0`` to ``t`` (float64
        values) and their difference is exact in long double, not always in float64 (there
        a rounded ``t - t0`` would put a relative error ``eps64`` on the long double sum and
        ``~eps64 |Delta ln rho|`` on its Liouville residual); the same operation in float64."""
        return self.spec.scalar(t) - self.spec.scalar(self.t0)

    def sample(self, phi, t: float):
        """Record the running estimate at ``t`` from ``Phi(t)`` without changing the run."""
        _, Rs = _qr(phi, self.spec)
        self.times.append(t)
        self.partial.append(np.sort((self.logs + np.log(np.diagonal(Rs))) / self._elapsed(t))[::-1])

    def chunk(self, phi, t: float, steps: int, *, record: bool) -> np.ndarray:
        """Add ``ln R_ii`` of the chunk ending at ``t``; ``Q`` flattened (row-major)."""
        self.n_steps += steps
        self.n_chunks += 1
        Q, R = _qr(phi, self.spec)
        self.logs = self.logs + np.log(np.diagonal(R))
        Rf = np.asarray(R, dtype=float)
        kappa = float(np.max(np.linalg.norm(Rf, axis=0) / np.diagonal(Rf)))  # max_i |Phi_k e_i| / R_ii >= 1
        self.cond_sum += kappa * (1.0 + float(np.sqrt(max(steps, 0))))
        if record:
            self.times.append(t)
            self.partial.append(np.sort(self.logs / self._elapsed(t))[::-1])
        return Q.reshape(-1)

    def result(self, internal_end, t: float) -> LyapunovSpectrum:
        from ._propagate import public_state

        prob, spec, n = self.prob, self.spec, self.prob.system.dim
        T = self._elapsed(t)
        total = self.logs.sum() / T
        x0 = public_state(prob.system, prob.pars, self.internal, spec)
        x1 = public_state(prob.system, prob.pars, internal_end, spec)
        resid = total + (_log_density(prob, x1) - _log_density(prob, x0)) / T
        bound = n * spec.eps * self.cond_sum / (t - self.t0)
        return LyapunovSpectrum(
            exponents=np.sort(self.logs / T)[::-1], times=np.asarray(self.times, dtype=float),
            partial=np.asarray(self.partial, dtype=spec.dtype).reshape(len(self.times), n), sum=total,
            sum_error_bound=float(bound), liouville_residual=float(resid), kind=prob.kind, problem=prob,
            t0=self.t0, t=t, renorm=self.renorm, initial_state=x0, final_state=x1, n_chunks=self.n_chunks,
            n_steps=self.n_steps, cond_sum=float(self.cond_sum))


@renamed(t="t_end", threads="workers")
def lyapunov_spectra(kind: Union[KindName, Problem], params: Union[ParamsLike, StatesLike, None] = None,
                     states: Optional[StatesLike] = None, t_end: Optional[float] = None, *,
                     t0: float = 0.0, renorm: float = 1.0, workers: Optional[int] = None,
                     progress: ProgressLike = False, sample: Optional[ArrayLike] = None) -> List[LyapunovSpectrum]:
    """:func:`lyapunov_spectrum` of many float64 orbits, in the SIMD lanes of heyoka batch
    integrators (one per thread; :mod:`taylorball.ensemble`, ``backend="lanes"``), each lane
    refilled with the next orbit as soon as its orbit ends.

    Each orbit runs on its own clock through the same chunk boundaries ``t0 + k renorm`` as
    :func:`lyapunov_spectrum`, with the same QR, so its result depends only on its own state
    (bit-identical whatever the threads and companions); it agrees with
    :func:`lyapunov_spectrum` of the same state to rounding, not bitwise (heyoka's vectorised
    code rounds differently; on a chaotic orbit the two then separate as two float64 runs
    do). The batch variational system compiles in compact mode.

    Parameters
    ----------
    kind : {"reduced", "full", "mparallel"} or Problem
        As for :func:`lyapunov_spectrum` (``lyapunov_spectra(prob, states, t_end)``); a
        Problem must be float64 at the default tolerance (the lanes' integrators).
    states : array_like, shape (n, d), or sequence of states
        The initial public states, one per row.
    sample : sequence of float, optional
        As for :func:`lyapunov_spectrum`, the same times for every orbit: the running
        estimates at those times instead of at the re-orthonormalisation times, from a QR of
        ``Phi`` read off the continuous output of each lane's chunks (``LaneLoad.samples`` of
        :mod:`taylorball.ensemble`, as :func:`megno_many`); the steps and re-orthonormalisations
        are those of the run without ``sample``, so the exponents are bit-identical.
    workers : int, optional
        Worker threads (default ``os.cpu_count()``; ``threads=`` is its deprecated old name).
    progress : bool
        A progress bar over orbits.

    Other parameters as for :func:`lyapunov_spectrum` (float64 only).

    Returns
    -------
    list of LyapunovSpectrum
        In the order of ``states``. An orbit whose integration fails is rerun alone by
        :func:`lyapunov_spectrum`, which raises the error.
    """
    prob, (states, t_end) = at_boundary("lyapunov_spectra", kind, params, (states, t_end), ("states", "t_end"))
    prob = lane_problem("lyapunov_spectra", prob)
    t0f, tf, rf, _ = _check_spectrum_args(t0, t_end, renorm, prob.spec)
    samples = _check_sample(sample, t0f, tf)
    n = prob.system.dim

    def start(internal):
        return _Benettin(prob, t0f, rf, internal), np.eye(n).reshape(-1)

    def rerun(state):  # lyapunov_spectrum raises the integration error (named by run_many)
        return lyapunov_spectrum(prob, state, t_end, t0=t0, renorm=renorm, sample=sample)

    return _fundamental_lanes(prob, states, t0f, tf, rf, samples, start=start,
                              finish=lambda acc, internal, x_end: acc.result(x_end, tf), rerun=rerun,
                              workers=workers, progress=f"Lyapunov spectra to t={tf:g}" if progress is True else progress,
                              func="lyapunov_spectra", one="lyapunov_spectrum")
