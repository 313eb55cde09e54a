"""``python -m hystdisc`` runs the command-line interface."""

import sys

from hystdisc.cli import main

if __name__ == "__main__":  # importing the module (as documentation tools do) runs nothing
    sys.exit(main())
