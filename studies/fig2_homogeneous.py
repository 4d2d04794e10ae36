"""Fig. 2: homogeneous ball, the section map and the contact point (Earnshaw's circle).

The study is :mod:`taylorball.figures.fig2_homogeneous` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/fig2_homogeneous.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import fig2_homogeneous as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
