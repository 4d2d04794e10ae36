"""A bifurcation diagram of periodic orbits in Omega (M||gamma map from 0 to 2, Tzenoff's case from 3 down).

The study is :mod:`taylorball.figures.skeleton_bifurcation` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/skeleton.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import skeleton_bifurcation as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
