"""``python -m jaxtrack``: the command line (``jaxtrack --help``)."""

import sys

from jaxtrack.cli import main

sys.exit(main())
