"""Objects that fit the task: starting clear of the hand, narrow enough to grasp where a
goal must be lifted to.

Object sizes and the object square are options, and two sizes failed without a word: a
block starting inside the hand is thrown out by the contact solver (push with
`block_half_size=0.5` sent it to z = 19.96 m within 10 steps, no divergence flagged), and
a block wider than the open hand (`block_half_size=0.06` on pick-and-place) can never be
lifted. Both are refused as the options are set (`TaskConfig.check`), with the size that
fits; so is a neutral pose that puts the hand into the floor (reported there at reset, and
thrown out of it by the first step).
"""

from __future__ import annotations

import functools

import numpy as np
from dm_control import mjcf

from franka_composer.entities.panda import MAX_FINGER_WIDTH, Panda

#: Room (m) kept between an object's top, where it can start, and the hand's lowest point
#: above it at the neutral pose.
HAND_CLEARANCE = 0.01


def clearance_inputs(config) -> tuple:
    """All that `check_clearance` reads of `config` (a `TaskConfig`): an option that leaves
    it as it was (a timing, a reward) needs no new check, and no Menagerie Panda, which
    reading a run's config.json (`franka-composer report`) should not."""
    box = config.workspace.object_box
    return (tuple(map(float, config.neutral_arm_qpos)), float(config.initial_finger_width),
            config.lifts_objects, config.control.actuated_gripper, tuple(map(float, box.low)),
            tuple(map(float, box.high)),
            tuple((spec.height, spec.footprint_radius, spec.grasp_width)
                  for spec in config.objects))


def check_clearance(config) -> None:
    """A ValueError unless every object of `config` (a `TaskConfig`) starts, anywhere in its
    square, `HAND_CLEARANCE` below the hand and fingers at the neutral pose, and unless
    objects that the goals need lifted fit between the open fingers; and unless the hand
    starts above the floor."""
    boxes = hand_boxes(tuple(map(float, config.neutral_arm_qpos)),
                       float(config.initial_finger_width))
    lowest = min(z for _, _, z in boxes)
    if lowest < 0:
        raise ValueError(f"neutral_arm_qpos puts the hand {-lowest:.3g} m into the floor (its "
                         f"lowest point at z = {lowest:.3g} m): give a pose with the hand "
                         "above it")
    if not config.objects:
        return
    if config.lifts_objects:
        _check_graspable(config)
    box = config.workspace.object_box
    for spec in config.objects:
        low, high = box.low - spec.footprint_radius, box.high + spec.footprint_radius
        above = [z for (xy_low, xy_high, z) in boxes
                 if np.all(xy_low < high) and np.all(xy_high > low)]
        if above and spec.height + HAND_CLEARANCE > min(above):
            room = min(above) - HAND_CLEARANCE
            raise ValueError(
                f"{config.name}'s {spec.entity_name} is {spec.height:.3g} m tall "
                f"({spec.height_option}={spec.height / 2:g}), and where it can start the "
                f"hand's lowest point is {min(above):.3g} m above the floor at the neutral "
                f"pose: it would start inside the hand. Give a {spec.height_option} under "
                f"{room / 2:.4g} ({HAND_CLEARANCE} m clear of the hand), or an "
                "object_centre/object_range away from the hand")


def _check_graspable(config) -> None:
    if not config.control.actuated_gripper:
        raise ValueError(f"{config.name}'s goals need its objects lifted "
                         f"({config.lifting_goals}), and actuated_gripper=False holds the "
                         "fingers closed: nothing can lift them. Give actuated_gripper=True")
    for spec in config.objects:
        if spec.grasp_width >= MAX_FINGER_WIDTH:
            raise ValueError(
                f"{config.name}'s {spec.entity_name} is {spec.grasp_width:.3g} m across "
                f"({spec.grasp_option}={spec.grasp_width / 2:g}), and the open hand is "
                f"{MAX_FINGER_WIDTH} m wide: it cannot be grasped, and its goals need it "
                f"lifted ({config.lifting_goals}). Give a {spec.grasp_option} under "
                f"{MAX_FINGER_WIDTH / 2:g}")


@functools.lru_cache(maxsize=16)
def hand_boxes(arm_qpos: tuple, finger_width: float) -> tuple:
    """(low xy, high xy, lowest z) of each geom of the Panda that touches objects (the hand
    and fingers), as world-aligned boxes around it, with the arm at `arm_qpos` and the
    fingers `finger_width` apart (an angle outside its joint's range a ValueError naming
    it). Builds and compiles a bare Panda (~0.1 s, mostly parsing Menagerie's XML), once
    per pose."""
    panda = Panda(visual_meshes=False)
    panda.check_arm_qpos("neutral_arm_qpos", arm_qpos)
    physics = mjcf.Physics.from_mjcf_model(panda.mjcf_model)
    panda.configure_joints(physics, arm_qpos, finger_width)
    physics.forward()
    model, data = physics.model, physics.data
    boxes = []
    for body in panda.colliding_bodies:
        for geom in physics.bind(body.geom).element_id:  # (Its own, not its children's.)
            if not (model.geom_contype[geom] or model.geom_conaffinity[geom]):
                continue  # Drawn only.
            rotation = data.geom_xmat[geom].reshape(3, 3)
            centre = data.geom_xpos[geom] + rotation @ model.geom_aabb[geom, :3]
            half = np.abs(rotation) @ model.geom_aabb[geom, 3:]
            boxes.append(((centre - half)[:2], (centre + half)[:2], float((centre - half)[2])))
    return tuple(boxes)
