"""The ``peoplebot`` command line."""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL before anything imports mujoco)

# isort: split
from imitation.calibrate import DEFAULT_BOARD_SPEC
from imitation.limits import BRAKE_LIMITS
from imitation.observers import OVERHEAD_REGISTRATIONS
from imitation.speedgain import SUPPORT_SPEEDS
from peoplebot_sim.viewpoints import VIEWS

RENDERS = pathlib.Path("renders")
#: The named perturbation level sets (``imitation.perturbations.PRESETS``).
PERTURBATION_PRESETS = ("realistic",)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (the bad argument and where to look), exit
    status 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


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
    from imitation.demo import DemoConfig, run_demo

    config = DemoConfig(
        seconds=args.seconds,
        width=args.width,
        height=args.height,
        seed=args.seed,
        camera=args.camera,
        speedup=args.speedup,
        video=not args.no_video,
        shadows=not args.no_shadows,
        mcap=args.mcap,
        preset=args.preset or "",
    )
    summary = run_demo(config, args.out, progress=not args.quiet)
    keys = (
        "simulated_seconds",
        "cycles_completed",
        "cycles_per_10_minutes",
        "time_share",
        "collisions",
        "watchdog_recoveries",
        "video",
        "mcap",
        "wall_clock_seconds",
    )
    print(json.dumps({k: summary[k] for k in keys}, indent=2))
    print(f"summary: {pathlib.Path(args.out).with_suffix('.json')}")
    return 0


def _cmd_track_bench(args) -> int:
    from imitation import track_bench

    report = track_bench.run(
        args.samples,
        args.width,
        args.height,
        args.seed,
        args.out,
        progress=not args.quiet,
        **({} if args.parts is None else {"parts": tuple(args.parts)}),
    )
    print(json.dumps(report, indent=2))
    print(f"written: {args.out}")
    return 0


BRAKE_AHEAD_HELP = (
    "on: the students, told their robot's acceleration limits, ask their network at the pose "
    "where braking now would bring them to rest; off: at their pose (default: the run's "
    "performance.brake_ahead, on; no change on a robot without limits)"
)

BRAKE_LIMITS_HELP = (
    "told: the students brake ahead at the student robot's acceleration limits "
    "(perturbations.actuation); estimated: at the limits they identify from their robot's "
    "response to their own commands during each trial, a robot of unknown limits (default: the "
    "run's performance.brake_limits, told)"
)

SUPPORT_SPEEDS_HELP = (
    "the speeds the hierarchical student's support lookahead follows each directive at: "
    "nominal, its wheel commands; measured, those scaled by the fractions of them the robot "
    "is measured to achieve during each trial (a robot whose casters drag); measured_forward, "
    "the forward speed scaled so and the yaw rate nominal (default: the run's "
    "performance.support_speeds, measured_forward)"
)

OVERHEAD_REGISTRATION_HELP = (
    "the overhead mode's camera pose: believed, as calibrated (with the preset's calibration "
    "error), or floor_markers, fitted once to the camera's photo of the floor markers "
    "(models/arena/floor_markers.toml) with the intrinsics as believed (default: the run's "
    "vision.overhead_registration, believed)"
)

#: Options ``reproduce`` and ``transfer`` share (``_add_student_options``) and the config keys
#: they set (``--brake-ahead``, on/off, is mapped on its own).
STUDENT_OPTIONS = {
    "brake_limits": "performance.brake_limits",
    "support_speeds": "performance.support_speeds",
    "overhead_registration": "vision.overhead_registration",
}

#: Command-line options of ``reproduce`` and the config keys they set.
REPRODUCE_OPTIONS = {
    "seed": "seed",
    "vision": "vision.mode",
    "motor_source": "learning.motor_source",
    "train_steps": "learning.train_steps",
    "test_steps": "learning.test_steps",
    "vision_test_steps": "vision.test_steps",
    "self_localisation": "vision.self_localisation",
    "trials": "performance.trials",
    "trial_seconds": "performance.trial_seconds",
    "workers": "workers",
    "drive": "performance.drive",
    **STUDENT_OPTIONS,
}


