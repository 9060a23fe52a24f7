"""How hard the surfaces are: the floor and the objects are stiff, the hand is as Menagerie has it.

The hand is pulled towards its target by a spring (the mocap weld, `controllers.py`). When
it presses an object onto the floor, the weld, the hand-object contact and the object-floor
contact sit in series. With MuJoCo's default contacts (time constant 0.02 s, impedance
0.9-0.95) everywhere and an unbounded weld force, a press compressed the object-floor
contact by centimetres and the object, released, shot out sideways (measured before this
model: blocks 3-4 cm into the floor, pucks launched at 2 m/s). Two things stop that: the
force is bounded (`surface_guard.py`), and the contacts an object rests on, on the floor or
on another object, are stiff, so the object keeps its height under that force.

The hand's contacts with objects keep MuJoCo's defaults, as in Menagerie: grasping, pushing
and striking were tuned with them (a stiff finger turns a push into a blow that tips a block
over, measured: 3 of 6 pushed blocks tumbled). MuJoCo mixes two geoms' contact parameters
by their `solmix` weights: objects weigh 0, so a contact between the hand (weight 1, the
default) and an object takes the hand's parameters, and one between an object and the floor
or another object takes the stiff ones; the floor weighs FLOOR_SOLMIX, so the fingertips
meet a stiff floor too (a press on the bare floor reaches the force bound and the fingertips
stay within ~0.03 mm of the surface).

An object's contacts with the floor and with other objects are predefined contact pairs
(`add_surface_pair`, made by the task that composes them), with the parameters MuJoCo would
mix for them but the sliding friction `surface_friction`: MuJoCo's own rule, the larger of
the two, let the floor's 1 hide a slippery object and an object's 1 a slippery floor. The
hand's contacts stay MuJoCo's dynamic ones: the finger pads' friction 2 rules the grip.

A body of mass m pushed onto a fixed surface with a force F settles about F (1 - d) tc^2 / m
into it (MuJoCo's soft contacts; d: impedance, tc: time constant). With the values below, a
0.1 kg block pressed with the ~130 N a Panda can push down with sinks ~0.02 mm; a block at
rest ~1.5 um.
"""

from __future__ import annotations

import mujoco
import numpy as np

#: solref (time constant, damping ratio): 0.004 s is twice the 2 ms physics step, the
#: stiffest time constant MuJoCo integrates stably at this step (its own lower bound);
#: critically damped, so contacts do not bounce.
CONTACT_SOLREF = (0.004, 1.0)
#: solimp (d at zero depth, d at `width` depth, width m, midpoint, power): an impedance of
#: 0.99, rising to 0.999 within 1 mm of penetration, makes a contact 10-100x harder to
#: compress than the default (0.9-0.95), while leaving a little compliance at first touch,
#: which keeps resting and sliding contacts smooth.
CONTACT_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)


#: The objects' mixing weight: in a contact with the hand, the hand's parameters win.
OBJECT_SOLMIX = 0.0
#: The floor's mixing weight: in a contact with the hand (weight 1), the floor's win (99.9 %).
FLOOR_SOLMIX = 1000.0


def make_stiff(geom, solmix: float = OBJECT_SOLMIX) -> None:
    """Gives a floor or object geom the stiff contact model, with mixing weight `solmix`
    (see the module docstring)."""
    geom.solref = CONTACT_SOLREF
    geom.solimp = CONTACT_SOLIMP
    geom.solmix = solmix


#: MuJoCo's geom defaults, for the attributes a geom leaves unset.
_MUJOCO_GEOM = mujoco.MjSpec().default.geom


def surface_friction(first: float, second: float) -> float:
    """The sliding friction of a contact between two surfaces whose coefficients (task
    options, object specs) are `first` and `second`: the smaller, as ODE and Gazebo combine
    them. The slipperier surface sets the contact, so `object_friction=0.3` or
    `floor_friction=0.3` makes a block slide on any floor (MuJoCo's rule, the larger, let the
    other surface's 1 hide it); equal coefficients give MuJoCo's value. Randomisation scales
    every contact a surface is in by that surface's factor: a pair's sliding friction is this
    times both surfaces' factors (`randomization/randomizer.py`)."""
    return min(first, second)


def add_surface_pair(root, geom1, geom2, name: str):
    """A contact pair `name` of `geom1` and `geom2` (MJCF geoms of equal priority) in `root`,
    the model that composes them, with the parameters of their dynamic contact as MuJoCo
    mixes them (the larger condim, torsional and rolling friction; solref and solimp weighed
    by solmix; margins, gaps and adhesions added), except the sliding friction,
    `surface_friction`. MuJoCo collides a predefined pair instead of the two geoms' dynamic
    contact, in its place, so with equal coefficients the physics is the same, bit for bit
    (tested)."""
    def value(geom, attribute) -> np.ndarray:
        full = np.array(getattr(_MUJOCO_GEOM, attribute), dtype=np.float64)
        given = getattr(geom, attribute)
        if given is not None:  # MJCF takes leading components; the rest keep their defaults.
            full.flat[:np.size(given)] = given
        return full

    if value(geom1, "priority") != value(geom2, "priority"):
        raise ValueError(f"{name}: a surface pair mixes the parameters of geoms of equal "
                         "priority, as MuJoCo does; these differ")
    solmix1, solmix2 = value(geom1, "solmix"), value(geom2, "solmix")
    if solmix1 >= mujoco.mjMINVAL and solmix2 >= mujoco.mjMINVAL:
        mix = solmix1 / (solmix1 + solmix2)
    elif solmix1 < mujoco.mjMINVAL and solmix2 < mujoco.mjMINVAL:
        mix = 0.5
    else:
        mix = 0.0 if solmix1 < mujoco.mjMINVAL else 1.0
    solref1, solref2 = value(geom1, "solref"), value(geom2, "solref")
    solref = (mix * solref1 + (1 - mix) * solref2 if solref1[0] > 0 and solref2[0] > 0
              else np.minimum(solref1, solref2))  # Standard references mix, direct ones: min.
    friction1, friction2 = value(geom1, "friction"), value(geom2, "friction")
    sliding = surface_friction(float(friction1[0]), float(friction2[0]))
    torsional, rolling = np.maximum(friction1[1:], friction2[1:])
    return root.contact.add(
        "pair", name=name, geom1=geom1, geom2=geom2,
        condim=int(max(value(geom1, "condim"), value(geom2, "condim"))),
        friction=(sliding, sliding, torsional, rolling, rolling),
        solref=solref, solimp=mix * value(geom1, "solimp") + (1 - mix) * value(geom2, "solimp"),
        solreffriction=(0.0, 0.0),  # None of its own: the contact's solref, as a dynamic one.
        margin=float(value(geom1, "margin") + value(geom2, "margin")),
        gap=float(value(geom1, "gap") + value(geom2, "gap")),
        adhesion=float(value(geom1, "adhesion") + value(geom2, "adhesion")))
