"""`python -m franka_composer` is the `franka-composer` command."""

import sys

from franka_composer.cli import main

sys.exit(main())
