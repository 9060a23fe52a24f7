"""Flip (panda-gym's): turn a cube to a random orientation."""

from franka_composer.controllers import ControlSettings
from franka_composer.tasks.config import BlockSpec, TaskConfig

# A 4 cm cube of 0.1 kg (graspable, like pick and place's block; panda-gym's weighs 1 kg)
# with six distinctly coloured faces, so its orientation shows in images. The goal is an
# orientation, observed and compared as a unit quaternion (w, x, y, z): success is a
# rotation angle below 0.2 rad, q and -q being the same orientation.
FLIP = TaskConfig(
    name="flip",
    description="Turn a 4 cm cube with six coloured faces to a uniformly random "
                "orientation: success is a rotation angle below 0.2 rad between the cube's "
                "orientation and the goal's. The goal is shown as a translucent cube beside "
                "the workspace.",
    objects=(BlockSpec(mass=0.1, entity_name="cube", rgba=(0.85, 0.85, 0.85, 1.0),
                       coloured_faces=True),),
    goal="orientation",
    object_orientation="quaternion",
    distance_threshold=0.2,
    control=ControlSettings(actuated_gripper=True),
)
