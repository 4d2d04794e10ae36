r"""Charts of the paper: the section-4 variables (K, r1, r2, l, g) and Andoyer--Deprit.

Section 4 (reduced system, level set ``|M| = C``, ``(M, gamma) = M_gamma``):

.. math::
    K = M_3,\quad r_1 = R_1\gamma_1 + R_2\gamma_2,\quad r_2 = R_1\gamma_2 - R_2\gamma_1,\quad
    l = \operatorname{atan2}(M_1, M_2),\quad
    g = \operatorname{atan2}\big(C(M_2\gamma_1 - M_1\gamma_2),\ M_\gamma K - C^2\gamma_3\big),

with ``l, g`` taken in ``[0, 2 pi)``. The same ``g`` with ``M -> K``, ``C -> G = |K|``,
``M_gamma -> lambda`` is the Andoyer--Deprit angle of section 5.

The helpers here are backend-neutral (see :mod:`taylorball._vec`), so the same code gives
numbers and heyoka expressions (for event functions).
"""

from __future__ import annotations

from ._vec import dot, norm2, sqrt

__all__ = ["g_angle_parts", "section_event_function"]


def g_angle_parts(M, gamma):
    """Numerator and denominator of ``g`` (section 4): ``g = atan2(num, den)`` with
    ``num = C (M2 gamma1 - M1 gamma2)``, ``den = (M, gamma) M3 - C^2 gamma3``, where
    ``C = |M|``; both are of size ``C^2``."""
    C2 = norm2(M)
    num = sqrt(C2) * (M[1] * gamma[0] - M[0] * gamma[1])
    den = dot(M, gamma) * M[2] - C2 * gamma[2]
    return num, den


def section_event_function(M, gamma, g0: float = 0.0):
    r"""Event function of the section ``g = g0``, scaled to order 1.

    .. math:: e = \frac{\mathrm{num}\cos g_0 - \mathrm{den}\sin g_0}{C^2}
              = \frac{\sqrt{\mathrm{num}^2 + \mathrm{den}^2}}{C^2}\,\sin(g - g_0)

    It vanishes on ``g = g0`` and on ``g = g0 + pi``; the crossings of ``g = g0`` are those
    where ``(num sin g0 + den cos g0) > 0``. It increases through zero when ``g``
    increases through ``g0``. ``|e| <= 1`` since ``num^2 + den^2 <= C^4``."""
    import math

    num, den = g_angle_parts(M, gamma)
    C2 = norm2(M)
    return (num * math.cos(g0) - den * math.sin(g0)) / C2
