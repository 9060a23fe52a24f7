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

A body of mass m pushed onto a fixed surface with a force F settles about F (1 - d) tc^2 / m
into it (MuJoCo's soft contacts; d: impedance, tc: time constant). With the values below, a
0.1 kg block pressed with the ~130 N a Panda can push down with sinks ~0.02 mm; a block at
rest ~1.5 um.
"""

from __future__ import annotations

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
