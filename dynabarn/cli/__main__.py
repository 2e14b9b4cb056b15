"""`python -m dynabarn.cli COMMAND ...`: the same as `python -m dynabarn COMMAND ...`."""

import sys

from dynabarn.cli.dispatch import main

if __name__ == "__main__":
    sys.exit(main(prog="python -m dynabarn.cli"))
