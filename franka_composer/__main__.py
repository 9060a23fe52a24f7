"""`python -m franka_composer` is the `franka-composer` command."""

import sys

from franka_composer.cli import console

sys.exit(console())
