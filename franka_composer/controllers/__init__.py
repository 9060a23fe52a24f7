"""Controllers: how actions move the Panda, chosen by the `control` task option.

- `mocap` (the paper's, the default): a mocap body welded to the tool centre point
  (`mocap.py`).
- `osc`: joint torques within the real Panda's limits from an operational-space law
  (`osc.py`).
- `joints`: joint-angle deltas to Menagerie's position servos (`joints.py`).

Each takes the same `ControlSettings` and owns its action law; the task builder reads
`CONTROLLERS[kind].ARM_ACTUATION` to build the Panda the controller drives.
"""

from __future__ import annotations

from franka_composer.controllers.base import ActionLaw, Controller
from franka_composer.controllers.joints import JointController, JointLaw
from franka_composer.controllers.mocap import MocapController, MocapLaw
from franka_composer.controllers.osc import OscController, OscLaw
from franka_composer.controllers.settings import (CONTROLS, DEFAULT_CONTROL, ControlSettings,
                                                  has_weld)

#: What each controller adds to its ids' version (`Franka{Task}Joints...-v<task's + this>`):
#: bumped when its dynamics change, the change written in every task's version history
#: (`adapters.pages.CONTROL_VERSION_HISTORY`).
CONTROL_VERSIONS: dict[str, int] = {"mocap": 0, "osc": 0, "joints": 1}

#: The controller class for each value of the `control` option.
CONTROLLERS: dict[str, type[Controller]] = {
    "mocap": MocapController,
    "osc": OscController,
    "joints": JointController,
}


def make_controller(arena, panda, settings: ControlSettings) -> Controller:
    """The controller `settings.kind` names, for `panda` in `arena`."""
    return CONTROLLERS[settings.kind](arena, panda, settings)


__all__ = ["ActionLaw", "CONTROLLERS", "CONTROLS", "CONTROL_VERSIONS", "ControlSettings", "Controller",
           "DEFAULT_CONTROL", "JointController", "JointLaw", "MocapController", "MocapLaw",
           "OscController", "OscLaw", "has_weld", "make_controller"]
