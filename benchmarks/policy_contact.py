"""Does a trained policy press its object? The lowest object height and the highest object
speed over evaluation episodes (issue 11: before the contact fix a press could sink the
puck 5 cm and launch it at 2 m/s).

    python benchmarks/policy_contact.py RUN_DIR [--episodes 20] [--seed 2024]

Runs the run's final model (else its latest checkpoint) deterministically, as `franka-composer
evaluate` does (same seed, same episodes), and reads every physics substep of each step from
the env's own MuJoCo data: the object's height against its resting height, its horizontal
speed, and the normal force between the hand and the object. Prints one JSON line. Uses only
APIs both before and after the fix have, so it measures either code on its own physics.
"""

from __future__ import annotations

import argparse
import copy
import json
import pathlib

import mujoco
import numpy as np


def measure(run_root: pathlib.Path, episodes: int, seed: int) -> dict:
    from franka_composer.training.models import load_model, make_env
    from franka_composer.training.runs import RunDir

    run = RunDir(run_root)
    config = run.read_config()
    # Trees before the controllers (issue 14) have no `control`: their runs are mocap.
    control = {"control": config.control} if hasattr(config, "control") else {}
    env = make_env(config.task, terminate_on_success=config.terminate_on_success, **control)
    model = load_model(config.algo, run.best_model(), env=env, device="cpu",
                       backend=config.backend)
    unwrapped = env.unwrapped
    task = unwrapped.task
    resting = task.prop.resting_height
    seen = {"lowest": np.inf, "fastest": 0.0, "strongest": 0.0, "pressing_substeps": 0,
            "substeps": 0}

    def after_substep(physics, random_state):  # Composer's public extra hook.
        model_ptr, data = physics.model.ptr, physics.data.ptr
        prop_body = model_ptr.geom_bodyid[physics.bind(task.prop.geom).element_id]
        robot = set(physics.bind(task.panda.mjcf_model.find_all("body")).element_id)
        # The step ends with mj_step1: new contacts, but no constraint solve for them yet
        # (efc_force belongs to the previous rows). Solve on a copy, not to disturb the run.
        solved = copy.copy(data)
        mujoco.mj_forward(model_ptr, solved)
        force = _hand_force_on(model_ptr, solved, prop_body, robot)
        speed = float(np.linalg.norm(_linear_velocity(model_ptr, data, prop_body)[:2]))
        seen["lowest"] = min(seen["lowest"], data.xpos[prop_body][2] - resting)
        seen["fastest"] = max(seen["fastest"], speed)
        seen["strongest"] = max(seen["strongest"], force)
        seen["pressing_substeps"] += int(force > 20.0)
        seen["substeps"] += 1

    unwrapped.composer_env.add_extra_hook("after_substep", after_substep)
    successes = 0
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed if episode == 0 else None)
        done = False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        successes += bool(info.get("is_success", False))
    env.close()
    return {"run": str(run_root), "task": config.task, "algo": config.algo,
            "steps_trained": int(model.num_timesteps), "episodes": episodes,
            "success_rate": successes / episodes,
            "lowest_object_height_below_rest_mm": -1000.0 * seen["lowest"],
            "highest_object_speed_m_per_s": seen["fastest"],
            "largest_hand_force_on_object_n": seen["strongest"],
            "substeps_with_hand_force_over_20_n": seen["pressing_substeps"],
            "substeps": seen["substeps"]}


def _linear_velocity(model, data, body: int) -> np.ndarray:
    velocity = np.zeros(6)
    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, velocity, 0)
    return velocity[3:]


def _hand_force_on(model, data, body: int, robot: set) -> float:
    """Sum of normal forces (N) of active contacts between the hand and `body`."""
    total, force = 0.0, np.zeros(6)
    for index in range(data.ncon):
        contact = data.contact[index]
        if contact.efc_address < 0:
            continue
        bodies = {int(model.geom_bodyid[contact.geom1]), int(model.geom_bodyid[contact.geom2])}
        if body in bodies and bodies & robot:
            mujoco.mj_contactForce(model, data, index, force)
            total += force[0]
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=pathlib.Path)
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=2024)
    args = parser.parse_args()
    print(json.dumps(measure(args.run, args.episodes, args.seed)))


if __name__ == "__main__":
    main()
