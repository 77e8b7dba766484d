"""What the sweep machinery costs, and what running cells at once gains, measured in one run.

    python benchmarks/bench_sweep.py                 # the quick preset without videos, seeds 0, 1
    python benchmarks/bench_sweep.py --train-steps 20000 --test-steps 10000

Three measurements of the same two cells (seeds 0 and 1), each in a fresh folder:

- direct: ``imitation.reproduce.run`` of each cell, one after the other, one process each cell
  (``workers = 1``, as the sweep runs its cells);
- sweep, one at a time: ``peoplebot sweep`` with a local Ray of one CPU (Ray start-up included):
  its overhead per cell against direct;
- sweep, two at once: a local Ray of two CPUs: its speed-up against direct.

Then the cells a day one machine (and N machines) would run, from the per-cell time.
"""

from __future__ import annotations

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import argparse
import pathlib
import shutil
import tempfile
import time

from imitation import reproduce, sweep
from imitation.config import RunConfig


def _timed(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def run(config: RunConfig, seeds=(0, 1)) -> dict[str, float]:
    """Returns the seconds of each measurement (see the module notes)."""
    root = pathlib.Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    try:
        direct = _timed(
            lambda: [
                reproduce.run(config.replace({"seed": s}), root / "direct" / f"seed{s}")
                for s in seeds
            ]
        )
        one = _timed(
            lambda: sweep.sweep(config, seeds, [], root / "one", workers=1, progress=False)
        )
        two = _timed(
            lambda: sweep.sweep(config, seeds, [], root / "two", workers=2, progress=False)
        )
    finally:
        shutil.rmtree(root, ignore_errors=True)
    return {"direct": direct, "sweep_one_at_a_time": one, "sweep_two_at_once": two}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train-steps", type=int, default=60_000)
    parser.add_argument("--test-steps", type=int, default=20_000)
    parser.add_argument("--trials", type=int, default=3)
    args = parser.parse_args()
    config = RunConfig.quick().replace(
        {
            "learning.train_steps": args.train_steps,
            "learning.test_steps": args.test_steps,
            "performance.trials": args.trials,
            "videos.enabled": False,
            "workers": 1,
        }
    )
    seconds = run(config)
    per_cell = seconds["direct"] / 2
    overhead = seconds["sweep_one_at_a_time"] / seconds["direct"] - 1
    speedup = seconds["direct"] / seconds["sweep_two_at_once"]
    print(
        f"two cells ({args.train_steps} training, {args.test_steps} test steps, {args.trials} "
        "trials per row, no videos)"
    )
    for name, value in seconds.items():
        print(f"  {name:22s} {value:7.1f} s")
    print(f"  sweep overhead per cell, one at a time: {100 * overhead:+.1f}% (goal <= 5%)")
    print(f"  two at once against one after the other: {speedup:.2f}x (goal >= 1.7x)")
    print(
        f"  per cell {per_cell:.1f} s: a 2-core machine runs {86400 / per_cell * speedup:.0f} "
        "such cells a day; N machines N times as many"
    )


if __name__ == "__main__":
    main()
