"""``python -m jaxtrack.cli``: the same as the ``jaxtrack`` command."""

import sys

from jaxtrack.cli import main

sys.exit(main())
