"""Draws one episode's randomised parameters and writes them into the compiled model.

Nothing is recompiled: every parameter is a value of the compiled MjModel (masses, inertias,
the surface pairs' frictions, damping, gains, colours, lights, cameras), written at the
start of an episode from the nominal values read once after compilation; `mj_setConst` then
brings the model's derived constants (subtree masses, the inverse weights contacts are
regularised with) in line with new masses. Sensing goes through Composer: noise is each
observable's corruptor, the delay its `delay` (`update_interval` one control step, so the
observation at step t is exactly the reading at the end of step t - k).

Streams. The draws come from streams of their own, one per group (`GROUPS`), keyed each
episode by a fingerprint of the episode's random state, which they do not advance: the
episodes (object placements, goals) are those of the same seed without randomisation, and
randomising one group never changes what another draws (visual randomisation leaves the
state trajectory as it was). Still a function of the seed alone.
"""

from __future__ import annotations

import hashlib

import mujoco
import numpy as np
from dm_control.composer.variation import variation_values

from franka_composer.entities.props import MIN_MASS
from franka_composer.randomization.parameters import GROUPS, PARAMETERS, noise, noisy
from franka_composer.randomization.ranges import draw_range
from franka_composer.randomization.settings import PROBE_DRAWS, RandomizationSettings


