"""`python -m dynabarn COMMAND ...`: any command without its installed script
(e.g. `python -m dynabarn run --world 137 --planner dwa`)."""

import sys

from dynabarn.cli.dispatch import main

if __name__ == "__main__":
    sys.exit(main())