def reproduce_config(args):
    """Returns the run configuration the ``reproduce`` options ask for: the defaults or the quick
    preset, then ``--config``'s file, then the other options."""
    from imitation import config as run_config
    from imitation import perturbations

    config = run_config.RunConfig.quick() if args.quick else run_config.RunConfig()
    if args.config is not None:
        config = run_config.load(args.config, base=config)
    if getattr(args, "preset", None) is not None:
        config = dataclasses.replace(config, perturbations=perturbations.preset(args.preset))
    changes = {
        key: getattr(args, option)
        for option, key in REPRODUCE_OPTIONS.items()
        if getattr(args, option) is not None
    }
    if args.no_videos:
        changes["videos.enabled"] = False
    if args.paper_only:
        changes["hierarchical.enabled"] = False
    if args.mcap:
        changes["videos.mcap"] = True
    if getattr(args, "randomise", None) is not None:
        from imitation import randomisation

        changes["randomisation.families"] = list(randomisation.parse_families(args.randomise))
    if getattr(args, "randomise_level", None) is not None:
        changes["randomisation.upper_level"] = args.randomise_level
    if getattr(args, "brake_ahead", None) is not None:
        changes["performance.brake_ahead"] = args.brake_ahead == "on"
    return config.replace(changes)


def _randomisation_suffix(chosen) -> str:
    """Returns the run folder's suffix for a randomisation other than the default one."""
    from imitation.randomisation import RandomisationConfig

    if chosen == RandomisationConfig():
        return ""
    return "-randomised-" + "-".join(chosen.families) if chosen.active else "-unrandomised"


def _options_suffix(args) -> str:
    """Returns the default folder's suffix for an explicit ``--brake-ahead``, ``--brake-limits``,
    ``--support-speeds`` and ``--overhead-registration`` (``_add_student_options``)."""
    suffix = "" if args.brake_ahead is None else f"-brake-ahead-{args.brake_ahead}"
    if args.brake_limits is not None:
        suffix += f"-brake-limits-{args.brake_limits}"
    if args.support_speeds is not None:
        suffix += f"-support-speeds-{args.support_speeds}"
    if args.overhead_registration is not None:
        suffix += f"-overhead-{args.overhead_registration.replace('_', '-')}"
    return suffix


def _cmd_reproduce(args) -> int:
    from imitation.reproduce import run

    config = reproduce_config(args)
    vision = config.vision.mode
    if vision == "head" and config.vision.self_localisation == "odometry":
        vision = "head_odometry"
    out = args.out or RENDERS / ("reproduce-quick" if args.quick else "reproduce") / (
        f"{vision}-{config.learning.motor_source}-seed{config.seed}"
        + _randomisation_suffix(config.randomisation)
        + _options_suffix(args)
    )
    results = run(config, out, fresh=args.fresh, reuse_from=args.reuse_from)
    print((pathlib.Path(out) / "results.md").read_text())
    print(f"run folder: {out} (config.toml, results.json, results.md, figures/, videos)")
    return 0 if results else 1


def _cmd_sweep(args) -> int:
    from imitation import sweep

    if not args.run or args.run[0] != "reproduce":
        raise ValueError(
            "say what each cell runs: peoplebot sweep --out DIR ... reproduce [its options]"
        )
    run_args = build_parser().parse_args(["reproduce", *args.run[1:]])
    for option in ("out", "fresh", "reuse_from"):
        if getattr(run_args, option) not in (None, False):
            raise ValueError(
                f"--{option.replace('_', '-')} is the sweep's to choose (each cell is "
                f"DIR/cells/<name>/); leave it out of the cells' options"
            )
    base = reproduce_config(run_args)
    seeds = sweep.parse_seeds(args.seeds) if args.seeds else (base.seed,)
    settings = [sweep.parse_setting(text) for text in args.set]
    summary = sweep.sweep(
        base, seeds, settings, args.out, address=args.address, workers=args.workers
    )
    out = pathlib.Path(args.out)
    print((out / "sweep.md").read_text())
    print(f"sweep folder: {out} (sweep.json, sweep.md, figures/, cells/)")
    return 1 if summary["counts"]["failed"] else 0


