"""The skeleton of the Fig. 3 map: periodic orbits found by Newton on the section map.

The study is :mod:`taylorball.figures.skeleton` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/skeleton.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import skeleton as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
