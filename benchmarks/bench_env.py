"""Control steps per second of the imitation environment against raw MuJoCo, and of the stream
generator.

    python benchmarks/bench_env.py                     # 1000 steps per measurement, 7 repeats
    python benchmarks/bench_env.py --steps 500 --repeats 3

Every figure is a median over interleaved repeats (their order rotated each repeat), measured in one
run on one compiled model:

- env: ``peoplebot_sim.task.load()`` (dm-control's ``composer.Environment``) with cameras off,
  stepped with a still student action (the teacher drives itself);
- raw: ``mujoco.mj_step(m, d, nstep=10)`` per control step on the environment's compiled model and a
  copy of its state and controls, no Python per step beyond the call;
- streams: ``imitation.streams.StreamGenerator`` (teacher controller + ``mj_step``).

The task layer's share is ``(t_env - t_raw) / t_env`` per control step; the goal is at most 30%.
"""

from __future__ import annotations

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import argparse
import statistics
import time

import mujoco
import numpy as np

from imitation.streams import StreamGenerator
from peoplebot_sim import task


def _time_env(env, action, n_steps: int) -> float:
    """Returns seconds for ``n_steps`` environment steps (episodes never end: no time limit)."""
    start = time.perf_counter()
    for _ in range(n_steps):
        env.step(action)
    return time.perf_counter() - start


def _time_raw(model, data, n_steps: int, substeps: int) -> float:
    """Returns seconds for ``n_steps`` control steps of ``mj_step(m, d, nstep=substeps)``."""
    start = time.perf_counter()
    for _ in range(n_steps):
        mujoco.mj_step(model, data, substeps)
    return time.perf_counter() - start


def _time_stream(generator: StreamGenerator, n_steps: int) -> float:
    start = time.perf_counter()
    generator.generate(n_steps)
    return time.perf_counter() - start


def run(n_steps: int, repeats: int, seed: int = 0) -> dict[str, float]:
    """Returns the median control steps/s of each loop, measured interleaved."""
    config = task.TaskConfig()
    action = np.zeros(len(task.ACTION_NAMES))
    envs = {"env": task.load(config, seed=seed)}
    for env in envs.values():
        env.reset()
        _time_env(env, action, 50)  # warm up: the teacher is driving, caches are built
    reference = envs["env"]
    model = reference.physics.model.ptr
    data = mujoco.MjData(model)
    source = reference.physics.data.ptr
    data.qpos[:], data.qvel[:], data.ctrl[:] = source.qpos, source.qvel, source.ctrl
    data.time = source.time
    mujoco.mj_forward(model, data)
    substeps = int(round(config.control_timestep / config.physics_timestep))
    generator = StreamGenerator(seed, config)
    generator.generate(50)

    loops = {name: (lambda env=env: _time_env(env, action, n_steps)) for name, env in envs.items()}
    loops["raw"] = lambda: _time_raw(model, data, n_steps, substeps)
    loops["streams"] = lambda: _time_stream(generator, n_steps)
    names = list(loops)
    seconds = {name: [] for name in names}
    for r in range(repeats):
        for name in names[r % len(names) :] + names[: r % len(names)]:  # rotate the order
            seconds[name].append(loops[name]())
    for env in envs.values():
        env.close()
    return {name: n_steps / statistics.median(s) for name, s in seconds.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000, help="control steps per measurement")
    parser.add_argument("--repeats", type=int, default=7, help="interleaved repeats (median)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.steps <= 0 or args.repeats <= 0:
        parser.error(f"--steps and --repeats must be positive, got {args.steps}, {args.repeats}")
    rates = run(args.steps, args.repeats, args.seed)
    print(
        f"mujoco {mujoco.__version__}; {args.steps} control steps (0.1 s, 10 physics steps) per "
        f"measurement, median of {args.repeats} interleaved repeats"
    )
    raw = rates["raw"]
    for name, rate in rates.items():
        print(
            f"  {name:18s} {rate:8.0f} steps/s   {rate / raw:5.2f} x raw   "
            f"{rate * 0.1:7.0f} x real time"
        )
    share = (1.0 / rates["env"] - 1.0 / raw) / (1.0 / rates["env"])
    print(f"  task-layer share of a control step: {100 * share:5.1f}% (goal <= 30%)")
    print(f"  streams / env: {rates['streams'] / rates['env']:.2f}")


if __name__ == "__main__":
    main()
