r"""Charts of the paper: the section-4 variables (K, r1, r2, l, g) and Andoyer--Deprit.

Section 4 (reduced system, level set ``|M| = C``, ``(M, gamma) = M_gamma``):

.. math::
    K = M_3,\quad r_1 = R_1\gamma_1 + R_2\gamma_2,\quad r_2 = R_1\gamma_2 - R_2\gamma_1,\quad
    l = \operatorname{atan2}(M_1, M_2),\quad
    g = \operatorname{atan2}\big(C(M_2\gamma_1 - M_1\gamma_2),\ M_\gamma K - C^2\gamma_3\big),

with ``l, g`` taken in ``[0, 2 pi)``. The same ``g`` with ``M -> K``, ``C -> G = |K|``,
``M_gamma -> lambda`` is the Andoyer--Deprit angle of section 5.

Contents:

* the angle ``g`` and the section's event function, backend-neutral (see
  :mod:`taylorball._vec`: the same code gives numbers and heyoka expressions);
* the section-4 chart and its inverse (numpy): :func:`reduced_chart`,
  :func:`reduced_state_from_chart`, and :func:`states_on_section`, which solves the energy
  equation for every root ``K``; :func:`section_admissible_sample` samples the region of
  ``(l, r1, r2)`` that carries states;
* the Andoyer--Deprit chart of section 5 (corrected: erratum E3) and its inverse with ``G``
  from the energy: :func:`mparallel_chart`, :func:`mparallel_state_from_chart`,
  :func:`mparallel_states_on_section`.

Singular sets (clear :class:`~taylorball.errors.ChartError` there): ``M`` along the body
axis e3 (``l``, ``g`` undefined), ``M`` parallel to ``gamma`` (``g`` undefined; the M||gamma
case), and for the inverse ``|gamma3|`` or ``|(gamma1, gamma2)|`` below
:data:`CHART_SINGULAR_TOL` (``R`` not determined by ``(r1, r2)``).
"""

from __future__ import annotations

# The charts live in four modules by job; they are public here, where they are documented.
from ._chart_reduced import (CHART_SINGULAR_TOL, R_from_r, andoyer_deprit_printed, angles_to_vectors,  # noqa: F401
                             g_angle_parts, reduced_chart, reduced_state_from_chart, section_event_function,
                             states_on_section)
from ._chart_reduced import (_SIGMA_DTHETA, _ball, _check_direction, _check_g0, _check_grid,  # noqa: F401
                             _check_h, _check_levels, _check_point, _degenerate_K, _grid_brackets, _orientation,
                             _reduced_energy_theta, _rng, _roots_1d, _roots_many, _section_states, _sheet_labels,
                             _sheet_poles, _side, _wrap)
from ._chart_sampling import section_admissible_sample, section_sigma, section_sigma_sample  # noqa: F401
from ._chart_sheets import section_sheet  # noqa: F401
from ._chart_mparallel import (mparallel_chart, mparallel_state_from_chart,  # noqa: F401
                               mparallel_states_on_section)


__all__ = [
    "g_angle_parts",
    "section_event_function",
    "angles_to_vectors",
    "andoyer_deprit_printed",
    "R_from_r",
    "reduced_state_from_chart",
    "reduced_chart",
    "states_on_section",
    "section_admissible_sample",
    "section_sheet",
    "section_sigma",
    "section_sigma_sample",
    "mparallel_chart",
    "mparallel_state_from_chart",
    "mparallel_states_on_section",
    "CHART_SINGULAR_TOL",
]

