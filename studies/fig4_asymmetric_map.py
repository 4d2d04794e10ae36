"""Fig. 4: the 3D Poincaré map of the dynamically asymmetric ball, H = 2 and H = 6.

The study is :mod:`taylorball.figures.fig4_asymmetric_map` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/fig4_asymmetric_map.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import fig4_asymmetric_map as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