class Randomizer:
    """One task's randomisation: `start_episode` draws and writes the episode's parameters;
    the sensed observables' corruptors and the action noise draw every step.

    Args:
      settings: what is randomised and how.
      arena, panda, props, controller: the task's parts whose values are written.
      surface_pairs: the contact pairs of the floor and the objects (`contacts.py`), whose
        sliding friction each surface's friction factor scales.
      sensed: the observables the policy reads (the state vector's and the cameras'), each
        with the noise parameter its readings get ("position_noise"...; None for images)
        and whether it reads a unit quaternion (turned by its noise, not added to).
      cameras: the camera elements the observation renders (for the pose jitter).
      marker_sites: the goal marker's sites drawn in the objects' colours, one per object
        in order (`Goal.marker_sites_by_prop`): `object_rgb` recolours them too.
      substeps: physics steps per control step (Composer counts delays in them).
    """

    def __init__(self, settings: RandomizationSettings, *, arena, panda, props, surface_pairs,
                 controller, sensed: list, cameras: list, substeps: int,
                 marker_sites=()) -> None:
        self._ranges = dict(settings.ranges)
        self._marker_sites = list(marker_sites)
        self._arena, self._panda, self._props = arena, panda, list(props)
        self._surface_pairs = list(surface_pairs)
        # Each pair's two surfaces, as indices into the episode's friction factors: the
        # objects' in order, then the floor's (`_pair_friction_factors`).
        surfaces = [prop.geom for prop in self._props] + [arena.floor]
        self._pair_surfaces = np.array(
            [sorted((surfaces.index(pair.geom1), surfaces.index(pair.geom2)))
             for pair in self._surface_pairs], dtype=int).reshape(-1, 2)
        self._controller, self._cameras, self._substeps = controller, list(cameras), substeps
        self._streams = {group: np.random.RandomState(0) for group in GROUPS}
        self._values: dict = {}
        self._nominal: dict = {}
        # Counts resets and control steps: readings within one tick share their noise.
        self._tick = 0
        self._sensed = [observable for observable, _, _ in sensed]
        for observable, parameter, quaternion in sensed:
            if parameter is not None and parameter in self._ranges:
                observable.corruptor = _StepNoise(self._ranges[parameter], self, quaternion)
        self._action_noise = self._ranges.get("action_noise")
        self._probe_object_colours()
        self._check_mass_range()

    def _probe_object_colours(self) -> None:
        """`object_rgb` drawn from each object's own colour (`noises.Multiplicative` jitter
        about it) is checked here, where the colours are known, as the option checks the
        other parameters: a range that can leave [0, 1] is refused before anything is built
        (where the range is known; else `PROBE_DRAWS` draws are)."""
        colour = self._ranges.get("object_rgb")
        probe = np.random.RandomState(0)
        for prop in self._props if colour is not None else ():
            nominal = PARAMETERS["object_rgb"].nominal(prop.rgba)
            PARAMETERS["object_rgb"].check_range("object_rgb", colour,
                                                 draw_range(colour, nominal))
            for _ in range(PROBE_DRAWS):
                self._draw("object_rgb", colour, nominal, probe)

    def _check_mass_range(self) -> None:
        """A mass factor whose known range makes an object lighter than any body compiles
        (`MIN_MASS`) is refused before anything is built, as the option refuses a range
        that leaves a factor's domain; each draw is checked again where it is written (a
        range open at 0, such as LogNormal's, reaches below it only in its far tail)."""
        factor = self._ranges.get("object_mass")
        masses = [geom.mass for prop in self._props for geom in prop.mjcf_model.find_all("geom")
                  if geom.mass is not None]
        drawn = None if factor is None or not masses else draw_range(factor, 1.0)
        if drawn is not None and 0.0 < drawn.low * min(masses) < MIN_MASS:
            raise ValueError(f"randomization 'object_mass' draws factors in {drawn}, which "
                             f"make a {min(masses):g} kg object as light as "
                             f"{drawn.low * min(masses):g} kg, lighter than any body compiles "
                             f"({MIN_MASS:g} kg): refused now, not at the first reset that "
                             "draws so (maybe hours into a run); bound it")

    @property
    def values(self) -> dict:
        """This episode's drawn parameters that apply, by name (factors, colours, offsets,
        angles, steps: `PARAMETERS`), as floats, ints and tuples; per-object ones one per
        object. (Camera jitter applies where a camera's images are observed.)"""
        return self._values

    # ----- Once per compiled model ----------------------------------------------------------

    def bind(self, physics) -> None:
        """Reads the nominal values of what is written (the model as compiled)."""
        model = physics.model

        def ids(elements) -> np.ndarray:
            return np.asarray(physics.bind(elements).element_id, dtype=int)

        bodies = np.array([physics.bind(prop.geom).bodyid for prop in self._props], dtype=int)
        object_geoms = (ids([prop.geom for prop in self._props]) if self._props
                        else np.zeros(0, dtype=int))
        pairs = np.array([model.name2id(pair.full_identifier, "pair")
                          for pair in self._surface_pairs], dtype=int)
        panda_geoms = ids(self._panda.mjcf_model.find_all("geom"))
        panda_materials = ids(self._panda.mjcf_model.find_all("material"))
        lights = ids(self._arena.mjcf_model.find_all("light"))
        if not np.allclose(model.light_dir0[lights], model.light_dir[lights]):
            raise ValueError("light_direction assumes every light hangs from a body aligned "
                             "with the world at qpos0 (light_dir0 == light_dir)")
        cameras = ids(self._cameras) if self._cameras else np.zeros(0, dtype=int)
        marker_sites = (ids(self._marker_sites) if self._marker_sites
                        else np.zeros(0, dtype=int))
        arm_dofs = np.asarray(physics.bind(self._panda.joints).dofadr, dtype=int)
        floor = int(physics.bind(self._arena.floor).element_id)
        self._nominal = dict(
            bodies=bodies, mass=model.body_mass[bodies].copy(),
            inertia=model.body_inertia[bodies].copy(),
            object_geoms=object_geoms, marker_sites=marker_sites,
            pairs=pairs, pair_friction=model.pair_friction[pairs, 0].copy(),
            floor_material=int(model.geom_matid[floor]),
            floor_rgba=model.mat_rgba[int(model.geom_matid[floor])].copy(),
            panda_geoms=panda_geoms, panda_geom_rgba=model.geom_rgba[panda_geoms].copy(),
            panda_materials=panda_materials,
            panda_material_rgba=model.mat_rgba[panda_materials].copy(),
            lights=lights, light_dir=model.light_dir[lights].copy(),
            light_diffuse=model.light_diffuse[lights].copy(),
            cameras=cameras, cam_pos=model.cam_pos[cameras].copy(),
            cam_quat=model.cam_quat[cameras].copy(),
            arm_dofs=arm_dofs, damping=model.dof_damping[arm_dofs].copy())

    # ----- Each episode ---------------------------------------------------------------------

    def start_episode(self, physics, random_state: np.random.RandomState) -> None:
        """Draws the episode's parameters (from streams keyed by `random_state`'s present
        state, which is not advanced), checks them, and writes them. A draw refused (a
        ValueError) moves `random_state` on by one draw before it is raised: else the next
        reset, keyed by the same state, drew the same values and failed again, and every
        one after it."""
        try:
            self._start_episode(physics, random_state)
        except ValueError:
            random_state.randint(2**31)
            raise

    def _start_episode(self, physics, random_state: np.random.RandomState) -> None:
        self._split_streams(random_state)
        self._tick += 1
        values = {}
        for name, distribution in self._ranges.items():
            parameter = PARAMETERS[name]
            if not parameter.episode:
                continue
            stream = self._streams[parameter.group]
            if parameter.per_object:  # Each object its own (none for reach).
                values[name] = [self._draw(name, distribution, parameter.nominal(prop.rgba),
                                           stream) for prop in self._props]
            else:
                values[name] = self._draw(name, distribution, parameter.nominal(), stream)
        self._write(physics, values)
        # Reported where it applies: a preset's camera jitter is drawn (the visual stream's
        # draws stay those of a pixel env) and moves nothing where no camera is observed;
        # a per-object parameter draws nothing where there is no object (reach), and the
        # floor's friction acts on nothing there (it scales the objects' contacts).
        self._values = {name: _plain(value) for name, value in values.items()
                        if (self._cameras or not PARAMETERS[name].observed_cameras)
                        and (self._props or not PARAMETERS[name].needs_objects)}

    @property
    def tick(self) -> int:
        """Changes at every reset and every control step."""
        return self._tick

    def stream(self, group: str) -> np.random.RandomState:
        return self._streams[group]

    def step_action(self, action: np.ndarray) -> np.ndarray:
        """A control step begins with the checked `action`: readings at its end get new
        noise, and the action gets this step's action noise (the controller clips it)."""
        self._tick += 1
        if self._action_noise is None:
            return action
        return np.asarray(noisy(self._action_noise, action, self._streams["action"]),
                          dtype=np.float64)

    def _split_streams(self, random_state: np.random.RandomState) -> None:
        """One Philox stream per group, keyed by a hash of the episode's random state and
        the group's name (a SeedSequence over MT19937's 625 words costs 0.8 ms; this 60 us)."""
        state = random_state.get_state(legacy=True)
        assert isinstance(state, tuple)  # MT19937's, as RandomState keeps it.
        _, keys, position, *_ = state
        fingerprint = hashlib.blake2b(keys.tobytes(), digest_size=16)
        fingerprint.update(int(position).to_bytes(4, "little"))
        for group in GROUPS:
            key = fingerprint.copy()
            key.update(group.encode())
            self._streams[group] = np.random.RandomState(
                np.random.Philox(key=int.from_bytes(key.digest(), "little")))

    @staticmethod
    def _draw(name, distribution, nominal, stream):
        return PARAMETERS[name].check(
            name, variation_values.evaluate(distribution, nominal, nominal, stream))

    def _write(self, physics, values: dict) -> None:
        model, nominal = physics.model, self._nominal
        ptr = model.ptr
        if values.get("object_mass"):
            factors = np.asarray(values["object_mass"])
            masses = nominal["mass"] * factors
            if masses.min() < MIN_MASS:  # (Its inertia could fall below MuJoCo's minimum.)
                raise ValueError(
                    f"randomization 'object_mass' drew a factor of "
                    f"{factors[np.argmin(masses)]:g}, which makes an object "
                    f"{masses.min():g} kg, lighter than any body compiles ({MIN_MASS:g} kg): "
                    "bound the factor away from 0")
            ptr.body_mass[nominal["bodies"]] = masses
            ptr.body_inertia[nominal["bodies"]] = nominal["inertia"] * factors[:, None]
        if values.get("object_friction") or "floor_friction" in values:
            # Both sliding components; the hand's contacts (dynamic) keep their friction.
            ptr.pair_friction[nominal["pairs"], :2] = (
                nominal["pair_friction"] * self._pair_friction_factors(values))[:, None]
        if "joint_damping" in values:
            ptr.dof_damping[nominal["arm_dofs"]] = nominal["damping"] * values["joint_damping"]
        if "gripper_gain" in values:
            self._panda.set_gripper_gain(physics, values["gripper_gain"])
        if "controller_gain" in values:
            self._controller.scale_gains(physics, values["controller_gain"])
        self._write_visual(ptr, values)
        if values.get("object_mass"):
            # Subtree masses and the inverse weights contacts are regularised with; last,
            # as it also takes the cameras' and lights' reference poses from the model.
            mujoco.mj_setConst(ptr, physics.data.ptr)
        if "observation_delay" in values:
            steps = values["observation_delay"]
            for observable in self._sensed:
                # Read once per control step, k control steps late (0: Composer's default).
                observable.update_interval = self._substeps if steps else 1
                observable.delay = steps * self._substeps

    def _pair_friction_factors(self, values: dict) -> np.ndarray:
        """Each surface pair's friction factor: its two surfaces' factors (1 where one is not
        randomised) multiplied, an object's first (`contacts.surface_friction`)."""
        objects = values.get("object_friction") or [1.0] * len(self._props)
        factors = np.array([*objects, values.get("floor_friction", 1.0)])
        first, second = self._pair_surfaces.T
        return factors[first] * factors[second]

    def _write_visual(self, ptr, values: dict) -> None:
        nominal = self._nominal
        if values.get("object_rgb"):
            colours = np.asarray(values["object_rgb"])
            ptr.geom_rgba[nominal["object_geoms"], :3] = colours
            ptr.site_rgba[nominal["marker_sites"], :3] = colours[:len(nominal["marker_sites"])]
        if "floor_tint" in values:
            ptr.mat_rgba[nominal["floor_material"], :3] = (nominal["floor_rgba"][:3]
                                                           * values["floor_tint"])
        if "robot_tint" in values:
            tint = values["robot_tint"]
            ptr.geom_rgba[nominal["panda_geoms"], :3] = nominal["panda_geom_rgba"][:, :3] * tint
            ptr.mat_rgba[nominal["panda_materials"], :3] = (
                nominal["panda_material_rgba"][:, :3] * tint)
        if "light_direction" in values:
            direction = nominal["light_dir"] + values["light_direction"]
            length = np.linalg.norm(direction, axis=1, keepdims=True)
            if not (length > 1e-6).all():
                raise ValueError(f"randomization 'light_direction' drew "
                                 f"{np.asarray(values['light_direction']).tolist()}, which "
                                 "cancels a light's "
                                 f"direction {nominal['light_dir'][np.argmin(length)].tolist()}"
                                 ": offsets must leave every direction some length")
            direction /= length
            ptr.light_dir[nominal["lights"]] = direction
            # A tracking light (Menagerie's "top", trackcom) keeps the world direction it has
            # at qpos0, light_dir0: the same here, its body being aligned with the world.
            ptr.light_dir0[nominal["lights"]] = direction
        if "light_intensity" in values:
            # In float64 (the model's colours are float32, which a product could overflow).
            diffuse = nominal["light_diffuse"].astype(np.float64) * values["light_intensity"]
            with np.errstate(over="ignore"):  # MuJoCo keeps float32: inf there, refused.
                representable = np.isfinite(diffuse.astype(np.float32)).all()
            if not representable:
                raise ValueError(f"randomization 'light_intensity' drew a factor of "
                                 f"{values['light_intensity']:g}, which makes a light's "
                                 "colour infinite in MuJoCo's float32: bound it")
            ptr.light_diffuse[nominal["lights"]] = diffuse
        if "camera_position" in values:
            ptr.cam_pos[nominal["cameras"]] = nominal["cam_pos"] + values["camera_position"]
        if "camera_rotation" in values:
            # About an axis uniform on the sphere, drawn from the visual stream.
            axis = self._streams["visual"].normal(size=3)
            axis /= np.linalg.norm(axis)
            turn, quat = np.zeros(4), np.zeros(4)
            mujoco.mju_axisAngle2Quat(turn, axis, values["camera_rotation"])
            for row, camera in enumerate(nominal["cameras"]):
                mujoco.mju_mulQuat(quat, nominal["cam_quat"][row], turn)
                ptr.cam_quat[camera] = quat


