"""`python -m testbench ...` behaves exactly like the `testbench` command (and `python cli.py`):
for an environment whose scripts folder is not on PATH, or to pick the interpreter explicitly."""

import sys

from testbench.cli import main

if __name__ == "__main__":
    sys.exit(main())
