"""``peoplebot sweep``: a grid of runs over seeds and settings, as Ray tasks, with every headline a
distribution.

Each cell of the grid (one seed, one value of every ``--set`` key) is an ordinary run folder,
``DIR/cells/<name>/``, made by ``imitation.reproduce.run`` as ``peoplebot reproduce`` would. Ray
runs the cells: a local Ray on this machine by default, or an existing cluster by address. A
finished cell is skipped, an interrupted one resumes through its run folder, a cell whose worker
dies is retried by Ray, and every cell's results come back to the driver through Ray, so ``DIR``
holds them even when the workers' disks are not shared. Cells that watch the same teacher streams
share them through ``DIR/stream-cache/``. The summary: ``sweep.json``, ``sweep.md`` and a figure
per metric in ``DIR/figures/``. The Ray machinery is ``imitation.raytasks``, shared with ``peoplebot
transfer``.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
import pathlib
import socket
import sys

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

import numpy as np

from imitation import page, raytasks, report, reproduce, storage
from imitation.config import RunConfig
from imitation.results import PAPER_TABLE_I, package_versions
from imitation.runstate import differing_keys

#: The environment variable through which a test makes a cell's worker die once (its value: a
#: marker file; the first attempt that finds it missing creates it and exits).
DIE_ONCE_ENV = "PEOPLEBOT_SWEEP_DIE_ONCE"
#: The read-outs and students whose numbers the summary gathers.
RECOGNITION_READOUTS = ("paper", "motor_weighted", "hierarchical", "hierarchical_over_time")
STUDENTS = ("student", "student_hierarchical", "teacher")
ROWS = ("go", "pick", "pick_other_wall", "lift")
WORDS = ("go", "pick", "lift")


@dataclasses.dataclass(frozen=True)
class Cell:
    """One run of the grid: its folder name, seed, the ``--set`` values it takes (dotted key,
    value) and its whole configuration."""

    name: str
    seed: int
    settings: tuple
    config: RunConfig

    @property
    def group(self) -> tuple:
        """Returns the cell's settings without the seed: cells of one group differ by seed only."""
        return self.settings


def parse_seeds(text: str) -> tuple[int, ...]:
    """Returns the seeds of ``"0-4"`` (a range, both ends included) or ``"0,3,7"``."""
    try:
        if "-" in text and "," not in text:
            first, last = (int(v) for v in text.split("-", 1))
            if last < first:
                raise ValueError
            seeds = tuple(range(first, last + 1))
        else:
            seeds = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise ValueError(
            f"--seeds {text!r} must be a range like 0-4 or a list like 0,3,7"
        ) from None
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"--seeds {text!r} repeats a seed")
    return seeds


def parse_setting(text: str) -> tuple[str, tuple]:
    """Returns ``(key, values)`` of ``"network.pose_weight=0.01,0.03"``; each value is read as a
    TOML value (numbers, true/false, quoted strings; a bare word is a string)."""
    key, sep, values = text.partition("=")
    if not sep or not key or not values:
        raise ValueError(
            f"--set {text!r} must be KEY=V1,V2,... (e.g. network.pose_weight=0.01,0.03)"
        )
    if key == "seed":
        raise ValueError("--set seed=... is what --seeds is for")
    parsed = []
    for value in values.split(","):
        try:
            parsed.append(tomllib.loads(f"v = {value}")["v"])
        except tomllib.TOMLDecodeError:
            parsed.append(value)
    return key.strip(), tuple(parsed)


def grid(base: RunConfig, seeds, settings) -> list[Cell]:
    """Returns the cells: the product of the seeds and every setting's values, each a validated
    configuration (an unknown key or a bad value is a ValueError naming it)."""
    keys = [key for key, _ in settings]
    if len(set(keys)) != len(keys):
        raise ValueError(f"--set names a key twice: {keys}")
    cells = []
    for values in itertools.product(*(values for _, values in settings)):
        chosen = tuple(zip(keys, values, strict=True))
        for seed in seeds:
            config = base.replace({"seed": seed, **dict(chosen)})
            name = ",".join([f"seed{seed}", *(f"{k}={v}" for k, v in chosen)])
            cells.append(Cell(name.replace("/", "_"), seed, chosen, config))
    return cells


