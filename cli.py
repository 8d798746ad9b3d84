"""Top-level shim: `python cli.py ...` behaves exactly like the `testbench` command."""

import sys

from testbench.cli import main

if __name__ == "__main__":
    sys.exit(main())
