"""Diffusion in the lifted angles on the Fig. 4 levels (resumable study stores).

The study is :mod:`taylorball.figures.diffusion` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/diffusion.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import diffusion as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
