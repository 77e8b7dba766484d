"""Speed of the associator's training loop against a dense bound, and the sleep-sign study.

    python benchmarks/bench_associator.py            # updates/s, bound, ratio, batch recognition
    python benchmarks/bench_associator.py --study 300000   # both sleep signs on a synthetic teacher

The bound is what any implementation of the dense rules must at least do per wake+sleep step: two
dense 768 x 180 matrix-vector products (W_bu z and W_bu z^s), here in a tight numpy loop at the
model's precision. Everything runs on one thread (set before numpy is imported).
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from associator import synthetic  # noqa: E402
from associator.encoding import DIRECTIVES, WORDS  # noqa: E402
from associator.network import Associator  # noqa: E402


def bound_updates_per_second(n_steps: int, dtype: str) -> float:
    """Returns steps/s of two dense 768 x 180 mat-vec products per step."""
    rng = np.random.default_rng(0)
    w = rng.random((768, 180)).astype(dtype)
    z = rng.random(180).astype(dtype)
    z_sleep = rng.random(180).astype(dtype)
    start = time.perf_counter()
    for _ in range(n_steps):
        w @ z
        w @ z_sleep
    return n_steps / (time.perf_counter() - start)


def fast_updates_per_second(stream, n_steps: int, dtype: str) -> float:
    """Returns wake+sleep steps/s of ``Associator.partial_fit`` at the paper's sizes."""
    vision, language, motor, changed = (a[:n_steps] for a in stream)
    model = Associator(dtype=dtype, n_steps_total=10 * n_steps, rng=0)
    model.partial_fit(vision[:100], language[:100], motor[:100], changed[:100])  # set-up
    start = time.perf_counter()
    model.partial_fit(vision, language, motor, changed)
    return n_steps / (time.perf_counter() - start)


def speed(n_steps: int, repeats: int) -> None:
    """Prints updates/s of the training loop and of the bound, measured alternately (the machine
    may be shared: each pair is taken close in time), best of ``repeats`` each, and the ratio."""
    stream = synthetic.encode_stream(synthetic.teacher_stream(n_steps, rng=1))
    print(f"one thread; {n_steps} steps per measurement, best of {repeats}, alternating")
    for dtype in ("float32", "float64"):
        pairs = [
            (
                fast_updates_per_second(stream, n_steps, dtype),
                bound_updates_per_second(n_steps, dtype),
            )
            for _ in range(repeats)
        ]
        fast = max(f for f, _ in pairs)
        bound = max(b for _, b in pairs)
        ratios = sorted(f / b for f, b in pairs)
        print(
            f"{dtype}: fast {fast:9.0f} updates/s   bound {bound:9.0f} steps/s   "
            f"ratio of bests {fast / bound:5.2f}   per-pair ratios "
            + " ".join(f"{r:.2f}" for r in ratios)
        )
    vision, _, motor, _ = stream
    model = Associator(rng=0).fit(*(a[:1000] for a in stream))
    n = 1_000_000
    vision = np.tile(vision, (n // len(vision) + 1, 1))[:n]
    motor = np.tile(motor, (n // len(motor) + 1, 1))[:n]
    start = time.perf_counter()
    model.recognise_batch(vision, motor)
    print(f"recognise_batch: {n} samples in {time.perf_counter() - start:.1f} s (one thread)")


def study(n_steps: int, seed: int) -> None:
    """Trains both sleep signs at the paper's sizes and prints what each learned."""
    train = synthetic.encode_stream(synthetic.teacher_stream(n_steps, rng=seed))
    test_stream = synthetic.teacher_stream(100_000, rng=seed + 1)
    vision, _, motor, _ = synthetic.encode_stream(test_stream)
    print(
        f"synthetic teacher, {n_steps} training steps (seed {seed}), 100000 test steps; "
        f"word shares {np.bincount(test_stream.word, minlength=3) / len(test_stream.word)}"
    )
    for sign in ("self_organising", "printed"):
        start = time.perf_counter()
        model = Associator(sleep_sign=sign, n_steps_total=n_steps, rng=seed).fit(*train)
        seconds = time.perf_counter() - start
        recognised = model.recognise_batch(vision, motor)
        predicted = np.array([WORDS.index(w) for w in recognised.words])
        confusion = np.array(
            [[np.mean(predicted[test_stream.word == i] == j) for j in range(3)] for i in range(3)]
        )
        performed = model.perform_batch(vision, [WORDS[i] for i in test_stream.word])
        directive = np.array([DIRECTIVES.index(d) for d in performed.directives])
        recall = [np.mean(directive[test_stream.directive == k] == k) for k in range(4)]
        print(
            f"\nsleep_sign={sign}: trained in {seconds:.0f} s; "
            f"{len(np.unique(recognised.winners))} distinct winners while recognising"
        )
        print("recognition (rows: performed go/pick/lift; columns: recognised go/pick/lift)")
        for word, row in zip(WORDS, confusion, strict=True):
            print(f"  {word:5s}" + "".join(f"{v:8.3f}" for v in row))
        print(f"  balanced recognition accuracy {np.mean(np.diag(confusion)):.3f} (chance 0.333)")
        print(
            "motor recall per directive "
            + ", ".join(f"{d} {r:.3f}" for d, r in zip(DIRECTIVES, recall, strict=True))
            + f"; balanced {np.mean(recall):.3f} (chance 0.25); plain accuracy "
            f"{np.mean(directive == test_stream.directive):.3f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000, help="steps per speed measurement")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--study",
        type=int,
        default=0,
        metavar="N",
        help="instead of timing, train both sleep signs on N steps",
    )
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    if args.study:
        study(args.study, args.seed)
    else:
        speed(args.steps, args.repeats)


if __name__ == "__main__":
    main()
