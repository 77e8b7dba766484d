"""Overhead-camera frames per second: the project's renderers against a bare ``mujoco.Renderer``.

    python benchmarks/bench_render.py                        # 320x240 and 640x480, 5 repeats
    python benchmarks/bench_render.py --sizes 320x240 --frames 100 --repeats 7

On the imitation scene (both robots, table, object; the teacher a few seconds into its loop), each
size is measured without shadows, then with them:

- bare: ``mujoco.Renderer`` on the environment's compiled model, ``update_scene`` + ``render``;
- FrameRenderer: ``peoplebot_sim.rendering.FrameRenderer.render("overhead")``;
- observable: the environment's ``overhead_camera`` observable (dm-control's ``physics.render``),
  without shadows only (the task turns them off);
- env step: a whole environment step with that observable on (physics, teacher, observations).

Every figure is a median over interleaved repeats (order rotated each repeat), in one run; ratios
are against the bare renderer of the same size and shadow setting. Rendering is headless (EGL, or
whatever ``MUJOCO_GL`` names); on a machine without a GPU it runs on the CPU.
"""

from __future__ import annotations

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import argparse
import os
import statistics
import time

import mujoco
import numpy as np

from peoplebot_sim import task
from peoplebot_sim.rendering import FrameRenderer


def _rate(render, frames: int) -> float:
    """Returns frames/s of ``frames`` calls of ``render``."""
    start = time.perf_counter()
    for _ in range(frames):
        render()
    return frames / (time.perf_counter() - start)


def _bare_loop(model, data, width: int, height: int, shadows: bool):
    renderer = mujoco.Renderer(model, height, width)
    camera = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "overhead")
    out = np.empty((height, width, 3), np.uint8)

    def render():
        renderer.update_scene(data, camera)
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows
        renderer.render(out=out)

    return renderer, render


def measure(width: int, height: int, frames: int, repeats: int, seed: int = 0) -> dict:
    """Returns ``{shadows: {loop: median frames/s}}`` for one frame size."""
    env = task.load(seed=seed, cameras=("overhead",), width=width, height=height)
    env.reset()
    still = np.zeros(len(task.ACTION_NAMES))
    for _ in range(30):
        env.step(still)
    physics = env.physics
    model, data = physics.model.ptr, physics.data.ptr
    observable = env.task.observables["overhead_camera"]
    observe = observable.observation_callable(physics, np.random.RandomState(0))
    results = {}
    closers = []
    try:
        for shadows in (False, True):
            bare, bare_render = _bare_loop(model, data, width, height, shadows)
            frame_renderer = FrameRenderer(physics, width, height, shadows=shadows)
            closers += [bare, frame_renderer]
            loops = {
                "bare": bare_render,
                "FrameRenderer": lambda r=frame_renderer: r.render("overhead"),
            }
            if not shadows:
                loops["observable"] = observe
                loops["env step"] = lambda: env.step(still)
            for render in loops.values():
                render()  # warm up (first frame uploads textures)
            names = list(loops)
            rates = {name: [] for name in names}
            for r in range(repeats):
                for name in names[r % len(names) :] + names[: r % len(names)]:
                    rates[name].append(
                        _rate(loops[name], frames if not shadows else max(1, frames // 4))
                    )
            results[shadows] = {name: statistics.median(v) for name, v in rates.items()}
    finally:
        for closer in closers:
            closer.close()
        env.close()
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--sizes", default="320x240,640x480", help="comma-separated WIDTHxHEIGHT frame sizes"
    )
    parser.add_argument(
        "--frames",
        type=int,
        default=60,
        help="frames per measurement without shadows (a quarter with shadows)",
    )
    parser.add_argument("--repeats", type=int, default=5, help="interleaved repeats (median)")
    args = parser.parse_args()
    try:
        sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.sizes.split(",")]
    except ValueError:
        parser.error(f"--sizes must look like 320x240,640x480, got {args.sizes!r}")
    if any(len(s) != 2 or min(s) <= 0 for s in sizes) or args.frames <= 0 or args.repeats <= 0:
        parser.error("sizes, --frames and --repeats must be positive")
    print(
        f"mujoco {mujoco.__version__}, MUJOCO_GL={os.environ.get('MUJOCO_GL')}; "
        f"median of {args.repeats} interleaved repeats of {args.frames} frames "
        f"({max(1, args.frames // 4)} with shadows)"
    )
    for width, height in sizes:
        results = measure(width, height, args.frames, args.repeats)
        for shadows, rates in results.items():
            bare = rates["bare"]
            label = "with shadows" if shadows else "no shadows"
            for name, rate in rates.items():
                print(
                    f"  {width}x{height} {label:12s} {name:14s} {rate:7.1f} frames/s   "
                    f"{rate / bare:5.2f} x bare"
                )
        print(
            f"  {width}x{height} shadows cost: bare {results[False]['bare']:.1f} -> "
            f"{results[True]['bare']:.1f} frames/s "
            f"({results[False]['bare'] / results[True]['bare']:.1f} x slower)"
        )


if __name__ == "__main__":
    main()
