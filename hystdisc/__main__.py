"""``python -m hystdisc`` runs the command-line interface."""

import sys

from hystdisc.cli import main

sys.exit(main())
