"""``python -m hmmtrack``: the command-line interface (:func:`hmmtrack.cli.main`)."""

import sys

from hmmtrack.cli import main

sys.exit(main())
