r"""Validated numerics for the paper's systems (optional extra ``rigorous``: python-flint).

* :func:`enclose`: a box that provably contains the solution at a time (Lohner's method on
  Taylor series in ball arithmetic, from the vector fields of :mod:`taylorball.model`);
* :mod:`taylorball.rigorous.section`: the section maps of the dynamically symmetric ball and of
  the M||gamma system and their C^1 enclosures (C^1 Lohner);
* :mod:`taylorball.rigorous.proofs`: Krawczyk proofs of periodic orbits and their certificates.

See ``docs/rigorous.md``.
"""

from __future__ import annotations

from .enclosure import Enclosure, enclose

__all__ = ["Enclosure", "enclose"]
