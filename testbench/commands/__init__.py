"""CLI subcommands: each module exposes `register(subparsers)` (see testbench/cli.py)."""
