"""Time per frame of every scene's NumPy picture, beside Gymnasium's pygame pictures, in one run.

For every scene of `lerax_like.SCENES`: `lerax_like.gym.render_frame(scene, state, action)`
(the NumPy rasteriser, what `render_mode="rgb_array"` returns for the ids that stand for
no Gymnasium env), on a state drawn within the scene's starts and moved by 0.3. For the
five scenes standing for Gymnasium's envs, also `render()` of Gymnasium's own env
(`gymnasium.make("CartPole-v1", render_mode="rgb_array")`, pygame) on the same state, and
of our id, which draws with Gymnasium's renderer. Every candidate is timed per call; a
block's statistic is the median call, the blocks of all candidates are interleaved, and
the minimum over blocks is reported.

    python -m benchmarks render [--quick]
    python -m benchmarks.render [--frames 50] [--repeats 7] [--out DIR]

Writes render.csv into benchmarks/results/ (results/quick/ with --quick).
"""

import os
import statistics
import time

import gymnasium
import jax
import numpy as np

import lerax_like
from benchmarks import benchmark_parser, output_folder, write_csv
from lerax_like.gym import SPECS, render_frame


def timer(draw, frames: int):
    """A thunk that times `frames` calls of `draw`; returns their median in seconds."""

    def block():
        times = []
        for _ in range(frames):
            start = time.perf_counter()
            draw()
            times.append(time.perf_counter() - start)
        return statistics.median(times)

    return block


def candidates() -> dict[tuple[str, str], object]:
    found = {}
    for name, cls in lerax_like.SCENES.items():
        scene = cls()
        low, high = (np.asarray(bound, dtype=np.float64) for bound in scene.initial_bounds)
        state = (low + high) / 2 + 0.3
        action = np.asarray(scene.action_space.sample(key=jax.random.key(0)))
        found[(name, "lerax_like render_frame (NumPy)")] = lambda scene=scene, state=state, action=action: render_frame(
            scene, state, action
        )
        spec = next((spec for spec in SPECS.values() if spec.scene is cls), None)
        if spec is not None and spec.stands_for_gymnasium:
            for label, env_id in (("Gymnasium's env render (pygame)", spec.name), ("our id's render (Gymnasium's renderer)", spec.id)):
                env = gymnasium.make(env_id, render_mode="rgb_array").unwrapped
                env.reset(seed=0)
                env.state = state
                found[(name, label)] = env.render
    return found


def main(argv=None):
    parser = benchmark_parser(__doc__, quick="10 frames a block, 2 blocks")
    parser.add_argument("--frames", type=int, default=None, help="frames a block (50; 10 with --quick)")
    parser.add_argument("--repeats", type=int, default=None, help="interleaved blocks (7; 2 with --quick)")
    arguments = parser.parse_args(argv)
    frames = arguments.frames or (10 if arguments.quick else 50)
    repeats = arguments.repeats or (2 if arguments.quick else 7)
    out = output_folder(arguments)
    blocks = {key: timer(draw, frames) for key, draw in candidates().items()}
    for block in blocks.values():
        block()  # imports pygame, fills caches
    load_before = os.getloadavg()
    results = {key: [] for key in blocks}
    for _ in range(repeats):
        for key, block in blocks.items():
            results[key].append(block())
    load_after = os.getloadavg()
    reference = min(results[("CartPole", "Gymnasium's env render (pygame)")])
    print(f"{frames} frames a block, {repeats} interleaved blocks; load average {load_before} before, {load_after} after")
    rows = []
    for (scene, renderer), times in results.items():
        seconds = min(times)
        rows.append({
            "scene": scene, "renderer": renderer, "ms_per_frame": seconds * 1e3,
            "vs_gymnasium_cartpole": seconds / reference, "frames": frames, "repeats": repeats,
            "load_average_before": round(load_before[0], 2), "load_average_after": round(load_after[0], 2),
        })
        print(f"{scene:22s} {renderer:40s} {seconds * 1e3:7.3f} ms  x{seconds / reference:5.2f} Gymnasium's CartPole")
    write_csv(out / "render.csv", rows)


if __name__ == "__main__":
    main()
