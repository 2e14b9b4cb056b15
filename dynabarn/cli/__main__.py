"""`python -m dynabarn.cli COMMAND ...`: any command without its installed script
(e.g. `python -m dynabarn.cli run --world 137 --planner dwa`)."""

import sys

from dynabarn import cli

COMMANDS = {name.removesuffix("_main"): getattr(cli, name) for name in cli.__all__}

if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1] not in COMMANDS:
        print(f"usage: python -m dynabarn.cli {{{','.join(COMMANDS)}}} ...", file=sys.stderr)
        sys.exit(2)
    sys.exit(COMMANDS[sys.argv[1]](sys.argv[2:]))
