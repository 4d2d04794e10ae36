"""The chaos atlas: the chaotic fraction of the Fig. 4 levels against the plane's rotation rate.

The study is :mod:`taylorball.figures.chaos_atlas` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/chaos_atlas.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import chaos_atlas as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