def run_cell(config: dict, folder: str, stream_cache: str) -> dict:
    """Runs (or resumes) one cell's run folder in this process; returns its results, its
    ``results.md`` and where it ran. The body of the Ray task."""
    marker = os.environ.get(DIE_ONCE_ENV)
    if marker and not os.path.exists(marker):
        pathlib.Path(marker).write_text(str(os.getpid()))
        os._exit(1)  # a worker that dies, for tests: Ray runs the cell again
    results = reproduce.run(RunConfig.from_dict(config), folder, stream_cache=stream_cache)
    return {
        "results": results.to_json(),
        "results_md": (pathlib.Path(folder) / "results.md").read_text(),
        "host": socket.gethostname(),
        "node": raytasks.node_id(),
    }


@dataclasses.dataclass
class CellOutcome:
    """What became of a cell: ``finished`` (with its results), ``skipped`` (finished earlier) or
    ``failed`` (with the error)."""

    cell: Cell
    status: str
    results: dict | None = None
    error: str | None = None
    node: str | None = None


def sweep(
    base: RunConfig,
    seeds,
    settings,
    out,
    *,
    address: str | None = None,
    workers: int | None = None,
    progress: bool = True,
) -> dict:
    """Runs the grid of ``base`` over ``seeds`` and ``settings`` in ``out`` (see the module notes);
    returns the summary (what ``sweep.json`` holds)."""
    out = pathlib.Path(out).resolve()
    cells = grid(base, seeds, settings)
    (out / "cells").mkdir(parents=True, exist_ok=True)
    outcomes = {}
    pending = []
    for cell in cells:
        earlier = _finished_results(out / "cells" / cell.name, cell.config)
        if earlier is not None:
            outcomes[cell.name] = CellOutcome(cell, "skipped", earlier)
        else:
            pending.append(cell)
    if pending:
        _run_on_ray(pending, out, outcomes, address, workers, progress)
    summary = summarise([outcomes[c.name] for c in cells], seeds, settings)
    storage.write_json(out / "sweep.json", summary)
    sweep_md = markdown(summary)
    storage.write_text(out / "sweep.md", sweep_md)
    figures = [str(p.relative_to(out)) for p in summary_figures(summary, out / "figures")]
    storage.write_text(
        out / "index.html", page.sweep_page(sweep_md, figures, [c.name for c in cells])
    )
    return summary


def _finished_results(folder: pathlib.Path, config: RunConfig) -> dict | None:
    """Returns a cell's results if its folder holds a finished run of ``config``."""
    try:
        results = json.loads((folder / "results.json").read_text())
    except (OSError, ValueError):
        return None
    theirs = {k: v for k, v in results.get("config", {}).items() if k != "workers"}
    mine = {k: v for k, v in config.to_dict().items() if k != "workers"}
    if (
        differing_keys(theirs, mine)
        or results.get("versions", {}).get("peoplebot-imitation") != _version()
    ):
        return None
    return results


def _version() -> str:
    return package_versions()["peoplebot-imitation"]


def _run_on_ray(cells, out, outcomes, address, workers, progress) -> None:
    env = {DIE_ONCE_ENV: os.environ[DIE_ONCE_ENV]} if DIE_ONCE_ENV in os.environ else {}
    cache = str(out / "stream-cache")
    # One process per cell: the cells themselves are the parallel work.
    jobs = {
        cell.name: (
            cell.config.replace({"workers": 1}).to_dict(),
            str(out / "cells" / cell.name),
            cache,
        )
        for cell in cells
    }
    by_name = {cell.name: cell for cell in cells}
    for outcome in raytasks.run_tasks(
        run_cell,
        jobs,
        address=address,
        workers=workers,
        env=env,
        progress=progress,
        description="sweep cells",
    ):
        cell = by_name[outcome.key]
        if outcome.error is not None:
            outcomes[cell.name] = CellOutcome(cell, "failed", error=outcome.error)
            continue
        returned = outcome.value
        folder = out / "cells" / cell.name
        folder.mkdir(parents=True, exist_ok=True)  # the driver's copy (disks not shared)
        storage.write_json(folder / "results.json", returned["results"])
        storage.write_text(folder / "results.md", returned["results_md"])
        outcomes[cell.name] = CellOutcome(
            cell, "finished", returned["results"], node=returned["node"]
        )


