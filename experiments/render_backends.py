"""Whether two GL backends (a GPU's EGL, Mesa's software GL) draw the same scene: frames of
one seeded push episode saved on each machine, then compared.

    python experiments/render_backends.py --save FILE.npz      # on each machine
    python experiments/render_backends.py --compare A.npz B.npz

A policy trained on pixels from one backend sees the other's frames; bit equality is not
expected (rasterisers differ at triangle edges). `--save` also prints the GL renderer.
"""

from __future__ import annotations

import argparse
import json

import gymnasium as gym
import numpy as np

import franka_composer  # noqa: F401 - registers the ids

STEPS = 20
RENDER_SIZE = 240


def save(path: str) -> None:
    actions = np.random.default_rng(0).uniform(-1, 1, (STEPS, 3)).astype(np.float32)
    env = gym.make("FrankaPushSparse-v0", observation_mode="pixels", render_mode="rgb_array",
                   width=RENDER_SIZE, height=RENDER_SIZE)
    obs, _ = env.reset(seed=3)
    observations, renders = [obs["workspace_pixels"]], [env.render()]
    for action in actions:
        obs, *_ = env.step(action)
        observations.append(obs["workspace_pixels"])
        renders.append(env.render())
    renderer = _renderer(env.unwrapped.composer_env.physics)
    env.close()
    np.savez_compressed(path, observations=np.stack(observations), renders=np.stack(renders),
                        renderer=renderer)
    print(json.dumps({"saved": path, "renderer": renderer}))


def _renderer(physics) -> str:
    from OpenGL import GL

    with physics.contexts.gl.make_current() as context:
        return context.call(lambda: GL.glGetString(GL.GL_RENDERER).decode())


def compare(a_path: str, b_path: str) -> None:
    a, b = np.load(a_path), np.load(b_path)
    report = {"renderers": [str(a["renderer"]), str(b["renderer"])]}
    for name in ("observations", "renders"):
        difference = np.abs(a[name].astype(int) - b[name].astype(int))
        pixels = difference.max(axis=-1)
        report[name] = {"shape": list(a[name].shape), "equal": bool((difference == 0).all()),
                        "mean": round(float(difference.mean()), 3),
                        "max": int(difference.max()),
                        "pixels_over_8": int((pixels > 8).sum()), "pixels": int(pixels.size)}
    print(json.dumps(report, indent=1))


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--save", metavar="FILE")
    group.add_argument("--compare", nargs=2, metavar=("A", "B"))
    args = parser.parse_args()
    if args.save:
        save(args.save)
    else:
        compare(*args.compare)


if __name__ == "__main__":
    main()
