"""``python -m hystdisc`` runs the command-line interface."""

from hystdisc.cli import console

if __name__ == "__main__":  # importing the module (as documentation tools do) runs nothing
    console()