# ---------------------------------------------------------------------------------------- summary
def metrics(results: dict) -> dict[str, float]:
    """Returns a run's headline numbers by name: correct recognition per read-out and word
    (``recognition.<read-out>.<word>``) and success rates per student and row
    (``performance.<student>.<row>``)."""
    out = {}
    rec = results.get("recognition") or {}
    tables = {
        "paper": rec.get("confusion"),
        "motor_weighted": (rec.get("motor_weighted") or {}).get("confusion"),
        "hierarchical": (rec.get("hierarchical") or {}).get("confusion"),
        "hierarchical_over_time": (rec.get("hierarchical_over_time") or {}).get("confusion"),
    }
    for readout, table in tables.items():
        for word in WORDS:
            if table and table[word][word] is not None:
                out[f"recognition.{readout}.{word}"] = table[word][word]
    perf = results.get("performance") or {}
    sources = {
        "student": perf,
        "student_hierarchical": perf.get("hierarchical") or {},
        "teacher": perf.get("teacher_reference") or {},
    }
    for student, rows in sources.items():
        for row in ROWS:
            if isinstance(rows.get(row), dict) and "success_rate" in rows[row]:
                out[f"performance.{student}.{row}"] = rows[row]["success_rate"]
    return out


def statistics(values, bounds=(0.0, 1.0)) -> dict:
    """Returns n, mean, the 95% confidence interval of the mean (Student's t, clipped to
    ``bounds``, the range the metric can take; None for one value), min and max of a list of
    numbers."""
    values = np.asarray(values, dtype=float)
    n = len(values)
    mean = float(values.mean())
    interval = None
    if n > 1:
        half = t_quantile_975(n - 1) * float(values.std(ddof=1)) / math.sqrt(n)
        interval = [max(mean - half, bounds[0]), min(mean + half, bounds[1])]
    return {
        "n": n,
        "mean": mean,
        "ci95": interval,
        "min": float(values.min()),
        "max": float(values.max()),
    }


#: Student's t 0.975 quantiles for 1 to 30 degrees of freedom.
_T975 = (
    12.7062, 4.3027, 3.1824, 2.7764, 2.5706, 2.4469, 2.3646, 2.3060, 2.2622, 2.2281,
    2.2010, 2.1788, 2.1604, 2.1448, 2.1314, 2.1199, 2.1098, 2.1009, 2.0930, 2.0860,
    2.0796, 2.0739, 2.0687, 2.0639, 2.0595, 2.0555, 2.0518, 2.0484, 2.0452, 2.0423,
)  # fmt: skip


def t_quantile_975(df: int) -> float:
    """Returns Student's t distribution's 0.975 quantile for ``df`` degrees of freedom (a table to
    30, then the Cornish-Fisher expansion, within 1e-4)."""
    if df < 1:
        raise ValueError(f"degrees of freedom must be at least 1, got {df}")
    if df <= len(_T975):
        return _T975[df - 1]
    z = 1.959964
    return z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)


def summarise(outcomes: list[CellOutcome], seeds, settings) -> dict:
    """Returns ``sweep.json``: every cell's settings and results, and per group of cells that
    differ only by seed the statistics of every metric over the seeds."""
    cells = []
    groups: dict[tuple, list[CellOutcome]] = {}
    for outcome in outcomes:
        cell = outcome.cell
        cells.append(
            {
                "name": cell.name,
                "seed": cell.seed,
                "settings": dict(cell.settings),
                "status": outcome.status,
                "node": outcome.node,
                "error": outcome.error,
                "config": cell.config.to_dict(),
                "results": outcome.results,
            }
        )
        groups.setdefault(cell.group, []).append(outcome)
    summary_groups = []
    for group, members in groups.items():
        done = [m for m in members if m.results is not None]
        per_seed: dict[str, dict[int, float]] = {}
        for member in done:
            for name, value in metrics(member.results).items():
                per_seed.setdefault(name, {})[member.cell.seed] = value
        summary_groups.append(
            {
                "settings": dict(group),
                "seeds": [m.cell.seed for m in done],
                "failed_seeds": [m.cell.seed for m in members if m.results is None],
                "metrics": {
                    name: {
                        **statistics(list(values.values())),
                        "worst_seed": min(values, key=values.get),
                        "by_seed": {str(k): v for k, v in values.items()},
                    }
                    for name, values in sorted(per_seed.items())
                },
            }
        )
    return {
        "seeds": list(seeds),
        "settings": {key: list(values) for key, values in settings},
        "counts": {
            status: sum(o.status == status for o in outcomes)
            for status in ("finished", "skipped", "failed")
        },
        "paper": PAPER_TABLE_I.to_json(),
        "groups": summary_groups,
        "cells": cells,
    }


def _cellfmt(stat: dict | None) -> str:
    if stat is None:
        return "-"
    scale = 100.0
    text = f"{scale * stat['mean']:.1f}"
    if stat["ci95"] is not None:
        lo, hi = (scale * v for v in stat["ci95"])
        text += f" [{lo:.1f}, {hi:.1f}]"
    text += f" ({scale * stat['min']:.1f}-{scale * stat['max']:.1f})"
    return text