class _StepNoise:
    """A Composer corruptor adding a noise distribution's draw to a reading, one draw per
    control step, from the randomizer's sensing stream (not the environment's, which draws
    the episodes). However often Composer reads an observable within a step (its updater
    reads each once more when it is rebuilt at a reset), the step's reading gets the same
    noise: the fast and stock paths observe the same values. A unit `quaternion` reading is
    turned instead, by the rotation vector of three draws (rad), and stays unit: added to
    its components, angle noise made it no orientation (norm 0.99 under the preset)."""

    def __init__(self, distribution, randomizer: Randomizer, quaternion: bool = False) -> None:
        self._distribution, self._randomizer = distribution, randomizer
        self._quaternion = quaternion
        self._tick, self._noise = None, None

    def __call__(self, value, random_state=None):
        randomizer = self._randomizer
        if self._tick != randomizer.tick:
            shape = np.zeros(3) if self._quaternion else value
            self._noise = noise(self._distribution, shape, randomizer.stream("sensing"))
            self._tick = randomizer.tick
        if not self._quaternion:
            return value + self._noise
        turned = np.array(value, dtype=np.float64)
        mujoco.mju_quatIntegrate(turned, np.broadcast_to(
            np.asarray(self._noise, dtype=np.float64), (3,)).copy(), 1.0)
        return turned


def _plain(value):
    """A drawn value as immutable floats, ints and tuples (JSON writes them as lists)."""
    if isinstance(value, (list, np.ndarray)):
        return tuple(_plain(item) for item in value)
    return float(value) if isinstance(value, (float, np.floating)) else value
