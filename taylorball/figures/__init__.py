"""The paper's figures, regenerated from their captions: one module per figure and the
studies beyond them, and the runner that computes, saves and plots them.

* :mod:`~taylorball.figures.runner` -- :func:`run` (compute or load, save data and sidecar,
  plot), :func:`main` (the command line of the ``studies/`` scripts), :data:`FIGURES`;
* ``fig1_mparallel_map`` ... ``fig5_contact_point``, ``contact_diffusion`` -- each a frozen
  ``Config``, ``QUICK`` and ``FULL``, a pure ``compute(cfg)`` and a separate ``plot``
  (matplotlib is imported inside the plotting functions only);
* ``_common``, ``_fig_ball_map`` -- their shared parts.

``taylorball reproduce`` runs the figures; ``python studies/<name>.py`` in the checkout
runs one.
"""

from .runner import DEFAULT_OUT, FIGURES, STUDIES, figure_studies, load_study, main, run

__all__ = ["DEFAULT_OUT", "FIGURES", "STUDIES", "figure_studies", "load_study", "main", "run"]
