"""Whether two runs' policy.pt hold the same actor, tensor for tensor (exit status 1 if not).

    python experiments/same_actor.py RUN_A/policy.pt RUN_B/policy.pt
"""

from __future__ import annotations

import argparse
import sys

import torch


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("first", metavar="RUN_A/policy.pt")
    parser.add_argument("second", metavar="RUN_B/policy.pt")
    args = parser.parse_args(argv)
    a, b = (torch.load(path)["actor"] for path in (args.first, args.second))
    assert a.keys() == b.keys(), "the two actors have different tensors"
    differ = {name: float((a[name] - b[name]).abs().max()) for name in a
              if not torch.equal(a[name], b[name])}
    print("policy.pt's actor:", f"{len(a)} tensors identical" if not differ else
          f"differs (largest |difference| per tensor): {differ}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