def student_changes(args) -> dict:
    """Returns the config changes of the explicit ``STUDENT_OPTIONS`` among ``args``."""
    return {
        key: getattr(args, option)
        for option, key in STUDENT_OPTIONS.items()
        if getattr(args, option) is not None
    }


def _cmd_transfer(args) -> int:
    from imitation import perturbations, transfer, transfer_runs

    scale = transfer.SCALES["quick" if args.quick else "default"]
    changes = {
        "performance.trials": args.trials or scale.trials,
        "vision.test_steps": args.vision_test_steps or scale.recognition_steps,
        "workers": args.trial_processes,
    }
    if args.trial_seconds is not None:
        changes["performance.trial_seconds"] = args.trial_seconds
    if args.brake_ahead is not None:
        changes["performance.brake_ahead"] = args.brake_ahead == "on"
    changes.update(student_changes(args))
    sources = transfer_runs.expand_sources(args.reuse_from)
    if not sources:
        raise ValueError(f"--reuse-from {args.reuse_from[0]} is a sweep folder without run cells")
    several = len(sources) > 1
    if several and args.compare is not None:
        raise ValueError(
            f"--compare takes one --reuse-from run, got {len(sources)} runs; compare them one "
            "seed at a time"
        )
    vision = args.vision or transfer.source_run(sources[0]).vision.mode
    if len(args.reuse_from) == 1:  # a run, or a sweep folder
        name = args.reuse_from[0].resolve().name
    else:
        name = f"{sources[0].name}-to-{sources[-1].name}"
    out = args.out or RENDERS / "transfer" / (
        f"{name}-{vision}" + (f"-{args.preset}" if args.preset else "") + _options_suffix(args)
    )
    families = args.families
    if families is None and scale.families is not None:
        families = ",".join(scale.families)
    options = dict(
        families=transfer.parse_families(families, vision),
        levels=transfer.parse_levels(args.levels),
        vision=args.vision,
        base_perturbations=perturbations.preset(args.preset) if args.preset else None,
        changes=changes,
        fresh=args.fresh,
        address=args.address,
        workers=args.workers,
        combined=None if args.combined == "none" else args.combined,
    )
    try:
        if several:
            transfer_runs.transfer_runs(sources, out, **options)
        else:
            transfer.transfer(
                sources[0], out, compare=args.compare, compare_label=args.compare_label, **options
            )
    except transfer.CellsFailed as error:
        print(f"peoplebot transfer: {error}", file=sys.stderr)
        return 1
    print((pathlib.Path(out) / "transfer.md").read_text())
    runs = ", <run>/ per run" if several else ""
    print(f"transfer folder: {out} (transfer.json, transfer.md, figures/, cells/{runs})")
    return 0


def _cmd_watch(args) -> int:
    from imitation import watch

    summary = watch.run(
        args.video,
        args.camera_info,
        args.arena,
        args.out,
        network=args.network,
        frame_seconds=args.frame_seconds,
        mcap=args.mcap,
    )
    print(
        json.dumps({k: summary[k] for k in ("frames", "frame_seconds", "seen_fraction")}, indent=2)
    )
    print(f"written: {args.out} ({', '.join(summary['files'])})")
    return 0


def _cmd_calibrate(args) -> int:
    from imitation import calibrate
    from perception.calibration import CalibrationConfig

    summary = calibrate.run(
        args.images,
        calibrate.parse_board_spec(args.board),
        args.out,
        CalibrationConfig(
            distortion=args.distortion,
            fix_principal_point=args.fix_principal_point,
            square_pixels=args.square_pixels,
            min_corners=args.min_corners,
        ),
        camera_name=args.camera_name,
    )
    print(json.dumps(summary, indent=2, default=str))
    return 0


def _cmd_register(args) -> int:
    from imitation import register

    summary = register.run(
        args.photo, args.camera_info, args.markers, args.arena, args.out, args.min_markers
    )
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_markers(args) -> int:
    from imitation import printables

    landmarks = None
    if args.landmarks is not None:
        from perception.landmarks import read_landmark_map

        landmarks = read_landmark_map(args.landmarks)
    summary = printables.write_plates_pdf(args.out, paper=args.paper, landmarks=landmarks)
    sheets = sorted({page["sheet"] for page in summary["pages"]})
    print(
        f"written: {args.out} ({len(summary['pages'])} pages on {', '.join(sheets)}; print at 100% "
        "and check each sheet's 10 cm bar)"
    )
    return 0


