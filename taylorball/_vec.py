"""Backend-neutral 3-vector algebra.

Every formula of the model is written once, on tuples of scalars, with the helpers below.
A "scalar" can be a heyoka expression (to build expression graphs), a numpy array or
scalar of any dtype heyoka supports (float64, longdouble, real128, real), an mpmath
``mpf`` or a sympy expression. Only ``+ - * /`` and the functions of this module are used
on them, so the same source serves compiled integration, vectorised numpy evaluation and
high-precision mpmath checks.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["dot", "cross", "add", "sub", "scale", "sqrt", "atan2", "norm2"]


def dot(u, v):
    """Euclidean inner product ``(u, v)``."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def norm2(u):
    """``(u, u)``."""
    return dot(u, u)


def cross(u, v):
    """Cross product ``u x v`` (right-handed)."""
    return (
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    )


def add(*vs):
    """Sum of 3-vectors."""
    return tuple(sum(c[1:], c[0]) for c in zip(*vs))


def sub(u, v):
    """``u - v``."""
    return (u[0] - v[0], u[1] - v[1], u[2] - v[2])


def scale(s, u):
    """``s u`` for a scalar ``s``."""
    return (s * u[0], s * u[1], s * u[2])


def _backend(x):
    mod = type(x).__module__ or ""
    if mod.startswith("heyoka"):
        import heyoka as hy

        if isinstance(x, hy.expression):
            return "heyoka"
        return "numpy"  # heyoka's real / real128 scalars work with numpy ufuncs
    if mod.startswith("mpmath"):
        return "mpmath"
    if mod.startswith("sympy"):
        return "sympy"
    return "numpy"


def sqrt(x):
    """Square root in the backend of ``x``."""
    backend = _backend(x)
    if backend == "heyoka":
        import heyoka as hy

        return hy.sqrt(x)
    if backend == "mpmath":
        import mpmath

        return mpmath.sqrt(x)
    if backend == "sympy":
        import sympy

        return sympy.sqrt(x)
    if isinstance(x, float):
        return math.sqrt(x)
    return np.sqrt(x)


def atan2(y, x):
    """Four-quadrant ``atan2(y, x)`` in the backend of its arguments."""
    backend = _backend(y) if _backend(y) != "numpy" else _backend(x)
    if backend == "heyoka":
        import heyoka as hy

        return hy.atan2(y, x)
    if backend == "mpmath":
        import mpmath

        return mpmath.atan2(y, x)
    if backend == "sympy":
        import sympy

        return sympy.atan2(y, x)
    return np.arctan2(y, x)
