"""Transport in the lifted angles from many orbits in the SIMD lanes (a resumable store).

The study is :mod:`taylorball.figures.diffusion_large` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/diffusion_large.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import diffusion_large as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
