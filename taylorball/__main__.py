"""``python -m taylorball``: the ``taylorball`` command (:mod:`taylorball.cli`)."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
