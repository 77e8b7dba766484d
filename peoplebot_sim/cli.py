"""The ``peoplebot`` command line."""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL before anything imports mujoco)

RENDERS = pathlib.Path("renders")


def _positive_int(text: str) -> int:
    value = int(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return value


def _cmd_demo(args) -> int:
    from peoplebot_sim.demo import DemoConfig, run_demo

    config = DemoConfig(seconds=args.seconds, width=args.width, height=args.height, seed=args.seed,
                        camera=args.camera, speedup=args.speedup, video=not args.no_video,
                        shadows=not args.no_shadows)
    summary = run_demo(config, args.out, progress=not args.quiet)
    keys = ("simulated_seconds", "cycles_completed", "cycles_per_10_minutes", "time_share",
            "collisions", "watchdog_recoveries", "video", "wall_clock_seconds")
    print(json.dumps({k: summary[k] for k in keys}, indent=2))
    print(f"summary: {pathlib.Path(args.out).with_suffix('.json')}")
    return 0


def _cmd_track_bench(args) -> int:
    from peoplebot_sim import track_bench

    report = track_bench.run(args.samples, args.width, args.height, args.seed, args.out,
                             progress=not args.quiet)
    print(json.dumps(report, indent=2))
    print(f"written: {args.out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="peoplebot",
        description="A student PeopleBot learns go, pick and lift by watching a teacher PeopleBot.")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="video of the teacher looping go-pick-lift, with a summary")
    demo.add_argument("--seconds", type=_positive_float, default=180.0, help="simulated seconds")
    demo.add_argument("--width", type=_positive_int, default=640)
    demo.add_argument("--height", type=_positive_int, default=480)
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--camera", choices=("showcase", "overhead"), default="showcase")
    demo.add_argument("--speedup", type=_positive_float, default=2.0, help="playback speed")
    demo.add_argument("--out", type=pathlib.Path, default=RENDERS / "demo" / "teacher.mp4")
    demo.add_argument("--no-video", action="store_true", help="write the JSON summary only")
    demo.add_argument("--no-shadows", action="store_true")
    demo.add_argument("--quiet", action="store_true", help="no progress bar")
    demo.set_defaults(func=_cmd_demo)

    bench = sub.add_parser("track-bench", help="vision accuracy and speed on rendered frames")
    bench.add_argument("--samples", type=_positive_int, default=200, help="frames per viewpoint")
    bench.add_argument("--width", type=_positive_int, default=320)
    bench.add_argument("--height", type=_positive_int, default=240)
    bench.add_argument("--seed", type=int, default=0)
    bench.add_argument("--out", type=pathlib.Path, default=RENDERS / "track_bench.json")
    bench.add_argument("--quiet", action="store_true")
    bench.set_defaults(func=_cmd_track_bench)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValueError as error:
        print(f"peoplebot {args.command}: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
