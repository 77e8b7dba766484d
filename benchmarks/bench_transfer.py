"""What ``peoplebot transfer`` costs against its targets, measured in one run.

    python benchmarks/bench_transfer.py --reuse-from renders/reproduce/truth-teacher-seed0
    python benchmarks/bench_transfer.py --reuse-from RUN --default   # also the default grid

Each grid runs as a user types it (``peoplebot transfer --reuse-from RUN [--quick] --workers N``,
a subprocess into a fresh temporary folder: Ray's start-up, the imports and checking the run's
files included), truth mode. Printed per grid: its cells, wall seconds against the target
(``--quick`` within 5 minutes, the default grid within 30, on 2 cores), and the cells' CPU
seconds from ``transfer.json`` (their sum over the wall time: how much of the cores it used).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

#: Wall-clock targets of the transfer grids, seconds (issue "Transfer tests toward real robots").
TARGET_S = {"quick": 5 * 60, "default": 30 * 60}


def run_grid(source: pathlib.Path, grid: str, workers: int) -> dict:
    """Runs one grid (``quick`` or ``default``) of ``peoplebot transfer`` on ``source``; returns
    its cells, wall seconds and the cells' summed CPU seconds."""
    peoplebot = pathlib.Path(sys.executable).parent / "peoplebot"
    out = pathlib.Path(tempfile.mkdtemp(prefix=f"bench_transfer_{grid}_"))
    command = [str(peoplebot), "transfer", "--reuse-from", str(source), "--workers", str(workers)]
    command += ["--out", str(out / "transfer")] + (["--quick"] if grid == "quick" else [])
    try:
        start = time.perf_counter()
        finished = subprocess.run(command, stdout=subprocess.DEVNULL)
        wall_s = time.perf_counter() - start
        if finished.returncode:  # the command's own one-line error is on stderr
            raise SystemExit(finished.returncode)
        summary = json.loads((out / "transfer" / "transfer.json").read_text())
    finally:
        shutil.rmtree(out, ignore_errors=True)
    return {"cells": summary["cells"], "wall_s": wall_s, "cpu_s": float(summary["cpu_seconds"])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reuse-from", type=pathlib.Path, required=True, help="a finished run")
    parser.add_argument("--default", action="store_true", help="also the default grid")
    parser.add_argument("--workers", type=int, default=2, help="cells at once (default 2)")
    args = parser.parse_args()
    for grid in ("quick", "default") if args.default else ("quick",):
        r = run_grid(args.reuse_from, grid, args.workers)
        target = TARGET_S[grid]
        print(
            f"{grid}: {r['cells']} cells, {r['wall_s']:.0f} s wall (target {target} s: "
            f"{'met' if r['wall_s'] <= target else 'missed'}), cells' CPU {r['cpu_s']:.0f} s "
            f"({r['cpu_s'] / r['wall_s']:.2f} cores busy on average)"
        )


if __name__ == "__main__":
    main()
