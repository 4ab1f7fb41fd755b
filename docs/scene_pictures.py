"""Write the animations of docs/scenes.md: one GIF per scene of `lerax_like.SCENES`.

    python docs/scene_pictures.py            # into docs/images/scenes/<Scene>.gif

Each scene is run through its Gymnasium id (`gymnasium.make("lerax_like/...")`, the
scene's own solver and `dt`) from a seeded reset, with a small hand-written policy that
shows what the scene does (a pendulum swinging, a car pumping energy up the hill, a
quadrotor flying home, a wheel rolling down its slope), and every frame is the scene's
NumPy picture (`lerax_like.gym.render_frame`), drawn at half size. Needs Pillow (a
dependency of matplotlib, the `study` extra). Takes a minute or two, most of it compiling.
"""

import math
import pathlib
import sys

import gymnasium
import numpy as np
from PIL import Image

import lerax_like
from lerax_like.gym import SPECS, render_frame


OUT = pathlib.Path(__file__).resolve().parent / "images" / "scenes"


def quadrotor_home(state: np.ndarray) -> np.ndarray:
    """A hand-tuned PD law flying the planar quadrotor to the origin: height by the mean
    thrust, position by the tilt (`x'' = -T sin(theta) / m`), tilt by the thrust difference."""
    x, z, theta, x_dot, z_dot, theta_dot = state
    mean = (-4.0 * z - 3.0 * z_dot) / 9.81
    tilt = 0.3 * x + 0.5 * x_dot
    difference = (-100.0 * (theta - tilt) - 20.0 * theta_dot) / 122.6
    return np.clip(np.array([mean - difference / 2, mean + difference / 2]), -1.0, 1.0)


UNBOUNDED = {"theta_threshold_radians": math.inf, "x_threshold": math.inf}

# scene -> (keywords of gymnasium.make, policy(state, step) -> action, number of steps, steps per frame)
RUNS = {
    # The cart-poles without their limits, the cart kept near the middle while the poles fall and swing.
    "CartPole": (UNBOUNDED, lambda s, k: 1 if s[0] + s[1] < 0 else 0, 150, 1),
    "CartPoleContinuous": (UNBOUNDED, lambda s, k: np.clip([-(s[0] + s[1])], -1.0, 1.0), 150, 1),
    "Pendulum": ({}, lambda s, k: np.array([0.0]), 100, 1),
    "Acrobot": ({}, lambda s, k: int(np.sign(s[3])) + 1, 100, 1),
    "MountainCar": ({}, lambda s, k: 2 if s[1] >= 0 else 0, 200, 2),
    "MountainCarContinuous": ({}, lambda s, k: np.array([1.0 if s[1] >= 0 else -1.0]), 200, 2),
    "VanDerPol": ({}, lambda s, k: np.array([0.0]), 200, 1),
    "DoubleCartPole": (UNBOUNDED, lambda s, k: np.clip([-(s[0] + s[3])], -1.0, 1.0), 150, 1),
    "NLinkPendulum": ({}, lambda s, k: np.zeros(3), 150, 1),
    "PlanarQuadrotor": ({}, lambda s, k: quadrotor_home(s), 150, 1),
    "BouncingBall": ({}, lambda s, k: np.array([0.6, 0.0]) if k < 30 else np.zeros(2), 150, 1),
    "RimlessWheel": ({}, lambda s, k: np.array([0.0]), 120, 2),
    "SimplestWalker": ({}, lambda s, k: np.array([0.0]), 120, 1),
    "CompassGait": ({}, lambda s, k: np.array([0.0]), 150, 2),
    "SlidingBlock": ({}, lambda s, k: np.array([1.0 if k < 20 else 0.0]), 80, 1),
    "RollingDisk": ({}, lambda s, k: np.array([0.0 if k < 10 else 1.0]), 80, 1),
}


def half_size(frame: np.ndarray) -> np.ndarray:
    """The frame at half its width and height, each pixel the mean of four (no aliasing)."""
    height, width = frame.shape[0] // 2 * 2, frame.shape[1] // 2 * 2
    blocks = frame[:height, :width].reshape(height // 2, 2, width // 2, 2, 3).astype(np.float32)
    return np.rint(blocks.mean(axis=(1, 3))).astype(np.uint8)


def frames_of(name: str) -> list[np.ndarray]:
    keywords, policy, steps, every = RUNS[name]
    env_id = next(env_id for env_id, spec in SPECS.items() if spec.scene is lerax_like.SCENES[name])
    env = gymnasium.make(env_id, **keywords).unwrapped
    env.reset(seed=1)
    frames = [half_size(render_frame(env.scene, env.state))]
    for step in range(steps):
        action = policy(env.state, step)
        _, _, terminated, _, _ = env.step(action)
        if terminated or (step + 1) % every == 0:
            frames.append(half_size(render_frame(env.scene, env.state, np.atleast_1d(action))))
        if terminated:  # the mountain car at its flag
            break
    env.close()
    return frames


def write_gif(path: pathlib.Path, frames: list[np.ndarray], fps: float) -> None:
    images = [Image.fromarray(frame).convert("P", palette=Image.Palette.ADAPTIVE, colors=32) for frame in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0, optimize=True)


def main(names: list[str]) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    missing = set(lerax_like.SCENES) - set(RUNS)
    if missing:
        raise SystemExit(f"no run for the scenes {sorted(missing)}: add one to RUNS in {__file__}")
    for name in names or list(RUNS):
        frames = frames_of(name)
        scene = lerax_like.SCENES[name]()
        _, _, _, every = RUNS[name]
        # Real time where a GIF shows it well (10 to 50 frames a second; the mountain
        # cars' dt of 1 is Gymnasium's unit, not a second).
        fps = min(50.0, max(10.0, 1.0 / (float(scene.dt) * every)))
        write_gif(OUT / f"{name}.gif", frames, fps)
        print(f"{name}: {len(frames)} frames at {fps:.0f} fps -> {OUT / f'{name}.gif'}")


if __name__ == "__main__":
    main(sys.argv[1:])
