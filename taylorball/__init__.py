"""taylorball: high-precision Taylor integration of the Chaplygin ball on a rotating plane.

The science is Bizyaev, Borisov & Mamaev, *Dynamics of the Chaplygin ball on a rotating
plane*. Three layers (imports point one way, see ``docs/design.md``): the core (this
package's modules), the checks of the paper (:mod:`taylorball.verify`, imported on first
use) and the figures (:mod:`taylorball.figures`, with one thin script each in ``studies/``).

The names below are the public API. Modules whose name starts with ``_`` are
implementation; a public function never shares its name with a module, so
``taylorball.integrals`` is always the function.
"""

import logging as _logging

from .errors import (
    ChartError,
    ConstraintError,
    EmptyLevelError,
    IntegrationError,
    ParameterError,
    StateError,
    StoreError,
    TaylorballError,
    UsageError,
)
from ._integrals import density, geometric_integrals, integral_expressions, integral_scales, integrals, integrals_mp
from .manifold import full_to_reduced, project, reduced_to_full
from .model import PUBLIC_NAMES, get_system
from .params import BallParams, MParallelParams, UnphysicalParametersWarning
from ._problem import Problem, problem
from ._propagate import make_integrator, propagate
from .sections import Outcome, Section, SectionOptions, SectionResult, poincare_section, poincare_sections
from .chaos import ChaosIndicators, MegnoOptions, megno, megno_many
from .chaos import LyapunovSpectrum, lyapunov_spectra, lyapunov_spectrum
from .chaos import GALI, gali, gali_many
from .periodic import NewtonFailure, NewtonOptions, PeriodicOrbit, periodic_orbit
from .periodic_search import SearchOptions, periodic_orbits
from ._atlas import ChaoticFraction, chaotic_fraction
from .maps import MegnoMapOptions, megno_map
from .ensemble import MemberFailure, run_many
from .levels import Levels, MParallelLevels
from .study import StudyConfig, StudyStatus, load_study, open_run, run_study, study_status
from .contact import ContactTrajectory, contact_trajectory
from .charts import (
    mparallel_chart,
    mparallel_states_on_section,
    reduced_chart,
    section_admissible_sample,
    section_sheet,
    section_sigma,
    section_sigma_sample,
    states_on_section,
)
from .closed_forms import psi, psi_mp, symmetric_integral
from . import transport  # noqa: F401  (tb.transport.msd, ...: numpy only)


_STUDY = ("a study, the one long-run path: tb.StudyConfig.from_problem(problem, states=..., t_end=..., "
          "checkpoint_every=..., store=...) and tb.run_study (or a study file and `taylorball run`), read by "
          "tb.open_run")
_NPZ = "; CHANGELOG.md (\"Moving an npz long run\") says how to rerun or read an old npz run folder"
#: Names removed in 0.1.0 (the npz long-run path), each with what to use instead.
_REMOVED = {
    "long_run": "use " + _STUDY + _NPZ,
    "load_long_run": "a study's store is read by tb.open_run (an xarray.Dataset)" + _NPZ,
    "LongRunConfig": "use tb.StudyConfig (tb.StudyConfig.from_problem(problem, ...) or a study file)" + _NPZ,
    "LongRunResult": "tb.open_run(store) returns an xarray.Dataset of a study's records" + _NPZ,
    "run_ensemble": ("use tb.run_many([taylorball.ensemble.call(fn, x) for x in items], backend=..., "
                     "workers=...), or " + _STUDY),
    "longrun": "the module is gone: long runs are studies (taylorball.study)" + _NPZ,
}


def __getattr__(name):
    # the checks layer (taylorball.verify) is imported on first use, never by `import taylorball`
    if name in ("liouville", "liouville_residual"):
        from .verify import invariant_measures

        return getattr(invariant_measures, name)
    if name in _REMOVED:
        raise AttributeError(f"taylorball.{name} was removed in 0.1.0 with the npz long-run path: {_REMOVED[name]}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


from ._version import __version__  # noqa: E402

# a library does not configure logging: silent unless the application (e.g. the
# `taylorball` command) installs a handler on the "taylorball" logger or the root logger
_logging.getLogger("taylorball").addHandler(_logging.NullHandler())

__all__ = [
    "PeriodicOrbit", "NewtonFailure", "NewtonOptions", "periodic_orbit", "periodic_orbits", "SearchOptions",
    "__version__",
    "problem",
    "Problem",
    "Section",
    "Outcome",
    "megno",
    "megno_many",
    "MegnoOptions",
    "ChaoticFraction",
    "chaotic_fraction",
    "ChaosIndicators",
    "lyapunov_spectrum",
    "LyapunovSpectrum",
    "lyapunov_spectra",
    "megno_map",
    "MegnoMapOptions",
    "GALI",
    "gali",
    "gali_many",
    "run_many",
    "MemberFailure",
    "Levels",
    "MParallelLevels",
    "StudyConfig",
    "StudyStatus",
    "load_study",
    "run_study",
    "study_status",
    "open_run",
    "BallParams",
    "MParallelParams",
    "UnphysicalParametersWarning",
    "PUBLIC_NAMES",
    "get_system",
    "propagate",
    "make_integrator",
    "integrals",
    "integral_scales",
    "integrals_mp",
    "integral_expressions",
    "geometric_integrals",
    "density",
    "project",
    "full_to_reduced",
    "reduced_to_full",
    "poincare_section",
    "poincare_sections",
    "SectionResult",
    "SectionOptions",
    "contact_trajectory",
    "ContactTrajectory",
    "states_on_section",
    "section_admissible_sample",
    "section_sheet",
    "section_sigma",
    "section_sigma_sample",
    "reduced_chart",
    "mparallel_chart",
    "mparallel_states_on_section",
    "psi",
    "psi_mp",
    "symmetric_integral",
    "liouville",
    "liouville_residual",
    "TaylorballError",
    "ParameterError",
    "StateError",
    "ConstraintError",
    "ChartError",
    "EmptyLevelError",
    "IntegrationError",
    "UsageError",
    "StoreError",
]
