"""Stack (panda-gym's): put block 1 at a goal on the floor and block 2 on top of it."""

from franka_composer.controllers import ControlSettings
from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.records import BlockSpec

# Two 4 cm blocks of 0.1 kg, light enough to grasp like pick and place's (panda-gym's are
# 2 and 1 kg), told apart by colour. Success is panda-gym's rule: the six coordinates of
# both blocks within 0.1 m of the goal's, as one vector. Two placements take twice the
# steps: 100, as in panda-gym.
STACK = TaskConfig(
    name="stack",
    description="Put the blue block (block 1) at a goal on the floor and the green block "
                "(block 2) on top of it. Both blocks are 4 cm, 0.1 kg; success is the two "
                "blocks' six coordinates within 0.1 m of the goal's (panda-gym's rule).",
    objects=(BlockSpec(mass=0.1, entity_name="block1"),
             BlockSpec(mass=0.1, entity_name="block2", rgba=(0.15, 0.7, 0.25, 1.0))),
    goal="stacked",
    distance_threshold=0.1,
    control=ControlSettings(actuated_gripper=True, guard_ignores_carried=True),
    max_episode_steps=100,
    version=1,
    version_history=(
        "v1: a block the hand carries (both fingers touch it, nothing else does) is part "
        "of the hand for the surface guard, not a surface beneath it: v0's rays from the "
        "fingertips met the underside of a block held low in the grip, and a full downward "
        "command carrying it moved the hand 2.5-3.3 mm a step, not 47 mm "
        "(`guard_ignores_carried`; the expert 99 -> 100 of 100 episodes). "
        "gym.make(id, guard_ignores_carried=False) gives v0's guard.",),
)
