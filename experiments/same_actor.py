"""Whether two runs' policy.pt hold the same actor, tensor for tensor (exit status 1 if not).

    python experiments/same_actor.py RUN_A/policy.pt RUN_B/policy.pt
"""

import sys

import torch


def main(first: str, second: str) -> int:
    a, b = (torch.load(path)["actor"] for path in (first, second))
    assert a.keys() == b.keys(), "the two actors have different tensors"
    differ = {name: float((a[name] - b[name]).abs().max()) for name in a
              if not torch.equal(a[name], b[name])}
    print("policy.pt's actor:", f"{len(a)} tensors identical" if not differ else
          f"differs (largest |difference| per tensor): {differ}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
