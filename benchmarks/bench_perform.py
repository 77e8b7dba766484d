"""Speed of the hierarchical student's perform step: the pose components and directive tables
kept between steps (as shipped) against computed afresh at every step.

    python benchmarks/bench_perform.py                                   # a synthetic network
    python benchmarks/bench_perform.py --network renders/reproduce/truth-teacher-seed0/hierarchical.npz

One perform step is what a student does each 0.1 s control step: one vision code, one word,
``HierarchicalAssociator.perform``. Both loops perform the same codes and must give the same
directives and motor outputs. The student's support lookahead adds one density of four poses a
step (``HierarchicalAssociator.pose_log_density``), timed on its own. Everything runs on one
thread (set before numpy is imported).
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import copy  # noqa: E402
import pathlib  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from associator import persistence, synthetic  # noqa: E402
from associator.encoding import WORDS  # noqa: E402
from associator.hierarchy import HierarchicalAssociator  # noqa: E402
from associator.network import Associator  # noqa: E402


def synthetic_network(n_steps: int) -> HierarchicalAssociator:
    """Returns a hierarchical network (the default lower map) trained and counted on ``n_steps``
    of the synthetic teacher."""
    train = synthetic.encode_stream(synthetic.teacher_stream(n_steps, rng=1))
    model = HierarchicalAssociator(lower=Associator(n_steps_total=n_steps, rng=0))
    return model.fit(*train).count_word_statistics(*train[:3])


def perform_all(model: HierarchicalAssociator, vision: np.ndarray, words) -> tuple:
    """Returns (seconds, motor outputs (n, 4)) of one perform step per code."""
    motor = np.empty((len(vision), 4))
    start = time.perf_counter()
    for i, (code, word) in enumerate(zip(vision, words, strict=True)):
        motor[i] = model.perform(code, word).motor
    return time.perf_counter() - start, motor


def densities_all(model: HierarchicalAssociator, vision: np.ndarray, words) -> float:
    """Returns the seconds of one four-pose density a step (the support lookahead's), the four
    codes being the step's code and its next three."""
    start = time.perf_counter()
    for i, word in enumerate(words):
        model.pose_log_density(vision[i : i + 4], word)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--network", type=pathlib.Path, help="a run's hierarchical.npz")
    parser.add_argument("--train-steps", type=int, default=30_000, help="without --network")
    parser.add_argument("--steps", type=int, default=600, help="perform steps timed (600)")
    args = parser.parse_args()
    if args.network is not None:
        model = persistence.load(args.network)
        source = str(args.network)
    else:
        model = synthetic_network(args.train_steps)
        source = f"synthetic teacher, {args.train_steps} steps"
    stream = synthetic.teacher_stream(args.steps, rng=2)
    vision = synthetic.encode_stream(stream)[0]
    words = [WORDS[i] for i in stream.word]
    model.perform(vision[0], words[0])  # the kept tables computed once, outside the timing
    kept_s, kept = perform_all(model, vision, words)
    afresh_model = copy.copy(model)
    afresh_model._derived = lambda name, compute: compute()
    afresh_s, afresh = perform_all(afresh_model, vision, words)
    if not np.array_equal(kept, afresh):
        raise SystemExit("the kept tables changed the motor outputs")
    print(f"network: {source} ({model.lower_.n_hidden} lower units)")
    print(f"perform steps: {args.steps}, identical outputs")
    print(f"kept tables:     {1000 * kept_s / args.steps:.2f} ms a step")
    print(f"computed afresh: {1000 * afresh_s / args.steps:.2f} ms a step")
    print(f"speed-up: {afresh_s / kept_s:.1f}x")
    density_s = densities_all(model, np.vstack([vision, vision[:3]]), words)
    print(f"support lookahead (4 densities): {1000 * density_s / args.steps:.2f} ms a step")


if __name__ == "__main__":
    main()