def markdown(summary: dict) -> str:
    """Returns ``sweep.md``: per group, recognition per word and read-out and performance per row
    and student, as mean [95% interval] (min-max) over the seeds, in percent."""
    names = {
        "paper": "paper's network",
        "motor_weighted": "paper's network, motor-weighted",
        "hierarchical": "hierarchical, one step",
        "hierarchical_over_time": "hierarchical, over time",
        "student": "student (paper's network)",
        "student_hierarchical": "student (hierarchical)",
        "teacher": "teacher (reference)",
    }
    counts = summary["counts"]
    lines = [
        "# Sweep",
        "",
        f"Seeds {', '.join(map(str, summary['seeds']))}; cells finished {counts['finished']}, "
        f"kept from earlier {counts['skipped']}, failed {counts['failed']}. Every number: mean "
        "[95% confidence interval of the mean] (worst-best seed), percent.",
        "",
    ]
    paper = summary["paper"]["confusion"]
    for group in summary["groups"]:
        title = ", ".join(f"{k} = {v}" for k, v in group["settings"].items()) or "defaults"
        m = group["metrics"]
        lines += [
            f"## {title} (seeds {', '.join(map(str, group['seeds']))})",
            "",
        ]
        if group["failed_seeds"]:
            lines += [f"Failed seeds: {', '.join(map(str, group['failed_seeds']))}.", ""]
        lines += [
            "Correct recognition:",
            "",
            "| read-out | 'go' | 'pick' | 'lift' |",
            "|---|---|---|---|",
            "| paper (Table I) | " + " | ".join(f"{100 * paper[w][w]:.1f}" for w in WORDS) + " |",
        ]
        for readout in RECOGNITION_READOUTS:
            row = [m.get(f"recognition.{readout}.{w}") for w in WORDS]
            if any(row):
                lines.append(f"| {names[readout]} | " + " | ".join(map(_cellfmt, row)) + " |")
        lines += [
            "",
            "Performing success:",
            "",
            "| student | 'go' | 'pick' | 'pick', other wall | 'lift' |",
            "|---|---|---|---|---|",
        ]
        for student in STUDENTS:
            row = [m.get(f"performance.{student}.{r}") for r in ROWS]
            if any(row):
                lines.append(f"| {names[student]} | " + " | ".join(map(_cellfmt, row)) + " |")
        lines.append("")
    failed = [c for c in summary["cells"] if c["status"] == "failed"]
    if failed:
        lines += ["## Failed cells", ""]
        lines += [f"- {c['name']}: {c['error']}" for c in failed]
        lines.append("")
    return "\n".join(lines)


def summary_figures(summary: dict, folder: pathlib.Path) -> list[pathlib.Path]:
    """Writes one figure per metric into ``folder``: for each group, each seed a dot, the mean and
    its 95% interval; returns the paths."""
    plt = report.plt
    folder.mkdir(parents=True, exist_ok=True)
    names = sorted({n for g in summary["groups"] for n in g["metrics"]})
    paths = []
    for name in names:
        fig, ax = plt.subplots(figsize=(max(3.2, 1.2 * len(summary["groups"]) + 1.5), 3.2))
        labels = []
        for i, group in enumerate(summary["groups"]):
            stat = group["metrics"].get(name)
            labels.append(
                "\n".join(f"{k.split('.')[-1]}={v}" for k, v in group["settings"].items())
                or "defaults"
            )
            if stat is None:
                continue
            values = [100 * v for v in stat["by_seed"].values()]
            ax.plot([i] * len(values), values, "o", color="tab:blue", alpha=0.6, ms=5)
            mean = 100 * stat["mean"]
            if stat["ci95"] is not None:
                lo, hi = (100 * v for v in stat["ci95"])
                ax.errorbar(
                    i + 0.15,
                    mean,
                    yerr=[[mean - lo], [hi - mean]],
                    fmt="s",
                    color="tab:red",
                    capsize=4,
                    ms=5,
                )
            else:
                ax.plot(i + 0.15, mean, "s", color="tab:red", ms=5)
        ax.set_xticks(range(len(labels)), labels, fontsize=8)
        ax.set_xlim(-0.6, len(labels) - 0.4)
        ax.set_ylim(-3, 103)
        ax.set_ylabel("%")
        ax.set_title(f"{name} (dots: seeds; square: mean, 95% CI)", fontsize=9)
        fig.tight_layout()
        path = folder / f"{name}.png"
        tmp = storage.temporary_name(path)
        fig.savefig(tmp, dpi=100)
        plt.close(fig)
        paths.append(storage.commit(tmp, path))
    return paths
