"""Pick and place: grasp a light block and carry it to a goal, in the air 70 % of the time."""

from franka_composer.controllers import ControlSettings
from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.records import BlockSpec, Workspace

# Grasping is held by the finger contacts (friction 2, condim 4, 10 N squeeze: see
# entities/panda.py). Measured over a 0.15 m lift and 0.1 m carry, impratio 1, 3 and 10 all
# keep the block within 3 mm of the tool centre point, so the default (1) stays; noslip
# (~30 % more per step) is not needed.
PICK_AND_PLACE = TaskConfig(
    name="pick_and_place",
    description="Grasp a 4 cm, 0.1 kg block and carry it to a goal that is in the air (up to "
                "0.2 m above the resting block) 70 % of the time, else on the floor. The "
                "last action (the fourth; under joints the eighth) opens and closes the hand.",
    objects=(BlockSpec(mass=0.1),),
    control=ControlSettings(actuated_gripper=True),
    workspace=Workspace(goal_max_height=0.2, goal_in_air_probability=0.7),
)
