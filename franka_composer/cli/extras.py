"""Which extra a command's missing package comes from, so that a command run without it
says what to install instead of ending in Python's ImportError traceback."""

from __future__ import annotations

import importlib.util
import re

#: The import name of each optional package the commands use, and the extra that brings it
#: (setup.cfg's extras_require; torch comes with stable-baselines3).
EXTRA_OF = {"stable_baselines3": "train", "sb3_contrib": "train", "torch": "train",
            "matplotlib": "train", "rich": "train", "sbx": "jax", "jax": "jax",
            "ray": "sweep", "minari": "data", "h5py": "data", "envlogger": "data",
            "gymnasium_robotics": "peers"}

#: What the 'train' extra needs first: a plain install of it pulls torch's multi-GB CUDA
#: build from PyPI.
TORCH_FIRST = (", after torch from PyTorch's CPU index: pip install -c constraints.txt torch "
               "--index-url https://download.pytorch.org/whl/cpu")


def missing_extra(error: ImportError) -> str | None:
    """What to install, for an ImportError of a package of `EXTRA_OF` that is not installed:
    named by the error (`No module named 'minari'`), or only in its text (Minari's own
    error for a missing h5py, SB3's for a missing rich). None for any other, and for a
    package that is there but fails to import (a version that lacks a name, a broken C
    extension: a traceback says more than "install it")."""
    names = [error.name.split(".")[0]] if error.name else re.findall(r"\b\w+\b", str(error))
    for name in names:
        if name in EXTRA_OF and not _installed(name):
            extra = EXTRA_OF[name]
            return (f"this command needs {name}, which the '{extra}' extra installs: in the "
                    f"checkout, pip install -c constraints.txt -e '.[{extra}]'"
                    + (TORCH_FIRST if extra == "train" and not _installed("torch") else "")
                    + f" (docs/guide/installation.md; {error})")
    return None


def _installed(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):  # Its import was refused, or left half done.
        return False
