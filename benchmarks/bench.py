"""Runs `franka-composer bench` with this script's arguments (see `--help`).

    python benchmarks/bench.py --steps 3000 --out results.json

Figures and how to read them: BENCHMARKS.md.
"""

import sys

from franka_composer.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", *sys.argv[1:]]))
