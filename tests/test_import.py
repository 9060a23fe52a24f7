"""What importing franka_composer does to the process beyond registering its ids."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow  # A fresh process.

_PROBE = """
import json, warnings
import gymnasium as gym  # Gymnasium's own filter ('once' for its modules) is not ours.
before = [repr(f) for f in warnings.filters]
import franka_composer
env = gym.make("FrankaPushSparse-v0")
env.reset(seed=0)
env.close()
print(json.dumps([repr(f) for f in warnings.filters if repr(f) not in before]))
"""


def test_importing_the_suite_leaves_the_warning_filters_as_they_were():
    """dm_control.composer's import turns every DeprecationWarning in the process to 'always'
    (gym#3059 is the same defect): it must not reach a user's program through ours."""
    result = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                            timeout=120, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    assert json.loads(result.stdout.strip().splitlines()[-1]) == []
