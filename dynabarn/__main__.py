"""`python -m dynabarn COMMAND ...`: any command without its installed script
(e.g. `python -m dynabarn run --world 137 --planner dwa`)."""

import sys

from dynabarn.processes import leave_the_current_folder_off_the_path

leave_the_current_folder_off_the_path()  # before anything else is imported

from dynabarn.cli.dispatch import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
