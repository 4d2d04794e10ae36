"""The cores of the Fig. 4b tori: two invariant circles of the 3D section map.

The study is :mod:`taylorball.figures.skeleton_tori` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/skeleton_tori.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import skeleton_tori as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
