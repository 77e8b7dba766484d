"""``peoplebot transfer``: a trained run's networks tested under each perturbation family, level
by level, with the operating envelope.

Each (family, level) is a cell, ``OUT/cells/<name>/`` (level 0 of every family is one cell,
``baseline``): a run folder of its own configuration (the source run's, with the vision mode, the
trial settings and the perturbations of the level) whose two stages, ``recognition`` (watching
the teacher, as the camera modes do, or the recorded test stream in the 'truth' mode) and
``performance`` (every student and the teacher's controller from the run's random starts), are
checkpointed in its ``state.json``: an interrupted transfer resumes, and a finished cell is kept.
The networks and the test stream are read from the source run, never copied. The cells run as Ray
tasks (``imitation.raytasks``, the scheduler of ``peoplebot sweep``): a local Ray by default, or a
cluster whose nodes see the source run and the transfer's folder at the same paths. The report:
``transfer.json``, ``transfer.md`` and ``figures/<family>.png``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from associator import encoding, persistence  # noqa: E402
from imitation import perturbations, raytasks, recognition, storage, trials  # noqa: E402
from imitation.config import RunConfig  # noqa: E402
from imitation.results import WORDS, package_versions  # noqa: E402
from imitation.runstate import RunState  # noqa: E402
from imitation.streams import TeacherStream  # noqa: E402
from perception.wallframe import ArenaGeometry  # noqa: E402

#: A word is inside the operating envelope while its success rate is at least this.
ENVELOPE_RATE = 0.8
#: The recognition read-outs measured in every cell.
READOUTS = ("paper", "hierarchical", "hierarchical_over_time")
#: The policies whose success the envelope gives.
POLICIES = ("student", "student_hierarchical", "teacher")
#: What ``peoplebot transfer`` writes into its folder.
SUMMARY_VERSION = 1


@dataclasses.dataclass(frozen=True)
class Scale:
    """How much a transfer measures where its options do not say: the families (None: every
    family that acts in the vision mode, ``perturbations.acts_in``), the levels of each (0 and
    ``perturbations.ANCHOR_LEVELS``: the anchor's and one past it), the trials per row and policy
    (of the source's trial length) and the watched steps for recognition."""

    families: tuple | None
    trials: int
    recognition_steps: int


#: ``peoplebot transfer`` and ``peoplebot transfer --quick``; their timings: docs/transfer.md.
SCALES = {
    "default": Scale(families=None, trials=10, recognition_steps=3000),
    "quick": Scale(
        families=("pose_noise", "latency", "command_latency", "acceleration"),
        trials=3,
        recognition_steps=1500,
    ),
}


@dataclasses.dataclass(frozen=True)
class TransferCell:
    """One configuration to test: its folder name, the perturbation settings it sets (dotted
    keys under ``perturbations``) and its whole configuration."""

    name: str
    settings: tuple
    config: RunConfig


@dataclasses.dataclass(frozen=True)
class CellResult:
    """A cell's numbers: correct recognition per read-out and word (None: no steps of it seen),
    the fraction of steps the teacher was seen, success rates per policy and row with their
    trial counts, and the CPU seconds each stage took (in the process that ran it, with one
    trial process: the cell's whole cost; empty for cells made before they were kept)."""

    recognition: dict
    seen_fraction: float
    performance: dict
    trials: dict
    cpu_seconds: dict = dataclasses.field(default_factory=dict)

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: dict) -> CellResult:
        return cls(**data)


class CellsFailed(RuntimeError):
    """Some cells of a transfer failed (the others are kept; a rerun resumes)."""


def parse_families(text: str | None, mode: str | None = None) -> tuple[str, ...]:
    """Returns the families of ``"latency,dropout"`` (None: every family, or with a vision
    ``mode`` every family that acts in it); ValueError listing them."""
    if text is None:
        return tuple(
            f for f in perturbations.FAMILIES if mode is None or perturbations.acts_in(f, mode)
        )
    names = tuple(name.strip() for name in text.split(",") if name.strip())
    for name in names:
        if name not in perturbations.FAMILIES:
            raise ValueError(
                f"--families: unknown family {name!r}; allowed: {', '.join(perturbations.FAMILIES)}"
            )
    if not names:
        raise ValueError("--families needs at least one family")
    return names


def parse_levels(text: str | None) -> tuple[int, ...] | str | None:
    """Returns the level indices of ``"0,2,3"``, ``"all"`` for every level of each family, or
    None (the default: 0 and each family's ``perturbations.ANCHOR_LEVELS``)."""
    if text is None or text == "all":
        return text
    try:
        levels = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--levels {text!r} must be level numbers like 0,1,3, or all") from None
    if any(level < 0 for level in levels) or len(set(levels)) != len(levels):
        raise ValueError(f"--levels {text!r} must be distinct level numbers >= 0")
    return levels


def level_label(level: dict) -> str:
    """Returns a level's short name, e.g. ``latency_ms=50`` (``0`` for the level that sets
    nothing)."""
    if not any(level.values()):
        return "0"
    return ", ".join(f"{key.rsplit('.', 1)[-1]}={value}" for key, value in level.items())


def source_run(source) -> RunConfig:
    """Returns the configuration of the finished run in ``source`` whose networks and test stream
    a transfer reads; ValueError in one line unless it was made by this version and its streams
    and learning stages are finished with their files intact."""
    source = pathlib.Path(source)
    try:
        state = json.loads((source / "state.json").read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"--reuse-from {source} is not a run folder ({error})") from None
    if not isinstance(state, dict) or not isinstance(state.get("config"), dict):
        raise ValueError(f"--reuse-from {source} is not a run folder (its state.json is not one)")
    version = package_versions()["peoplebot-imitation"]
    if state.get("version") != version:
        raise ValueError(
            f"--reuse-from {source} was made by peoplebot-imitation {state.get('version')}, this "
            f"is {version}; it cannot be reused"
        )
    for stage in ("streams", "learning"):
        if stage not in state.get("stages", {}):
            raise ValueError(f"--reuse-from {source} has not finished its {stage} stage")
        for name, digest in state.get("artifacts", {}).get(stage, {}).items():
            path = source / name
            if not path.is_file() or storage.file_digest(path) != digest:
                raise ValueError(
                    f"--reuse-from {source}: {name} is missing or changed since its run; it "
                    "cannot be reused"
                )
    return RunConfig.from_dict(state["config"])


def plan(base: RunConfig, families, levels=None) -> tuple[list, list[TransferCell]]:
    """Returns ``(rows, cells)``: per family and chosen level ``(family, index, level)`` and the
    distinct cells to run (a level equal to the base's perturbations is the ``baseline`` cell).
    ``levels``: indices, ``"all"``, or None (0 and the family's ``ANCHOR_LEVELS``). ``base``'s
    own perturbations (a preset) stay under every level."""
    rows, cells = [], {}
    for family in families:
        grid = perturbations.FAMILIES[family]
        if levels is None:
            chosen = (0, *perturbations.ANCHOR_LEVELS[family])
        elif levels == "all":
            chosen = range(len(grid))
        else:
            chosen = [i for i in levels if i < len(grid)]
        for index in chosen:
            level = grid[index]
            config = base.replace({f"perturbations.{k}": v for k, v in level.items()})
            name = "baseline" if config == base else f"{family}-{index}"
            rows.append((family, index, level))
            cells.setdefault(name, TransferCell(name, tuple(level.items()), config))
    return rows, list(cells.values())


def cell_name(base: RunConfig, family: str, index: int) -> str:
    """Returns the name of the cell that holds ``family``'s level ``index``."""
    level = perturbations.FAMILIES[family][index]
    config = base.replace({f"perturbations.{k}": v for k, v in level.items()})
    return "baseline" if config == base else f"{family}-{index}"


def combined_cell(base: RunConfig, preset: str | None) -> TransferCell | None:
    """Returns the cell of every family at once at the named preset's levels (the report's
    combined row), or None without a preset or where the base already has those perturbations."""
    if preset is None:
        return None
    config = dataclasses.replace(base, perturbations=perturbations.preset(preset))
    return None if config == base else TransferCell(f"combined-{preset}", (), config)


def finished_cell(cell: TransferCell, folder: pathlib.Path, fresh: bool = False):
    """Returns the numbers of ``cell`` if ``folder`` holds it finished, else None after making
    the folder ready to run it (``fresh``: what an earlier run wrote there is removed; a stage
    whose files were lost is forgotten). ValueError in one line when the folder holds a cell of
    other settings."""
    state = RunState(folder, cell.config.to_dict(), fresh=fresh, defaults=RunConfig().to_dict())
    try:
        if state.done("performance") and not state.intact("performance"):
            state.forget(["performance"])
        if state.done("recognition") and state.done("performance"):
            return _cell_result(state)
        return None
    finally:
        state.close()


def run_cell(config: dict, source: str, folder: str, students_only: bool = False) -> dict:
    """Runs (or resumes) one cell of the configuration ``config`` (plain values) in ``folder``
    with the networks and test stream of ``source`` (``students_only``: no teacher reference
    trials, for a compared run); returns its numbers (``CellResult`` as JSON). The body of the
    Ray task."""
    config, source, folder = RunConfig.from_dict(config), pathlib.Path(source), pathlib.Path(folder)
    policies = trials.policies_of(config)
    if students_only:
        policies = tuple(p for p in policies if p != "teacher")
    state = RunState(folder, config.to_dict(), defaults=RunConfig().to_dict())
    try:
        if not state.done("recognition"):
            wall, cpu = time.perf_counter(), time.process_time()
            result = _recognition(config, source)
            result["cpu_seconds"] = time.process_time() - cpu
            state.finish("recognition", result, seconds=time.perf_counter() - wall)
        if not state.done("performance"):
            wall, cpu = time.perf_counter(), time.process_time()
            rates = trials.success_rates(config, folder, networks_from=source, policies=policies)
            result = {**_performance_json(rates), "cpu_seconds": time.process_time() - cpu}
            state.finish(
                "performance",
                result,
                [folder / "performance_trials.json"],
                seconds=time.perf_counter() - wall,
            )
        return _cell_result(state).to_json()
    finally:
        state.close()


def compared(result: CellResult, other: CellResult, label: str) -> CellResult:
    """Returns ``result`` with the read-outs and students of ``other`` (a compared run's cell)
    added under ``"<name> (<label>)"``."""

    def tagged(mine: dict, theirs: dict) -> dict:
        return {**mine, **{f"{name} ({label})": value for name, value in theirs.items()}}

    return CellResult(
        tagged(result.recognition, other.recognition),
        result.seen_fraction,
        tagged(result.performance, other.performance),
        tagged(result.trials, other.trials),
        {
            stage: seconds + other.cpu_seconds.get(stage, 0.0)
            for stage, seconds in result.cpu_seconds.items()
        },
    )


def _cell_result(state: RunState) -> CellResult:
    rec, perf = state.result("recognition"), state.result("performance")
    cpu = {
        stage: result["cpu_seconds"]
        for stage, result in (("recognition", rec), ("performance", perf))
        if "cpu_seconds" in result
    }
    return CellResult(rec["recognition"], rec["seen_fraction"], perf["rates"], perf["trials"], cpu)


def _recognition(config: RunConfig, source: pathlib.Path) -> dict:
    """Returns correct recognition per read-out and word as the cell's student sees the teacher:
    the test stream's first ``vision.test_steps`` steps in the 'truth' mode (under its
    perception faults), the camera otherwise."""
    dt = config.task.control_timestep
    seed = config.seed * 2 + 3
    if config.vision.mode == "truth":
        stream = TeacherStream.load(source / "streams" / "test.npz")
        observed = recognition.perturbed_truth(
            stream, config.vision.test_steps, config.perturbations, dt, seed
        )
    else:
        observed = recognition.watch_with_vision(
            seed,
            config.vision.test_steps,
            config.vision.mode,
            config.vision.width,
            config.vision.height,
            progress=False,
            task=config.world_config(),
            perturbations=config.perturbations,
            self_localisation=config.vision.self_localisation,
            overhead_registration=config.vision.overhead_registration,
        )
    encoder = encoding.VisionEncoder(half_side_m=ArenaGeometry().half_side_m)
    models = {"paper": persistence.load(source / "network.npz")}
    if config.hierarchical.enabled:
        models["hierarchical"] = models["hierarchical_over_time"] = persistence.load(
            source / "hierarchical.npz"
        )
    out = {}
    for readout, model in models.items():
        table = recognition.recognise_observed(
            model,
            observed,
            encoder,
            config.learning.motor_source,
            dt,
            over_time=readout == "hierarchical_over_time",
        ).vision
        out[readout] = {word: table.correct(word) for word in WORDS}
    return {"recognition": out, "seen_fraction": float(observed.seen.mean())}


def _performance_json(rates: dict) -> dict:
    """Returns success rates and trial counts per policy and row, as JSON values."""
    out = {"rates": {}, "trials": {}}
    for row, policies in rates.items():
        for policy, rate in policies.items():
            if rate is not None:
                out["rates"].setdefault(policy, {})[row] = rate.success_rate
                out["trials"].setdefault(policy, {})[row] = rate.trials
    return out


def envelope(levels: list, results: list[CellResult], policies=POLICIES) -> dict:
    """Returns, per policy and word, the largest level (its label) up to which every level
    succeeds at least ``ENVELOPE_RATE`` of the time, or None when level 0 already fails;
    ``levels`` and ``results`` in the family's order."""
    out = {}
    for policy in policies:
        for word in WORDS:
            largest = None
            for level, result in zip(levels, results, strict=True):
                rate = result.performance.get(policy, {}).get(word)
                if rate is None or rate < ENVELOPE_RATE:
                    break
                largest = level_label(level)
            if any(word in r.performance.get(policy, {}) for r in results):
                out.setdefault(policy, {})[word] = largest
    return out


def _compare_label(source, compared, folder_name: str) -> str:
    """Returns the compared students' default tag from the two runs' randomisation settings."""
    if compared.active and not source.active:
        return "randomised"
    if source.active and not compared.active:
        return "unrandomised"
    return folder_name


def transfer(
    source,
    out,
    *,
    families=None,
    levels=None,
    vision: str | None = None,
    base_perturbations: perturbations.PerturbationConfig | None = None,
    changes: dict | None = None,
    fresh: bool = False,
    address: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    compare=None,
    compare_label: str | None = None,
    combined: str | None = "realistic",
) -> dict:
    """Tests the networks of the finished run in ``source`` under each family's levels (see the
    module notes) in ``out``; returns the summary (what ``transfer.json`` holds).

    ``families``: default every family that acts in the vision mode; ``levels``: see ``plan``;
    ``vision``: the vision mode (default the source's); ``base_perturbations``: perturbations
    under every level (a preset; default none); ``changes``: other dotted config keys (trials,
    trial seconds, vision test steps; ``workers``: trial processes per cell, default 1);
    ``fresh``: every cell starts over (a cell made with other settings is refused without it);
    ``address``: a Ray cluster (else ``RAY_ADDRESS``, else a local Ray); ``workers``: cells at
    once; ``compare``: another finished run whose students are tested in the same cells (in
    ``OUT/compare/cells/``, without the teacher) and reported beside these as
    ``"<policy> (<compare_label>)"`` (default label: 'randomised' or 'unrandomised' for a run
    trained with domain randomisation where the source was not, or the other way round, else its
    folder's name); ``combined``: a preset (``perturbations.PRESETS``) whose levels, all at once
    in place of the base's perturbations, are one more cell, the report's combined row (None:
    none; none either where the base's perturbations are already that preset's)."""
    source, out = pathlib.Path(source).resolve(), pathlib.Path(out).resolve()
    settings = {
        "videos.enabled": False,
        "workers": 1,
        **({"vision.mode": vision} if vision else {}),
        **(changes or {}),
    }
    base = source_run(source).replace(settings)
    if base_perturbations is not None:
        base = dataclasses.replace(base, perturbations=base_perturbations)
    families = parse_families(None, base.vision.mode) if families is None else tuple(families)
    rows, cells = plan(base, families, levels)
    together = combined_cell(base, combined)
    cells = [*cells, together] if together is not None else cells
    # Every cell to run: (its key, the run whose networks it tests, its folder, the cell).
    todo = [(cell.name, source, out / "cells" / cell.name, cell) for cell in cells]
    other = None
    if compare is not None:
        compare = pathlib.Path(compare).resolve()
        other = source_run(compare).replace({**settings, "vision.mode": base.vision.mode})
        other = dataclasses.replace(other, perturbations=base.perturbations)
        if compare_label is None:
            compare_label = _compare_label(base.randomisation, other.randomisation, compare.name)
        _, other_cells = plan(other, families, levels)
        if together is not None:
            other_cells.append(combined_cell(other, combined))
        todo += [
            (f"compare/{c.name}", compare, out / "compare" / "cells" / c.name, c)
            for c in other_cells
        ]
    results = {}
    for key, _, folder, cell in todo:
        earlier = finished_cell(cell, folder, fresh)
        if earlier is not None:
            results[key] = earlier
    jobs = {
        key: (cell.config.to_dict(), str(run), str(folder), key.startswith("compare/"))
        for key, run, folder, cell in todo
        if key not in results
    }
    if progress:
        print(f"[transfer] {len(todo)} cells: {len(results)} finished earlier, {len(jobs)} to run")
    failed = []
    if jobs:
        for outcome in raytasks.run_tasks(
            run_cell,
            jobs,
            address=address,
            workers=workers,
            cpus_per_task=base.workers,
            progress=progress,
            description="transfer cells",
        ):
            if outcome.error is not None:
                failed.append(f"{outcome.key}: {outcome.error}")
            else:
                results[outcome.key] = CellResult.from_json(outcome.value)
    if failed:
        raise CellsFailed(
            f"{len(failed)} of {len(todo)} transfer cells failed (rerun to resume the others): "
            + "; ".join(failed)
        )
    policies = POLICIES
    if other is not None:
        students = [p for p in POLICIES if p != "teacher"]
        policies = (*POLICIES, *(f"{p} ({compare_label})" for p in students))
        results = {
            cell.name: compared(results[cell.name], results[f"compare/{cell.name}"], compare_label)
            for cell in cells
        }
    summary = _summary(source, base, families, rows, results, policies)
    if together is not None:
        summary["combined"] = {
            "preset": combined,
            "cell": together.name,
            **results[together.name].to_json(),
        }
    if other is not None:
        summary["compare"] = {
            "source": str(compare),
            "label": compare_label,
            "randomisation": other.to_dict().get("randomisation"),
        }
    storage.write_json(out / "transfer.json", summary)
    storage.write_text(out / "transfer.md", markdown(summary))
    figures(summary, out / "figures")
    return summary


def _summary(source, base: RunConfig, families, rows, results: dict, policies=POLICIES) -> dict:
    per_family = {}
    for family in families:
        mine = [(index, level) for f, index, level in rows if f == family]
        cells = [results[cell_name(base, family, index)] for index, _ in mine]
        per_family[family] = {
            "levels": [
                {
                    "index": index,
                    "label": level_label(level),
                    "settings": level,
                    "cell": cell_name(base, family, index),
                    **cell.to_json(),
                }
                for (index, level), cell in zip(mine, cells, strict=True)
            ],
            "envelope": envelope([level for _, level in mine], cells, policies),
        }
    return {
        "version": SUMMARY_VERSION,
        "source": str(source),
        "vision": base.vision.mode,
        "randomisation": base.to_dict().get("randomisation"),
        "policies": list(policies),
        "envelope_rate": ENVELOPE_RATE,
        "base_perturbations": base.to_dict()["perturbations"],
        "trials_per_row": base.performance.trials,
        "cells": len(results),
        "cpu_seconds": sum(sum(r.cpu_seconds.values()) for r in results.values()),
        "recognition_steps": _recognition_steps(base, source),
        "families": per_family,
        "versions": package_versions(),
    }


def _recognition_steps(config: RunConfig, source: pathlib.Path) -> int:
    """Returns how many steps each cell's recognition watched: ``vision.test_steps`` through the
    camera, or in the 'truth' mode as many of them as the source's test stream has."""
    if config.vision.mode != "truth":
        return config.vision.test_steps
    return min(config.vision.test_steps, len(TeacherStream.load(source / "streams" / "test.npz")))


def _pct(value) -> str:
    return "-" if value is None else f"{100 * value:.0f}%"


def _policies(summary: dict) -> list[str]:
    return summary.get("policies", list(POLICIES))


def _over_time(recognition: dict, label: str | None = None) -> dict:
    """Returns the numbers of the read-out a table shows (``over_time_readout``)."""
    return recognition.get(over_time_readout(recognition, label), {})


def markdown(summary: dict) -> str:
    """Returns ``transfer.md``: the operating envelope, then per family its levels' numbers."""
    policies = _policies(summary)
    label = (summary.get("compare") or {}).get("label")
    lines = [
        f"# Transfer: {summary['source']} ({summary['vision']} vision)",
        "",
        f"{summary['trials_per_row']} trials per row and policy; recognition on "
        f"{summary['recognition_steps']} watched steps (the hierarchical associator over time, "
        "or the paper's network without it); 'seen': steps the teacher's pose was known. "
        "Perturbations: docs/transfer.md.",
    ]
    if label:
        lines += [
            "",
            f"Compared: the students of {summary['compare']['source']} as '<policy> ({label})' "
            f"(its randomisation: {summary['compare']['randomisation'] or 'none'}).",
        ]
    lines += [
        "",
        f"## Operating envelope (largest level with success >= {100 * ENVELOPE_RATE:.0f}%)",
        "",
        "| family | " + " | ".join(f"{p} {w}" for p in policies for w in WORDS) + " |",
        "|---|" + "---|" * (len(policies) * len(WORDS)),
    ]
    for family, data in summary["families"].items():
        cells = [
            str(data["envelope"].get(p, {}).get(w, "-") or "none") for p in policies for w in WORDS
        ]
        lines.append(f"| {family} | " + " | ".join(cells) + " |")
    recognitions = [None, label] if label else [None]
    if "combined" in summary:
        lines += combined_table(summary["combined"], policies, recognitions)
    for family, data in summary["families"].items():
        lines += [
            "",
            f"## {family}",
            "",
            "| level | seen | "
            + " | ".join(
                f"recognition{f' ({tag})' if tag else ''} go / pick / lift" for tag in recognitions
            )
            + " | "
            + " | ".join(f"{p} go / pick / lift" for p in policies)
            + " |",
            "|---|---|" + "---|" * (len(recognitions) + len(policies)),
        ]
        for level in data["levels"]:
            rec = [
                " / ".join(_pct(_over_time(level["recognition"], tag).get(w)) for w in WORDS)
                for tag in recognitions
            ]
            perf = [
                " / ".join(_pct(level["performance"].get(p, {}).get(w)) for w in WORDS)
                for p in policies
            ]
            lines.append(
                f"| {level['label']} | {_pct(level['seen_fraction'])} | "
                + " | ".join(rec + perf)
                + " |"
            )
    return "\n".join(lines) + "\n"


def combined_table(combined: dict, policies, recognitions=(None,), show=None) -> list[str]:
    """Returns the markdown lines of the combined row: every family at once at the preset's
    levels. ``show(field, name, word)`` formats one rate (default: the percentage of
    ``combined[field][name][word]``)."""
    if show is None:

        def show(field: str, name: str, word: str) -> str:
            return _pct(combined[field].get(name, {}).get(word))

    heads = [f"recognition{f' ({t})' if t else ''} go / pick / lift" for t in recognitions]
    readouts = [over_time_readout(combined["recognition"], t) for t in recognitions]
    rec = [" / ".join(show("recognition", r, w) for w in WORDS) for r in readouts]
    perf = [" / ".join(show("performance", p, w) for w in WORDS) for p in policies]
    return [
        "",
        f"## Every family at once: the `{combined['preset']}` preset's levels",
        "",
        "| seen | " + " | ".join(heads + [f"{p} go / pick / lift" for p in policies]) + " |",
        "|---|" + "---|" * (len(heads) + len(policies)),
        f"| {_pct(combined['seen_fraction'])} | " + " | ".join(rec + perf) + " |",
    ]


def over_time_readout(recognition: dict, label: str | None = None) -> str:
    """Returns the name of the read-out a table shows: the hierarchical associator over time, or
    the paper's network without it (of the compared run: ``label``)."""
    tag = f" ({label})" if label else ""
    name = f"hierarchical_over_time{tag}"
    return name if recognition.get(name) else f"paper{tag}"


def wilson_interval(rate: float | None, trials: int | None) -> tuple[float, float]:
    """Returns the 95% Wilson score interval of a success ``rate`` over ``trials`` (NaN, NaN
    without trials)."""
    if rate is None or not trials:
        return float("nan"), float("nan")
    z = 1.959964
    centre = (rate + z * z / (2 * trials)) / (1 + z * z / trials)
    half = (
        z / (1 + z * z / trials) * math.sqrt(rate * (1 - rate) / trials + z * z / (4 * trials**2))
    )
    # It holds the rate; rounding aside (at a rate of 0 or 1).
    return min(max(centre - half, 0.0), rate), max(min(centre + half, 1.0), rate)


def figures(summary: dict, folder: pathlib.Path) -> list[pathlib.Path]:
    """Draws ``<family>.png`` per family: success per policy and word with its 95% Wilson
    interval (left) and correct recognition per read-out and word (right) against the level (a
    compared run's in their own colours; a summary over several runs, ``transfer_runs``: their
    mean, the interval of their pooled trials, and the worst run's as crosses); returns the
    paths."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    styles = {"go": "-", "pick": "--", "lift": ":"}
    colours = {"student": "C0", "student_hierarchical": "C2", "teacher": "C7"}
    readout_colours = {"paper": "C0", "hierarchical": "C1", "hierarchical_over_time": "C2"}
    label = (summary.get("compare") or {}).get("label")
    if label:
        colours |= {f"student ({label})": "C3", f"student_hierarchical ({label})": "C4"}
        readout_colours |= {
            f"paper ({label})": "C3",
            f"hierarchical ({label})": "C5",
            f"hierarchical_over_time ({label})": "C4",
        }
    for family, data in summary["families"].items():
        levels = data["levels"]
        x = list(range(len(levels)))
        fig, (left, right) = plt.subplots(1, 2, figsize=(14, 4.5), sharey=True)
        for policy in _policies(summary):
            for word in WORDS:
                y = [lv["performance"].get(policy, {}).get(word) for lv in levels]
                if any(v is not None for v in y):
                    n = [lv["trials"].get(policy, {}).get(word) for lv in levels]
                    bounds = [wilson_interval(v, k) for v, k in zip(y, n, strict=True)]
                    rate = [float("nan") if v is None else v for v in y]
                    left.errorbar(
                        x,
                        rate,
                        yerr=[
                            [max(r - lo, 0.0) for r, (lo, _) in zip(rate, bounds, strict=True)],
                            [max(hi - r, 0.0) for r, (_, hi) in zip(rate, bounds, strict=True)],
                        ],
                        fmt=styles[word],
                        marker="o",
                        capsize=2,
                        elinewidth=0.6,
                        color=colours.get(policy, "C9"),
                        label=f"{policy} {word}",
                    )
                    worst = [
                        lv.get("worst_performance", {}).get(policy, {}).get(word) for lv in levels
                    ]
                    if any(v is not None for v in worst):  # over several runs: the worst one's
                        left.plot(
                            x,
                            [float("nan") if v is None else v for v in worst],
                            "x",
                            color=colours.get(policy, "C9"),
                        )
        for readout, colour in readout_colours.items():
            for word in WORDS:
                y = [lv["recognition"].get(readout, {}).get(word) for lv in levels]
                if any(v is not None for v in y):
                    right.plot(
                        x,
                        [float("nan") if v is None else v for v in y],
                        styles[word],
                        marker="o",
                        color=colour,
                        label=f"{readout} {word}",
                    )
        keys = [key.rsplit(".", 1)[-1] for key in levels[-1]["settings"]]
        ticks = [
            " / ".join(str(v) for v in lv["settings"].values()) if lv["label"] != "0" else "0"
            for lv in levels
        ]
        for axis, title in ((left, "performing: success rate"), (right, "recognition: correct")):
            axis.axhline(ENVELOPE_RATE, color="k", lw=0.5, alpha=0.5)
            axis.set_xticks(x, ticks, fontsize=8)
            axis.set_xlabel(" / ".join(keys), fontsize=8)
            axis.set_ylim(-0.05, 1.05)
            axis.set_title(title)
            axis.legend(fontsize=6, ncol=1, loc="center left", bbox_to_anchor=(1.0, 0.5))
        runs = f", {len(summary['runs'])} runs' trials pooled" if "runs" in summary else ""
        fig.suptitle(f"{family} ({summary['vision']} vision{runs})")
        fig.tight_layout()
        path = folder / f"{family}.png"
        tmp = storage.temporary_name(path)
        fig.savefig(tmp, format="png", dpi=90)
        plt.close(fig)
        paths.append(storage.commit(tmp, path))
    return paths
