r"""The Andoyer--Deprit chart of the M || gamma system (paper section 5; public from
:mod:`taylorball.charts`): :func:`mparallel_chart`, :func:`mparallel_state_from_chart`,
:func:`mparallel_states_on_section`.
"""

from __future__ import annotations

import math as _math
from typing import Any, Dict, Sequence

import numpy as _np
from numpy.typing import ArrayLike

from ._chart_reduced import (_check_g0, _check_grid, _check_h, _check_point, _roots_1d, _wrap, angles_to_vectors,
                             g_angle_parts)
from ._typing import FloatOrArray, ParamsLike
from ._vec import dot, norm2
from .errors import ChartError, EmptyLevelError
from .numbers import real_number


# ---------------------------------------------------------------------------------------
# Section 5: the Andoyer--Deprit chart of the M || gamma system.
# ---------------------------------------------------------------------------------------
def mparallel_chart(state: ArrayLike) -> Dict[str, Any]:
    """Andoyer--Deprit coordinates of mparallel state(s) ``(K, gamma)``: ``dict`` with
    ``L = K3``, ``G = |K|``, ``l = atan2(K1, K2)``, ``g`` (the section-4 formula with
    ``M -> K``, ``C -> G``, ``M_gamma -> lambda``), ``L/G`` and ``lambda = (K, gamma)``.

    Raises
    ------
    ChartError
        Where ``K`` is along e3 (``l`` undefined) or parallel to ``gamma``.
    """
    from .manifold import as_state

    x = _np.asarray(as_state("mparallel", state), dtype=float)
    K, gamma = tuple(x[..., i] for i in range(3)), tuple(x[..., i] for i in range(3, 6))
    G2 = norm2(K)
    G = _np.sqrt(G2)
    num, den = g_angle_parts(K, gamma)
    if _np.any(_np.hypot(K[0], K[1]) <= 1e-12 * G) or _np.any(_np.hypot(num, den) <= 1e-12 * G2):
        raise ChartError("the Andoyer-Deprit chart is singular here: K along e3 or K parallel to gamma")
    return {"L": K[2], "G": G, "l": _wrap(_np.arctan2(K[0], K[1])), "g": _wrap(_np.arctan2(num, den)),
            "L/G": K[2] / G, "lambda": dot(K, gamma)}


def mparallel_state_from_chart(*, lam: float, L: FloatOrArray, G: FloatOrArray, l: FloatOrArray,
                               g: FloatOrArray) -> _np.ndarray:
    """mparallel state(s) ``(K, gamma)`` from Andoyer--Deprit variables (corrected chart,
    erratum E3): ``|gamma| = 1`` and ``(K, gamma) = lambda`` hold identically.

    Raises
    ------
    ChartError
        Unless ``G > |lambda|`` and ``|L| <= G``.
    """
    G_arr = _np.asarray(G, dtype=float)
    if _np.any(~(G_arr > abs(lam))) or _np.any(_np.abs(_np.asarray(L, dtype=float)) > G_arr):
        raise ChartError(f"Andoyer-Deprit variables need G > |lambda| = {abs(lam)!r} and |L| <= G, got "
                         f"G = {G!r}, L = {L!r}")
    Ks, gamma = angles_to_vectors(G_arr, lam, L, l, g)
    return _np.stack(_np.broadcast_arrays(*Ks, *gamma), axis=-1)


def _mparallel_energy_mu(params, lam, ratio, l, g, mu):
    """``Etilde`` on the chart point ``(l, L/G = ratio)`` at ``g``, with ``G = lambda/mu``,
    written as ``Etilde = G^2 Q(mu)``: returns ``Q`` (homogeneity of degree 2 in K)."""
    from .model import mparallel_constants

    c = mparallel_constants(params.pars)
    Khat, gamma = angles_to_vectors(1.0, mu, ratio, l, g)  # C = 1: K/G and gamma at mu = lambda/G
    AK = tuple(c.A[i] * Khat[i] for i in range(3))
    D = 1 - c.d * dot(gamma, tuple(c.A[i] * gamma[i] for i in range(3)))
    return dot(Khat, AK) / 2 - norm2(Khat) / (2 * c.d) + c.d * dot(AK, gamma) ** 2 / (2 * D)


def mparallel_states_on_section(params: ParamsLike, *, lam: float, h: float, point: Sequence[float],
                                g0: float = 0.0, n_grid: int = 4001) -> _np.ndarray:
    r"""Every M||gamma state with ``(K, gamma) = lambda``, ``Etilde = h`` and
    Andoyer--Deprit chart point ``point = (l, L/G)`` on the section ``g = g0``.

    ``Etilde`` is homogeneous of degree 2 in ``K`` for fixed ``gamma``; on the chart,
    ``gamma`` depends on ``G`` only through ``mu = lambda/G``, so ``Etilde = G^2 Q(mu)``
    and the energy equation becomes ``lambda^2 Q(mu) = h mu^2`` for ``mu`` in ``(0, 1)``
    (``lambda > 0``; mirrored for ``lambda < 0``): a smooth equation on a bounded interval,
    solved like :func:`states_on_section`. For ``lambda = 0``, ``G = sqrt(h / Q(0))``.

    Returns
    -------
    ndarray, shape (n, 6)
        States ``(K, gamma)`` ordered by ``G``.

    Raises
    ------
    ChartError, EmptyLevelError
    """
    from .manifold import params_for

    params = params_for("mparallel", params)
    l, ratio = _check_point(point, 2, "(l, L/G)")
    if not -1.0 <= ratio <= 1.0:
        raise ChartError(f"L/G must lie in [-1, 1], got {ratio!r}")
    g0 = _check_g0(g0)
    lam, h = real_number("lam", lam, error=ChartError), _check_h(h)
    n_grid = _check_grid(n_grid)
    if lam == 0.0:
        Q = float(_mparallel_energy_mu(params, 0.0, ratio, l, g0, _np.array(0.0)))
        Gs = _np.array([_math.sqrt(h / Q)]) if Q != 0 and h / Q > 0 else _np.empty(0)
    else:
        sgn = 1.0 if lam > 0 else -1.0

        def f(mu_abs):
            mu = sgn * mu_abs
            return lam * lam * _mparallel_energy_mu(params, lam, ratio, l, g0, mu) - h * mu * mu

        # mu = 1 is G = |lambda| (K || gamma); mu -> 0 is G -> infinity
        roots, _ = _roots_1d(f, 0.0, 1.0, n_grid)
        roots = roots[(roots > 0) & (roots < 1)]
        Gs = _np.sort(abs(lam) / roots)
    if Gs.size == 0:
        raise EmptyLevelError(
            f"no M||gamma state has chart point (l, L/G) = {point!r} on g = {g0!r} with lambda = {lam!r}, "
            f"Etilde = {h!r}: the energy equation has no root G > |lambda|"
        )
    return _np.stack([mparallel_state_from_chart(lam=lam, L=ratio * G, G=G, l=l, g=g0) for G in Gs])
