"""Fig. 1: the Poincaré map of the M||gamma system on g = 0, in (l, L/G).

The study is :mod:`taylorball.figures.fig1_mparallel_map` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/fig1_mparallel_map.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import fig1_mparallel_map as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