def _cmd_figures(args) -> int:
    from associator import figures, persistence
    from associator.network import Associator

    model = persistence.load(args.network)
    out = pathlib.Path(args.out)
    if not isinstance(model, Associator):
        raise ValueError(
            f"{args.network} holds a {type(model).__name__}; the paper's figures need the paper's "
            "network (a run folder's network.npz)"
        )
    out.mkdir(parents=True, exist_ok=True)
    written = [
        figures.fig3_word_codes(out / "fig3_word_codes.png"),
        figures.fig5_language_weights(model, out / "fig5_language_weights.png"),
        figures.fig6_motor_weights(model, out / "fig6_motor_weights.png"),
    ]
    print("\n".join(str(p) for p in written))
    return 0


def _add_student_options(parser: argparse.ArgumentParser) -> None:
    """Adds the options ``reproduce`` and ``transfer`` share for how the students drive and see:
    ``--brake-ahead``, ``--brake-limits``, ``--support-speeds``, ``--overhead-registration``
    (default: the run's)."""
    parser.add_argument("--brake-ahead", choices=("on", "off"), default=None, help=BRAKE_AHEAD_HELP)
    parser.add_argument(
        "--brake-limits", choices=BRAKE_LIMITS, default=None, help=BRAKE_LIMITS_HELP
    )
    parser.add_argument(
        "--support-speeds", choices=SUPPORT_SPEEDS, default=None, help=SUPPORT_SPEEDS_HELP
    )
    parser.add_argument(
        "--overhead-registration",
        choices=OVERHEAD_REGISTRATIONS,
        default=None,
        help=OVERHEAD_REGISTRATION_HELP,
    )


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="peoplebot",
        description="A student PeopleBot learns go, pick and lift by watching a teacher PeopleBot.",
    )
    parser.add_argument(
        "--debug", action="store_true", help="show the traceback of an expected failure too"
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    debug = _Parser(add_help=False)
    debug.add_argument(
        "--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS
    )
    defaults = {"formatter_class": argparse.ArgumentDefaultsHelpFormatter, "parents": [debug]}

    demo = sub.add_parser(
        "demo", help="video of the teacher looping go-pick-lift, with a summary", **defaults
    )
    demo.add_argument(
        "--seconds", type=_positive_float, default=180.0, help="simulated seconds to run"
    )
    demo.add_argument(
        "--width", type=_positive_int, default=640, help="video width, pixels (even, up to 1280)"
    )
    demo.add_argument(
        "--height", type=_positive_int, default=480, help="video height, pixels (even, up to 960)"
    )
    demo.add_argument(
        "--seed", type=int, default=0, help="the environment's seed: teacher start and jitter"
    )
    demo.add_argument(
        "--camera",
        choices=VIEWS,
        default="showcase",
        help="the view: showcase (oblique, the whole arena), follow (behind and above the "
        "teacher, with a table close-up while it docks) or overhead (a real-time recording "
        "that peoplebot watch takes)",
    )
    demo.add_argument(
        "--speedup",
        type=_positive_float,
        default=2.0,
        help="playback speed: simulated seconds per second of video",
    )
    demo.add_argument(
        "--out",
        type=pathlib.Path,
        default=RENDERS / "demo" / "teacher.mp4",
        help="the video; the summary goes beside it as .json",
    )
    demo.add_argument(
        "--no-video", action="store_true", help="write the JSON summary only (much faster)"
    )
    demo.add_argument(
        "--no-shadows", action="store_true", help="render without shadows (faster on the CPU)"
    )
    demo.add_argument(
        "--mcap",
        action="store_true",
        help="also write the episode as a ROS 2 MCAP log (<out>.mcap)",
    )
    demo.add_argument(
        "--preset",
        choices=PERTURBATION_PRESETS,
        default=None,
        help="a named perturbation level set (docs/transfer.md): the room's appearance and, for "
        "an overhead recording, its frames' image faults and the calibration written beside it",
    )
    demo.add_argument("--quiet", action="store_true", help="no progress bar")
    demo.set_defaults(func=_cmd_demo)

    bench = sub.add_parser(
        "track-bench", help="vision accuracy and speed on rendered frames", **defaults
    )
    bench.add_argument("--samples", type=_positive_int, default=200, help="frames per viewpoint")
    bench.add_argument("--width", type=_positive_int, default=320, help="frame width, pixels")
    bench.add_argument("--height", type=_positive_int, default=240, help="frame height, pixels")
    bench.add_argument("--seed", type=int, default=0, help="the sampled poses")
    bench.add_argument(
        "--out", type=pathlib.Path, default=RENDERS / "track_bench.json", help="the JSON report"
    )
    bench.add_argument(
        "--parts",
        nargs="+",
        default=None,
        help="which parts run (default all): viewpoints (single frames), sequence (tracking over "
        "--samples steps, the student standing, with the head's glance cost), self_localisation "
        "(3 x --samples steps, the student driving)",
    )
    bench.add_argument("--quiet", action="store_true", help="no progress bar")
    bench.set_defaults(func=_cmd_track_bench)

    rep = sub.add_parser(
        "reproduce",
        help="the paper's experiment end to end: watch, learn, recognise, perform",
        parents=[debug],
    )
    rep.add_argument(
        "--quick",
        action="store_true",
        help="the 'quick' preset: the same stages at a small scale (about a minute on 2 cores); "
        "the defaults in brackets below are the full run's",
    )
    rep.add_argument(
        "--config",
        type=pathlib.Path,
        default=None,
        help="a run configuration (TOML or JSON, e.g. a run folder's config.toml; keys left out "
        "keep the defaults, or the quick preset's with --quick); the other options override it",
    )
    rep.add_argument(
        "--preset",
        choices=PERTURBATION_PRESETS,
        default=None,
        help="test the student on a perturbed robot: a named level set of [perturbations] "
        "(realistic: ARIA accelerations, 50 ms camera and command latency, camera noise and mild "
        "blur, 2%% calibration error, encoder noise, caster friction; docs/transfer.md); "
        "replaces --config's [perturbations]",
    )
    rep.add_argument(
        "--randomise",
        default=None,
        metavar="FAMILIES",
        help="domain randomisation while the student learns: the training stream seen through "
        "these perception families (pose_noise, latency, dropout, occlusion, comma-separated, or "
        "all; none: off), each minute drawing every family's level uniformly up to "
        "--randomise-level (docs/transfer.md; default pose_noise,latency)",
    )
    rep.add_argument(
        "--randomise-level",
        type=int,
        default=None,
        help="the highest level of each randomised family's grid that is drawn (default 3)",
    )
    rep.add_argument(
        "--vision",
        choices=("truth", "overhead", "head"),
        default=None,
        help="how the student sees the robots (default: truth, the paper's setting)",
    )
    rep.add_argument(
        "--motor-source",
        choices=("teacher", "vision"),
        default=None,
        help="the teacher's directive is given (default) or inferred from motion",
    )
    rep.add_argument(
        "--seed", type=int, default=None, help="one seed for streams, networks and trials (0)"
    )
    rep.add_argument(
        "--train-steps", type=_positive_int, default=None, help="steps watched to learn (1000000)"
    )
    rep.add_argument(
        "--test-steps",
        type=_positive_int,
        default=None,
        help="steps watched for Table I (1000000)",
    )
    rep.add_argument(
        "--vision-test-steps",
        type=_positive_int,
        default=None,
        help="steps watched through the camera for recognition (camera modes)",
    )
    rep.add_argument(
        "--self-localisation",
        choices=("landmarks", "odometry"),
        default=None,
        help="the head mode's own pose: wall landmarks and odometry from an unknown start "
        "(default) or odometry alone from the known start",
    )
    rep.add_argument(
        "--trials", type=_positive_int, default=None, help="random starts per word (50)"
    )
    rep.add_argument(
        "--trial-seconds", type=_positive_float, default=None, help="length of a trial (60)"
    )
    rep.add_argument("--workers", type=_positive_int, default=None, help="parallel processes (2)")
    rep.add_argument(
        "--drive",
        choices=("graded", "directive"),
        default=None,
        help="the student's wheels follow its graded motor activations (default) or the "
        "strongest directive",
    )
    _add_student_options(rep)
    rep.add_argument("--no-videos", action="store_true", help="skip the student videos")
    rep.add_argument(
        "--mcap",
        action="store_true",
        help="with each student video, a ROS 2 MCAP log of the episode (student_<word>.mcap)",
    )
    rep.add_argument(
        "--paper-only",
        action="store_true",
        help="only the paper's network (no hierarchical associator row)",
    )
    rep.add_argument(
        "--out",
        type=pathlib.Path,
        default=None,
        help="run folder, resumed if present (renders/reproduce/<vision>-<motor source>-seed<seed>)",
    )
    rep.add_argument(
        "--fresh",
        action="store_true",
        help="remove everything an earlier run wrote into the folder, then start over",
    )
    rep.add_argument(
        "--reuse-from",
        type=pathlib.Path,
        default=None,
        help="take the streams and trained networks of this finished run folder (same seed, motor "
        "source, steps and networks; the hierarchical student's performing-only settings may "
        "differ): compare vision modes or read-outs on one network",
    )
    rep.set_defaults(func=_cmd_reproduce)

    tra = sub.add_parser(
        "transfer",
        help="a trained run's networks under each perturbation family and level: recognition, "
        "performing and the operating envelope (docs/transfer.md)",
        description="A trained run's networks under each perturbation family and level, as Ray "
        "tasks. By default: every family that acts in the vision mode at 3 levels (0, the "
        "anchor's level and one past it), 10 trials per row and policy of the source's trial "
        "length, 3000 recognition steps, and one cell of every family at once at the realistic "
        "preset's levels; in the 'truth' mode 22 cells, about 12 minutes on 2 idle cores "
        "(--quick: 10 cells, about 2 minutes). Camera modes watch and perform through "
        "the camera and take far longer. Timings and grids: docs/transfer.md.",
        parents=[debug],
    )
    tra.add_argument(
        "--reuse-from",
        type=pathlib.Path,
        nargs="+",
        required=True,
        metavar="RUN",
        help="the finished run folder whose networks and test stream are tested; several runs "
        "that differ by seed only, or a sweep folder (its cells), give the envelope over the "
        "seeds (each run's grid in OUT/<run folder>/, the mean and the worst run in OUT)",
    )
    tra.add_argument(
        "--out",
        type=pathlib.Path,
        default=None,
        help="the transfer's folder (default: renders/transfer/<run or sweep folder>-<vision>"
        "[-<preset>], for several runs <first>-to-<last>-<vision>[-<preset>]); rerun to resume",
    )
    tra.add_argument(
        "--compare",
        type=pathlib.Path,
        default=None,
        metavar="RUN",
        help="another finished run (e.g. one trained with --randomise) whose students are tested "
        "in the same cells and shown in the same figures and envelope table",
    )
    tra.add_argument(
        "--compare-label",
        default=None,
        help="the compared students' tag, '<policy> (<label>)' (default: 'randomised' or "
        "'unrandomised' when only one of the two runs was trained with domain randomisation, "
        "else the compared run's folder name)",
    )
    tra.add_argument(
        "--families",
        default=None,
        help="comma-separated families (default: every family that acts in the vision mode, "
        "10 in 'truth', 21 in 'overhead', 22 in 'head'; see docs/transfer.md), e.g. "
        "latency,dropout",
    )
    tra.add_argument(
        "--levels",
        default=None,
        help="comma-separated level numbers of each family's grid, 0 = off, or 'all' (default: "
        "0, the level of the family's anchor and one past it)",
    )
    tra.add_argument(
        "--quick",
        action="store_true",
        help="a first look: the families pose_noise, latency, command_latency and acceleration, "
        "3 trials per row, 1500 recognition steps (about 2 minutes on 2 idle cores in the "
        "'truth' mode)",
    )
    tra.add_argument(
        "--vision",
        choices=("truth", "overhead", "head"),
        default=None,
        help="how the student sees (default: the source run's mode)",
    )
    tra.add_argument(
        "--preset",
        choices=PERTURBATION_PRESETS,
        default=None,
        help="perturbations under every level (e.g. realistic); default none",
    )
    _add_student_options(tra)
    tra.add_argument(
        "--combined",
        choices=(*PERTURBATION_PRESETS, "none"),
        default="realistic",
        help="one more cell with every family at once at this preset's levels, the report's "
        "combined row (default realistic; none: no such cell; none either with --preset, whose "
        "levels are then the baseline's)",
    )
    tra.add_argument(
        "--trials",
        type=_positive_int,
        default=None,
        help="trials per row and policy (default 10, --quick 3)",
    )
    tra.add_argument(
        "--trial-seconds",
        type=_positive_float,
        default=None,
        help="seconds per trial (default: the source run's)",
    )
    tra.add_argument(
        "--vision-test-steps",
        type=_positive_int,
        default=None,
        help="steps watched for recognition per cell (default 3000, --quick 1500)",
    )
    tra.add_argument(
        "--address",
        default=None,
        help="a Ray cluster to run the cells on, whose nodes see the source run and --out at the "
        "same paths (else RAY_ADDRESS, else a local Ray on this machine)",
    )
    tra.add_argument(
        "--workers",
        type=_positive_int,
        default=None,
        help="cells at once (default: this machine's cores on a local Ray, all on a cluster)",
    )
    tra.add_argument(
        "--trial-processes",
        type=_positive_int,
        default=1,
        help="processes for one cell's trials (default 1; each cell's Ray task reserves as many "
        "CPUs)",
    )
    tra.add_argument(
        "--fresh",
        action="store_true",
        help="start every chosen cell over (a cell made with other settings is refused without it)",
    )
    tra.set_defaults(func=_cmd_transfer)

    sweep = sub.add_parser(
        "sweep",
        help="a grid of reproduce runs over seeds and settings, on Ray (local or a cluster)",
        **defaults,
    )
    sweep.add_argument("--out", type=pathlib.Path, required=True, help="the sweep's folder")
    sweep.add_argument(
        "--seeds", default=None, help="seeds: a range 0-4 or a list 0,3,7 (default: the run's seed)"
    )
    sweep.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=V1,V2",
        help="a config key and its values (e.g. network.pose_weight=0.01,0.03); repeatable",
    )
    sweep.add_argument(
        "--address",
        default=None,
        help="a Ray cluster to join (else RAY_ADDRESS, else a local Ray on this machine)",
    )
    sweep.add_argument(
        "--workers",
        type=_positive_int,
        default=None,
        help="cells at once (default: this machine's cores on a local Ray, all on a cluster)",
    )
    sweep.add_argument(
        "run", nargs=argparse.REMAINDER, help="reproduce [its options]: what each cell runs"
    )
    sweep.set_defaults(func=_cmd_sweep)

    watch = sub.add_parser(
        "watch",
        help="the student's perception and a trained network over a recorded video",
        **defaults,
    )
    watch.add_argument(
        "video", type=pathlib.Path, help="an mp4 (or any video) or a folder of images"
    )
    watch.add_argument(
        "--camera-info", type=pathlib.Path, required=True, help="the camera's ROS camera_info YAML"
    )
    watch.add_argument(
        "--arena",
        type=pathlib.Path,
        required=True,
        help="the arena file: walls, table and the fixed camera's pose (models/arena/arena.toml "
        "is the simulated arena's, without a camera)",
    )
    watch.add_argument(
        "--network",
        type=pathlib.Path,
        default=None,
        help="a run folder (its network.npz and hierarchical.npz) or one network .npz",
    )
    watch.add_argument(
        "--frame-seconds",
        type=_positive_float,
        default=None,
        help="seconds between frames (default: the video's 1/fps; 0.1 for images)",
    )
    watch.add_argument(
        "--mcap", action="store_true", help="also write watched.mcap, a ROS 2 log of what it saw"
    )
    watch.add_argument("--out", type=pathlib.Path, required=True, help="folder for what it writes")
    watch.set_defaults(func=_cmd_watch)

    cal = sub.add_parser(
        "calibrate",
        help="camera intrinsics and distortion from photos of the ChArUco board",
        **defaults,
    )
    cal.add_argument(
        "images", nargs="+", type=pathlib.Path, help="photos of the board: files and/or folders"
    )
    cal.add_argument(
        "--board",
        default=DEFAULT_BOARD_SPEC,
        help="SQUARES_XxSQUARES_Y:SQUARE_M:MARKER_M[:DICTIONARY], the printed board "
        "(peoplebot markers prints the default)",
    )
    cal.add_argument(
        "--out", type=pathlib.Path, default=pathlib.Path("camera_info.yaml"), help="the ROS YAML"
    )
    cal.add_argument("--camera-name", default="camera", help="camera_name in the YAML")
    cal.add_argument(
        "--distortion",
        choices=("plumb_bob", "radial", "none"),
        default="plumb_bob",
        help="the lens model fitted (radial: no tangential terms, no k3)",
    )
    cal.add_argument(
        "--fix-principal-point", action="store_true", help="keep the principal point at the centre"
    )
    cal.add_argument("--square-pixels", action="store_true", help="fit one focal length")
    cal.add_argument(
        "--min-corners", type=_positive_int, default=6, help="least board corners in a photo"
    )
    cal.set_defaults(func=_cmd_calibrate)

    reg = sub.add_parser(
        "register",
        help="a fixed camera's pose from its photo of floor markers, into an arena file",
        **defaults,
    )
    reg.add_argument("photo", type=pathlib.Path, help="the camera's photo of the floor markers")
    reg.add_argument(
        "--camera-info",
        type=pathlib.Path,
        required=True,
        help="its intrinsics (peoplebot calibrate)",
    )
    reg.add_argument(
        "--markers",
        type=pathlib.Path,
        required=True,
        help="where the markers lie, a landmark map file (like models/arena/floor_markers.toml)",
    )
    reg.add_argument(
        "--arena",
        type=pathlib.Path,
        required=True,
        help="the room's arena file (its camera replaced)",
    )
    reg.add_argument(
        "--out", type=pathlib.Path, required=True, help="the arena file written, with the camera"
    )
    reg.add_argument(
        "--min-markers", type=_positive_int, default=4, help="fewest markers to fit to (4)"
    )
    reg.set_defaults(func=_cmd_register)

    markers = sub.add_parser(
        "markers",
        help="the robots' marker plates and the calibration board as a PDF at true printed scale",
        **defaults,
    )
    markers.add_argument("--out", type=pathlib.Path, default=RENDERS / "plates.pdf", help="the PDF")
    markers.add_argument(
        "--paper",
        choices=("A4", "A3", "letter"),
        default="A4",
        help="the paper series (plates go on the smallest sheet of it that holds them)",
    )
    markers.add_argument(
        "--landmarks",
        type=pathlib.Path,
        default=None,
        help="also print the wall landmarks of this marker map (the simulated arena's: "
        "models/arena/landmarks.toml)",
    )
    markers.set_defaults(func=_cmd_markers)

    fig = sub.add_parser(
        "figures", help="the paper's Figs. 3, 5 and 6 from a saved network", **defaults
    )
    fig.add_argument(
        "--network",
        type=pathlib.Path,
        required=True,
        help="a saved paper's network (a run folder's network.npz)",
    )
    fig.add_argument(
        "--out", type=pathlib.Path, default=RENDERS / "figures", help="folder for the PNGs"
    )
    fig.set_defaults(func=_cmd_figures)
    return parser


def main(argv=None) -> int:
    """Runs a ``peoplebot`` command. Expected failures (bad settings, unreadable or corrupt files,
    unwritable folders, a run folder of other settings) are one line on stderr and exit status 2;
    ``--debug`` shows their traceback. Anything else is a bug and shows its traceback."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, OSError) as error:
        if args.debug:
            raise
        print(f"peoplebot {args.command}: error: {_one_line(error)}", file=sys.stderr)
        return 2


def _one_line(error: Exception) -> str:
    """Returns an expected failure as one line: a file error names the file and what went wrong."""
    if isinstance(error, OSError) and error.strerror:
        where = f"{error.filename}: " if error.filename else ""
        return f"{where}{error.strerror.lower()}"
    return " ".join(str(error).split())


if __name__ == "__main__":
    sys.exit(main())
