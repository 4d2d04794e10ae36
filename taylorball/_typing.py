"""Type aliases shared by the annotations of the public API.

For annotations only. It imports nothing of the package but the parameter classes
(``params`` imports only ``errors``), so any module can import it without an import
circle, and the aliases resolve at run time too (``typing.get_type_hints``).
"""

from __future__ import annotations

import os
from typing import Any, Callable, Literal, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .params import BallParams, MParallelParams

__all__ = ["KindName", "FpTypeLike", "ParamsLike", "Scalar", "Vec3", "VecLike", "FloatOrArray", "SeedLike",
           "Direction", "ProgressLike", "PathLike", "StatesLike"]

#: A system of the paper by name (``taylorball.model.KINDS``).
KindName = Literal["full", "reduced", "mparallel"]

#: What ``fp_type=`` takes: ``float``, ``numpy.float64``, ``numpy.longdouble``,
#: ``heyoka.real128``, ``heyoka.real`` or one of their names (``"float"``, ``"longdouble"``,
#: ``"real128"``, ``"real"``); see :func:`taylorball.numbers.resolve_fp_type`.
FpTypeLike = Union[type, str]

#: A ball's parameters, or the M||gamma system's (``kind="mparallel"``).
ParamsLike = Union[BallParams, MParallelParams]

#: A scalar of any backend the formulas run on: a Python or numpy number or array (float64,
#: long double, heyoka ``real128`` / ``real``), a heyoka expression, an mpmath ``mpf`` or a
#: sympy expression (see ``taylorball._vec``). heyoka, mpmath and sympy have no type
#: information, so this is ``Any``.
Scalar = Any

#: A 3-vector as the formulas return it: a tuple of three backend scalars.
Vec3 = Tuple[Scalar, Scalar, Scalar]

#: A vector of backend scalars as the formulas accept it (a 3-vector, a state): a sequence
#: or a numpy array.
VecLike = Union[Sequence[Scalar], NDArray[Any]]

#: A real number, or a numpy array of them (functions that work elementwise).
FloatOrArray = Union[float, NDArray[Any]]

#: A random seed: ``None`` (fresh entropy), an integer, a numpy ``SeedSequence`` or ``Generator``.
SeedLike = Union[None, int, np.random.SeedSequence, np.random.Generator]

#: Crossing direction of a section: ``+1`` (g increasing), ``-1`` (decreasing), ``0`` (both).
Direction = Literal[-1, 0, 1]

#: ``progress=`` of the many-orbit functions (:func:`taylorball.ensemble.run_many`): ``False``
#: (none), ``True`` or a label (a tqdm bar over members), or a callable taking each increase
#: in fractions of a member.
ProgressLike = Union[bool, str, Callable[[float], Any]]

#: A file or folder: a string or an ``os.PathLike`` (``pathlib.Path``).
PathLike = Union[str, "os.PathLike[str]"]

#: Many initial states: a sequence of states or an array with one state per row.
StatesLike = Union[Sequence[ArrayLike], NDArray[Any]]
