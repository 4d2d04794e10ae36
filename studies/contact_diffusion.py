"""Does the contact point diffuse? Long runs of the Fig. 4/5 ball (resumable).

The study is :mod:`taylorball.figures.contact_diffusion` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/contact_diffusion.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.
"""

import sys
from pathlib import Path

from taylorball.figures import contact_diffusion as study
from taylorball.figures.runner import main

if __name__ == "__main__":
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
