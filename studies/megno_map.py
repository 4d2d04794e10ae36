"""MEGNO map of the Fig. 4b level (H = 6) in a slice l = const, with invariant curves over it.

The study is :mod:`taylorball.figures.megno_map` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/megno_map.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import megno_map as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
