r"""The variational equations of a system, built once: :class:`TangentSystem`.

For ``x' = f(x)`` a tangent vector ``delta`` follows ``delta' = J(x) delta``
(``J = df/dx``). A :class:`TangentSystem` is the system augmented with either

* ``vectors="one"``: one tangent vector, ``d' = J d`` (``n`` extra equations, so default
  mode stays affordable to compile), the product ``J d`` formed by ``jacobian``:
  ``"symbolic"`` (``hy.diff`` of every component of ``f`` by every variable, then
  ``sum_j (df_i/dx_j) d_j``) or ``"forward"`` (forward-mode differentiation: the vector
  field's own formula evaluated on dual numbers ``x + eps d``, so ``J d`` shares the
  field's intermediate results; for the reduced system with the MEGNO integrands 223
  elementary operations in heyoka's decomposition instead of 599, ~4x faster per step,
  the same values to rounding); optionally with the
  MEGNO/FLI integrands (``indicators=True``; :mod:`taylorball.chaos`):
  ``y' = t lambda``, ``w' = 2 y / t``, ``ell' = lambda`` with
  ``lambda = (d, J d) / (d, d)`` (``norm="full"``) or, with ``norm="compact"``, the same
  on the tangent vector's components on the compact part of the phase space
  (:attr:`taylorball.model.System.compact_indices`: ``P`` the projection on them,
  ``lambda_c = (P d, P J d) / (P d, P d)``; the tangent equation itself is unchanged); or
* ``vectors="all"``: the full set, the fundamental matrix ``Phi' = J Phi`` of
  ``hy.var_ode_sys(..., hy.var_args.vars, order=1)`` (``n^2`` extra equations; compact
  mode: ~2 s to compile instead of ~17 minutes). Used by the Liouville checks
  (``det Phi``) and the section-map Jacobian (:mod:`taylorball.verify`); the same
  layout serves a Lyapunov spectrum (Benettin et al.: integrate a chunk, replace ``Phi``
  by ``Q`` of its QR factorisation, accumulate ``ln |R_ii|``), scalar or in the lanes of
  :meth:`TangentSystem.batch_template`.

Layout of the augmented state (:attr:`x`, :attr:`tangents`, :attr:`indicators_slice`):
``x`` first (the system's internal variables), then the tangent vectors, then
``(y, w, ell)``. The tangent block holds the ``n x k`` matrix row-major: entry ``(i, j)``
is component ``i`` of tangent vector ``j`` (for ``"all"``, ``dx_i(t)/dx_j(0)``), so
:meth:`tangent_matrix` is a reshape and its columns are the tangent vectors.

Compiled objects go through :func:`taylorball._cache.compiled`; the key is the tag
``"tangent"`` (scalar) or ``"tangent_batch"`` (float64 batch), the variant (vectors,
indicators), the system and formulation, the number type and tolerance (scalar) or the
batch size (batch), and the compact mode. Callers never mutate a template: they
``copy.copy`` it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, List, Literal, Optional, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from .errors import UsageError
from ._problem import Problem
from .model import KIND_TABLE, System
from .numbers import FpSpec

__all__ = ["TangentSystem", "VECTORS", "NORMS", "JACOBIANS"]

#: The two variants: one tangent vector, or the full set (the fundamental matrix).
VECTORS = ("one", "all")

#: What the MEGNO/FLI integrands measure the tangent vector on: all of it, or its components
#: on the compact part of the phase space (without the contact point's unbounded directions).
NORMS = ("full", "compact")


#: How the product ``J d`` of ``vectors="one"`` is formed (see the module docstring).
JACOBIANS = ("forward", "symbolic")


class _Dual:
    """A dual number ``v + eps d`` (``eps**2 = 0``) over heyoka expressions: the vector field's
    formula (``+ - * /`` only, as every formula of :mod:`taylorball.model`) evaluated on
    ``x + eps d`` gives ``f(x)`` in :attr:`v` and the directional derivative ``J(x) d`` in
    :attr:`d`. A plain operand (a constant, a parameter expression) has derivative 0 and
    adds no operation to :attr:`d`."""

    __slots__ = ("v", "d")

    def __init__(self, v: Any, d: Any) -> None:
        self.v, self.d = v, d

    def __add__(self, o: Any) -> "_Dual":
        if isinstance(o, _Dual):
            return _Dual(self.v + o.v, self.d + o.d)
        return _Dual(self.v + o, self.d)

    def __radd__(self, o: Any) -> "_Dual":
        return _Dual(o + self.v, self.d)

    def __sub__(self, o: Any) -> "_Dual":
        if isinstance(o, _Dual):
            return _Dual(self.v - o.v, self.d - o.d)
        return _Dual(self.v - o, self.d)

    def __rsub__(self, o: Any) -> "_Dual":
        return _Dual(o - self.v, -self.d)

    def __neg__(self) -> "_Dual":
        return _Dual(-self.v, -self.d)

    def __mul__(self, o: Any) -> "_Dual":
        if isinstance(o, _Dual):
            return _Dual(self.v * o.v, self.d * o.v + self.v * o.d)
        return _Dual(self.v * o, self.d * o)

    def __rmul__(self, o: Any) -> "_Dual":
        return _Dual(o * self.v, o * self.d)

    def __truediv__(self, o: Any) -> "_Dual":
        if isinstance(o, _Dual):
            q = self.v / o.v
            return _Dual(q, (self.d - q * o.d) / o.v)
        return _Dual(self.v / o, self.d / o)

    def __rtruediv__(self, o: Any) -> "_Dual":
        q = o / self.v
        return _Dual(q, -(q * self.d) / self.v)


#: The systems whose tangent seeds are defined (their Kind lists tangent constraints).
SEED_KINDS = tuple(k for k, info in KIND_TABLE.items() if info.tangent_constraints)


@dataclass(frozen=True)
class TangentSystem:
    """A system with its variational equations (see the module docstring).

    Build it from a system (``TangentSystem(get_system("reduced"), "all")``) or a
    :class:`taylorball._problem.Problem` (:meth:`of`). It is cheap to build: the equations
    are formed and compiled only by :meth:`template` / :meth:`batch_template`, once per
    key per process.

    Attributes
    ----------
    system : taylorball.model.System
        The system in its formulation.
    vectors : {"one", "all"}
        One tangent vector, or the full set (the fundamental matrix).
    indicators : bool
        With the MEGNO/FLI integrands (``vectors="one"`` only).
    norm : {"full", "compact"}
        The stretching rate of the integrands from the whole tangent vector or from its
        components on :attr:`taylorball.model.System.compact_indices` (with indicators only).
    jacobian : {"symbolic", "forward"}
        How ``J d`` of ``vectors="one"`` is formed (module docstring): ``"symbolic"``
        (default here; the equations of earlier releases, bit for bit) or ``"forward"``.
    """

    system: System
    vectors: Literal["one", "all"] = "one"
    indicators: bool = False
    norm: str = "full"
    jacobian: str = "symbolic"

    def __post_init__(self) -> None:
        if self.vectors not in VECTORS:
            raise UsageError(f"vectors must be one of {VECTORS} (one tangent vector, or the full set), "
                             f"got {self.vectors!r}")
        if self.indicators and self.vectors != "one":
            raise UsageError("indicators=True (the MEGNO/FLI integrands) needs vectors='one', "
                             f"got vectors={self.vectors!r}")
        if self.norm not in NORMS:
            raise UsageError(f"norm must be one of {NORMS} (the whole tangent vector, or its components on the "
                             f"compact part of the phase space), got {self.norm!r}")
        if self.norm != "full" and not self.indicators:
            raise UsageError(f"norm={self.norm!r} applies to the MEGNO/FLI integrands: it needs indicators=True")
        if self.jacobian not in JACOBIANS:
            raise UsageError(f"jacobian must be one of {JACOBIANS} (how the tangent equation's J d is formed), "
                             f"got {self.jacobian!r}")
        if self.jacobian != "symbolic" and self.vectors != "one":
            raise UsageError(f"jacobian={self.jacobian!r} forms one tangent vector's J d: it needs vectors='one', "
                             f"got vectors={self.vectors!r}")

    @classmethod
    def of(cls, problem: Problem, vectors: Literal["one", "all"] = "one",
           indicators: bool = False, norm: str = "full", jacobian: str = "symbolic") -> "TangentSystem":
        """The tangent system of a problem's system."""
        return cls(problem.system, vectors, bool(indicators), norm, jacobian)

    @property
    def norm_indices(self) -> tuple:
        """Components of the tangent vector the indicators' stretching rate uses: all for
        ``norm="full"``, :attr:`taylorball.model.System.compact_indices` for ``"compact"``
        (all of them for M||gamma, whose phase space is compact)."""
        n = self.n
        return tuple(range(n)) if self.norm == "full" else tuple(self.system.compact_indices)

    # -- layout of the augmented state ------------------------------------------------------
    @property
    def n(self) -> int:
        """Dimension of the system."""
        return self.system.dim

    @property
    def n_vectors(self) -> int:
        """Tangent vectors carried: 1 or ``n``."""
        return 1 if self.vectors == "one" else self.n

    @property
    def size(self) -> int:
        """Length of the augmented state."""
        return self.n * (1 + self.n_vectors) + (3 if self.indicators else 0)

    @property
    def x(self) -> slice:
        """The system's state."""
        return slice(0, self.n)

    @property
    def tangents(self) -> slice:
        """The tangent vectors (row-major ``n x n_vectors``; see :meth:`tangent_matrix`)."""
        return slice(self.n, self.n * (1 + self.n_vectors))

    @property
    def indicators_slice(self) -> slice:
        """``(y, w, ell)``: MEGNO's ``int t lambda``, ``int 2 y / t`` and the FLI ``int lambda``."""
        self._need_indicators()
        return slice(self.n * (1 + self.n_vectors), self.size)

    @property
    def megno_y(self) -> int:
        self._need_indicators()
        return self.n * (1 + self.n_vectors)

    @property
    def megno_w(self) -> int:
        return self.megno_y + 1

    @property
    def fli(self) -> int:
        return self.megno_y + 2

    def _need_indicators(self):
        if not self.indicators:
            raise UsageError("this tangent system has no MEGNO/FLI integrands; build it with indicators=True")

    def tangent_matrix(self, state: ArrayLike) -> np.ndarray:
        """The tangent vectors of an augmented state as the columns of an ``(n, n_vectors)``
        view (``(n, n_vectors, lanes)`` for a batch state of shape ``(size, lanes)``)."""
        state = np.asarray(state)
        return state[self.tangents].reshape((self.n, self.n_vectors) + state.shape[1:])

    def identity(self, spec: FpSpec) -> np.ndarray:
        """``Phi(0) = E`` flattened for the tangent block of ``vectors="all"``, in ``spec``'s type."""
        if self.vectors != "all":
            raise UsageError("identity() is the initial fundamental matrix of vectors='all'")
        return spec.array(np.eye(self.n).reshape(-1))

    def seed(self, x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A random unit tangent vector (float64) to the constraint manifold at internal
        state ``x`` (tangent to first order: ``|gamma| = 1`` and, for the reduced system,
        ``(R, gamma) = 0``; for the full one the frame ``(alpha, beta, gamma)`` stays
        orthonormal, ``dv = xi x v``), by the Kind's ``tangent_constraints``.

        Parameters
        ----------
        x : array_like
            Internal state (any number type; the seed is float64).
        rng : numpy.random.Generator
            Draws ``n`` normal deviates, projected and normalised.
        """
        constraints = self.system.info.tangent_constraints
        if not constraints:
            raise UsageError(f"a tangent seed is defined for kinds {SEED_KINDS}, got kind={self.system.kind!r}")
        d = rng.normal(size=len(x))
        for project in constraints:
            project(x, d)
        return d / np.linalg.norm(d)

    # -- equations and compiled integrators --------------------------------------------------
    def equations(self) -> Union[List[Tuple[Any, Any]], Any]:
        """The augmented system (parameters ``hy.par[i]``): a list of heyoka ``(variable,
        rhs)`` pairs for ``vectors="one"``, a ``hy.var_ode_sys`` (its pairs in ``.sys``)
        for ``vectors="all"``; either is what ``hy.taylor_adaptive`` takes."""
        import heyoka as hy

        system = self.system
        if self.vectors == "all":
            return hy.var_ode_sys(system.equations(), hy.var_args.vars, order=1)
        xs = hy.make_vars(*system.internal_names)
        ds = hy.make_vars(*[f"d_{v}" for v in system.internal_names])
        pars = [hy.par[i] for i in range(system.n_pars)]
        if self.jacobian == "forward":
            out = system.rhs(pars, [_Dual(x, d) for x, d in zip(xs, ds)])
            # a component that does not depend on the state (none of the paper's) has J d = 0
            f = [o.v if isinstance(o, _Dual) else o for o in out]
            Jd = [o.d if isinstance(o, _Dual) else hy.expression(0.0) for o in out]
        else:
            f = list(system.rhs(pars, xs))
            Jd = [hy.sum([hy.diff(fi, xj) * dj for xj, dj in zip(xs, ds)]) for fi in f]
        eqs = list(zip(xs, f)) + list(zip(ds, Jd))
        if self.indicators:
            y, w, ell = hy.make_vars("megno_y", "megno_w", "fli")
            # the projection P keeps the listed components; P = E (norm="full", or a compact
            # phase space) gives the very same expression, hence the same compiled code
            idx = self.norm_indices
            Pd, PJd = [ds[i] for i in idx], [Jd[i] for i in idx]
            lam = hy.sum([d * jd for d, jd in zip(Pd, PJd)]) / hy.sum([d * d for d in Pd])
            t = hy.time
            eqs += [(y, t * lam), (w, 2.0 * y / t), (ell, lam)]
        return eqs

    def _variant(self):
        # the indices, not the name: norm="compact" of a compact phase space is norm="full"
        norm = () if not self.indicators or self.norm_indices == tuple(range(self.n)) else self.norm_indices
        jac = ("forward",) if self.jacobian == "forward" else ()  # "symbolic": the keys of earlier releases
        return (self.vectors, self.indicators, self.system.kind, self.system.formulation) + ((norm,) if norm else ()) + jac

    def _n_init(self) -> int:
        # var_ode_sys: heyoka sets Phi(0) = E itself when given only the n original values
        return self.n if self.vectors == "all" else self.size

    def template(self, problem: Problem, *, compact_mode: bool) -> Any:
        """The cached, compiled scalar integrator (do not mutate: ``copy.copy`` it).

        Parameters
        ----------
        problem : taylorball._problem.Problem
            Supplies the number type and tolerance (its system must be this one's).
        compact_mode : bool
            heyoka's compact mode (a per-client choice, measured: see its callers).
        """
        import heyoka as hy

        from ._cache import compiled

        if problem.system != self.system:
            raise UsageError(f"the problem's system {problem.kind}/{problem.formulation} is not this tangent "
                             f"system's {self.system.kind}/{self.system.formulation}")
        spec, tol, cm = problem.spec, problem.tol, bool(compact_mode)

        def build():
            zero = spec.scalar(0.0)
            kw = dict(fp_type=spec.fp_type, compact_mode=cm)
            if spec.prec is not None:
                kw["prec"] = spec.prec
                kw["time"] = zero
            if tol is not None:
                kw["tol"] = spec.scalar(tol)
            return hy.taylor_adaptive(self.equations(), [spec.scalar(0.1)] * self._n_init(),
                                      pars=[zero] * self.system.n_pars, **kw)

        return compiled(("tangent",) + self._variant() + (str(spec), tol, cm), build)

    def batch_template(self, *, compact_mode: bool, size: Optional[int] = None) -> Any:
        """The cached, compiled float64 batch integrator (do not mutate: ``copy.copy`` it),
        default tolerance, ``size`` lanes (default :func:`taylorball.sections.batch_size`)."""
        import heyoka as hy

        from ._cache import compiled

        if size is None:
            from .sections import batch_size

            size = batch_size()
        size, cm = int(size), bool(compact_mode)

        def build():
            return hy.taylor_adaptive_batch(self.equations(), np.full((self._n_init(), size), 0.1),
                                            pars=np.zeros((self.system.n_pars, size)), compact_mode=cm)

        return compiled(("tangent_batch",) + self._variant() + ("float", size, cm), build)
