r"""The constraint manifolds: validation, projection, and the full <-> reduced maps.

Constraint surfaces (their values are fixed by geometry, not by initial conditions):

* full: ``(alpha, beta, gamma)`` orthonormal and right-handed (``Q in SO(3)``);
* reduced: ``gamma^2 = 1``, ``(R, gamma) = 0``;
* mparallel: ``gamma^2 = 1``.

A state is *on* the manifold when every residual is below ``constraint_tol`` (default
``sqrt(eps)/10`` of the input's number type, relative to the natural scale: 1.5e-9 for
float64). That separates the rounding and drift of a computed state (1e-16 .. 1e-11) from
a state that was never on the manifold (a user's unnormalised ``gamma``). States within
the tolerance are accepted and *snapped* onto the manifold in the working precision by
:func:`project` (a change of the size of the residual); states beyond it are rejected with
:class:`~taylorball.errors.ConstraintError` unless ``project=True`` is asked for.
"""

from __future__ import annotations

import math
from typing import Any, Dict, Literal, Optional, overload

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from ._typing import KindName, ParamsLike
from ._vec import add, scale
from .errors import ConstraintError, StateError
from .model import KIND_TABLE, PUBLIC_NAMES, _project_array, get_system, lift_reduced
from .numbers import real_number
from .params import BallParams, MParallelParams

__all__ = [
    "params_for",
    "as_state",
    "constraint_residuals",
    "project",
    "default_constraint_tol",
    "full_to_reduced",
    "reduced_to_full",
]


@overload
def params_for(kind: Literal["full", "reduced"], params: object) -> BallParams: ...
@overload
def params_for(kind: Literal["mparallel"], params: object) -> MParallelParams: ...
@overload
def params_for(kind: KindName, params: object) -> ParamsLike: ...
def params_for(kind: KindName, params: object) -> ParamsLike:
    """Check that ``params`` fits ``kind``; converts BallParams for ``"mparallel"``."""
    return get_system(kind).check_params(params)


def as_state(kind: KindName, state: ArrayLike, *, params: Optional[ParamsLike] = None, check: bool = True,
             constraint_tol: Optional[float] = None) -> np.ndarray:
    """Validate a public state (or a stack of them) and return it as a numpy array.

    The dtype is kept when heyoka supports it (float64, long double, real128, real);
    integers become float64.

    Raises
    ------
    StateError
        Wrong length, non-numeric or non-finite entries.
    ConstraintError
        With ``check=True``, a residual of the constraints beyond ``constraint_tol``.
    """
    import heyoka as hy

    get_system(kind)  # an unknown kind is a UsageError
    if constraint_tol is not None:  # checked first: a bad tolerance is not the state's fault
        real_number("constraint_tol", constraint_tol, lo=0.0, lo_open=True)
    names = PUBLIC_NAMES[kind]
    try:
        x = np.asarray(state)
    except Exception as exc:  # pragma: no cover - numpy raises many types
        raise StateError(f"state must be an array of {len(names)} numbers {names}, got {state!r}") from exc
    if x.dtype.kind in "iub":
        x = x.astype(np.float64)
    ok_dtypes = (np.dtype(np.float64), np.dtype(np.longdouble), np.dtype(hy.real128), np.dtype(hy.real))
    if x.dtype not in ok_dtypes:
        if x.dtype == object:
            try:
                x = x.astype(np.float64)
            except (TypeError, ValueError):
                raise StateError(f"state entries must be real numbers, got {state!r}") from None
        elif x.dtype.kind == "f":
            x = x.astype(np.float64)
        else:
            raise StateError(f"state must be an array of real numbers, got dtype {x.dtype} ({state!r})")
    if x.ndim == 0 or x.shape[-1] != len(names):
        raise StateError(
            f"state for kind={kind!r} must have {len(names)} entries {names} (shape ({len(names)},) or "
            f"(n, {len(names)})), got shape {x.shape}"
        )
    if x.dtype.kind == "f":
        finite = bool(np.all(np.isfinite(x)))
    else:
        finite = all(math.isfinite(float(v)) for v in x.reshape(-1))
    if not finite:
        raise StateError(f"state for kind={kind!r} has non-finite entries: {x!r}")
    if check:
        tol = default_constraint_tol(x.dtype) if constraint_tol is None else real_number(
            "constraint_tol", constraint_tol, lo=0.0, lo_open=True)
        res = constraint_residuals(kind, x)
        for name, r in res.items():
            worst = float(np.max(np.abs(np.asarray(r, dtype=float))))
            if not worst <= tol:
                raise ConstraintError(
                    f"state is off the constraint manifold of kind={kind!r}: {name} residual {worst:.3g} "
                    f"> constraint_tol={tol:.3g}. Valid states have "
                    + KIND_TABLE[kind].manifold_text
                    + "; pass project=True to project it, or fix the state"
                )
        orientation = KIND_TABLE[kind].orientation
        if orientation is not None:
            det = orientation(_cols(x))
            if np.any(np.asarray(det, dtype=float) <= 0):
                raise ConstraintError(
                    "state for kind='full': (alpha, beta, gamma) is left-handed (det Q < 0); the rows "
                    "of Q in SO(3) must satisfy alpha x beta = gamma"
                )
    return x


