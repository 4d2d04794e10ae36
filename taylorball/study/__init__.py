"""Your own long runs: a study file, its run store, and the runner.

The one long-run path, for every system: the reduced one (``[ball]``), the full one
(``[ball] system = "full"``) and M||gamma (``[mparallel]``).

A *study file* (TOML) names the ball, the level, the orbits, the run (end time, chunks,
number type, backend), the observables reduced on the fly (:mod:`taylorball.observables`)
and the store (:mod:`taylorball.store`)::

    [ball]
    inertia = [2.0, 3.0, 4.0]
    mass = 1.0
    radius = 5.0
    plane_rate = 2.0

    [level]            # caption form G, H, h; or C, M_gamma, h
    G = 10.0
    H = 2.0
    h = 5.0

    [orbits]
    n = 4              # drawn on the level's admissible region
    seed = 1

    [run]
    t_end = 2000.0
    checkpoint_every = 500.0

    [observables]
    extremes = true
    angles_every = 10.0
    sections = "all"

    [output]
    store = "runs/h2"

:func:`run_study` runs (or resumes, or extends) every orbit; :func:`study_status` reports
progress; :func:`open_run` reads the store as an ``xarray.Dataset``. The reference of every
key is in ``docs/longruns.md``.

Bits. An orbit's records depend on the problem (ball, number type, tolerance), its initial
state, ``checkpoint_every`` and ``sample_dt`` (each chunk is one ``propagate_grid`` on the
sample grid ``t_m = m * sample_dt`` whose last point is the chunk's end), never on which
observables are on (their events are non-terminal), the scalar backend, interruptions,
or ``t_end``: extending a run from ``T1`` to ``T2`` runs exactly the chunks a direct run to
``T2`` runs after ``T1``.

``backend = "lanes"`` (float64 only) runs the orbits in the SIMD lanes of heyoka batch
integrators (:func:`taylorball.ensemble.run_many` with ``backend="lanes"``), one per worker
thread, a lane refilled with the next orbit when its orbit is done; each chunk is one
batch ``propagate_grid`` on every lane's own grid, reduced and committed per orbit exactly
as above. A lane's bits depend only on its own orbit (not on the lane, the thread or the
other orbits), but they are not the scalar integrator's: the integrator family enters the
fingerprint, and a store is resumed only by the family that wrote it.
"""

from .config import BACKENDS, FP_TYPES, MAX_CHUNKS, MAX_ORBITS, MAX_SAMPLES_PER_CHUNK, StudyConfig, load_study
from .read import open_run
from .runner import Terminated, run_study
from .status import StudyStatus, study_status

__all__ = ["StudyConfig", "load_study", "run_study", "study_status", "open_run", "StudyStatus", "Terminated"]
