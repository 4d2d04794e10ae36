"""Fig. 3: dynamically symmetric ball, the section map (a chaotic orbit) and a contact point.

The study is :mod:`taylorball.figures.fig3_symmetric` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/fig3_symmetric.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import fig3_symmetric as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