def default_constraint_tol(dtype: DTypeLike) -> float:
    """``sqrt(eps)/10`` of ``dtype`` (1.5e-9 for float64): above rounding and integrator
    drift of computed states, far below the error of a state that was never on the
    manifold."""
    import heyoka as hy

    if dtype == np.dtype(hy.real):
        return 1.5e-9  # a real array's elements may have any precision; use float64's
    if dtype == np.dtype(hy.real128):
        return math.sqrt(2.0**-112) / 10
    return math.sqrt(float(np.finfo(dtype).eps)) / 10


def _cols(x):
    return tuple(x[..., i] for i in range(x.shape[-1]))


def constraint_residuals(kind: KindName, x: ArrayLike) -> Dict[str, Any]:
    """Residuals of the geometric constraints at public state(s) ``x``, each relative to
    its natural scale (``(R, gamma)`` relative to ``|R| |gamma|``)."""
    return KIND_TABLE[kind].constraints(_cols(np.asarray(x)))


def project(kind: KindName, state: ArrayLike) -> np.ndarray:
    """Project public state(s) onto the constraint manifold, in the state's own dtype.

    * reduced: ``gamma <- gamma/|gamma|``, then ``R <- R - (R, gamma) gamma``;
    * full: Gram--Schmidt starting from ``gamma`` (the contact normal is kept exactly in
      direction), ``alpha <- unit(alpha - (alpha, gamma) gamma)``,
      ``beta <- gamma x alpha``; a left-handed frame is rejected;
    * mparallel: ``gamma <- gamma/|gamma|``.

    Angular velocity (or ``K``) and ``x, y`` are left as they are. ``state`` may be one
    state ``(d,)`` or a stack ``(n, d)``.

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> from taylorball.paper import demo_reduced_state
    >>> x = demo_reduced_state()
    >>> x[3:6] *= 1.01                             # gamma off the unit sphere
    >>> y = tb.project("reduced", x)
    >>> bool(abs(np.linalg.norm(y[3:6]) - 1) < 1e-15), bool(abs(y[3:6] @ y[6:9]) < 1e-15)
    (True, True)
    >>> bool((y[:3] == x[:3]).all())               # omega is left as it is
    True
    """
    get_system(kind)  # a clear error for an unknown kind
    return _project_array(KIND_TABLE[kind], as_state(kind, state, check=False))


# ---------------------------------------------------------------------------------------
# Full <-> reduced.
# ---------------------------------------------------------------------------------------
def full_to_reduced(state: ArrayLike) -> np.ndarray:
    """``(omega, alpha, beta, gamma, x, y) -> (omega, gamma, R)`` with
    ``R = x alpha + y beta`` (paper eq. (1) [eq1]). Works on one state or a stack; keeps the dtype."""
    x = np.asarray(state)
    c = _cols(x)
    R = add(scale(c[12], c[3:6]), scale(c[13], c[6:9]))
    out = np.empty(x.shape[:-1] + (9,), dtype=x.dtype)
    for i, v in enumerate((*c[0:3], *c[9:12], *R)):
        out[..., i] = v
    return out


def reduced_to_full(params: BallParams, state: ArrayLike, *, psi: float = 0.0) -> np.ndarray:
    r"""Lift a reduced state to the full system (section 3).

    The fixed frame is fixed only up to a rotation about the vertical (the symmetry
    ``u_s``, paper eq. (14) [eq9]). With ``psi = 0`` it is the frame where ``F1 = (M, alpha) = 0`` and
    ``F2 = (M, beta) > 0``:

    .. math::
        \beta = \frac{M - M_\gamma \gamma}{\sqrt{C^2 - M_\gamma^2}},\quad
        \alpha = \beta\times\gamma = \frac{M\times\gamma}{\sqrt{C^2 - M_\gamma^2}},\quad
        x = (\alpha, R),\ y = (\beta, R);

    the paper prints ``\dot\alpha``, ``\dot\beta`` on the left (an erratum, see
    ``docs/errata.md``). ``psi`` rotates that frame by ``psi`` about the vertical:
    ``alpha <- cos(psi) alpha + sin(psi) beta``, ``beta <- -sin(psi) alpha + cos(psi) beta``.
    ``state`` may be one state ``(9,)`` or a stack ``(n, 9)`` (then each state uses its
    own ``M``; along an orbit they differ only by the drift of the integrals).

    Raises
    ------
    ChartError
        When ``M`` is parallel to ``gamma`` (``C^2 = M_gamma^2``): the frame is undefined.

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> x0 = demo_reduced_state()
    >>> full = tb.reduced_to_full(FIG4_BALL, x0)  # (omega, alpha, beta, gamma, x, y)
    >>> full.shape
    (14,)
    >>> f = tb.integrals("full", FIG4_BALL, full)
    >>> bool(abs(f["F1"]) < 1e-12), bool(f["F2"] > 0)   # the frame with psi = 0
    (True, True)
    >>> bool(abs(f["E"] - tb.integrals("reduced", FIG4_BALL, x0)["E"]) < 1e-12)
    True
    >>> bool(np.allclose(tb.full_to_reduced(full), x0, rtol=0, atol=1e-14))   # and back
    True
    """
    params = params_for("reduced", params)
    psi = real_number("psi (an angle)", psi)
    return lift_reduced(params, as_state("reduced", state, check=True), psi=psi)
