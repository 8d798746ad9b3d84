"""The `testbench` command line. Subcommands live in testbench/commands/.

Prints to stdout/stderr (library code only logs). User mistakes -> one line on stderr and exit
status 2; an aborted simulation -> 4; a failed threshold -> 3; an internal error -> 1 with the
traceback (that is a bug to report).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
import traceback

# numpy asks the kernel for transparent huge pages (madvise) on every array of 4 MB or more.
# A run allocates and frees such arrays every frame (camera frames, ortho views, remap tables),
# and each new one is then faulted in and zeroed 2 MB at a time: 14 % of a paper_ismn_800m
# run's CPU samples (perf: clear_page_erms), its system time 3.4-4.2 s against 1.7 s without,
# its real-time factor 5.4-5.7 against 6.0-6.9 (docs/measurements.md, "Scene matching,
# latency and speed"). numpy reads the variable when it is imported, so it is set here,
# before any subcommand imports numpy; a value the user set is kept. It changes no number
# (the pages' size, not the arrays' addresses or contents). numpy issue 31590 discusses the
# same advice's costs.
os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")

from testbench import __version__
from testbench.core.errors import EXIT_INTERNAL, InputError, TestbenchError
from testbench.core.heap import keep_freed_memory

# One module per subcommand family (testbench/commands/<name>.py with register(subparsers)).
COMMAND_MODULES = ("run", "report", "make_map", "aircraft", "sensors", "locate", "ismn", "montecarlo", "compare", "bench", "detector")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="testbench", description="GNSS-denied navigation testbench for UAVs and UAV swarms")
    parser.add_argument("--version", action="version", version=f"testbench {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="log more (-v info, -vv debug)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"testbench.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"testbench.commands.{name}":
                continue  # that command family is not part of this build
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    keep_freed_memory()  # glibc: no fresh pages for every large temporary (core/heap.py)
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING if args.verbose == 0 else logging.INFO if args.verbose == 1 else logging.DEBUG
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(handler(args) or 0)
    except InputError as exc:
        print(f"testbench: error: {exc}", file=sys.stderr)
        return exc.exit_status
    except TestbenchError as exc:
        print(f"testbench: {type(exc).__name__}: {exc}", file=sys.stderr)
        return exc.exit_status
    except KeyboardInterrupt:
        print("testbench: interrupted", file=sys.stderr)
        return 130
    except Exception:  # noqa: BLE001 -- a bug: show it
        traceback.print_exc()
        print("testbench: internal error (a bug: please report it with the traceback above)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
