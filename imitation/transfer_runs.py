"""``peoplebot transfer`` over several trained runs (the seeds of a sweep): the envelope as a
distribution over seeds.

Each run's grid is an ordinary one-run transfer in ``OUT/<run folder>/`` (``transfer.transfer``:
checkpointed cells, resumed on a rerun). The runs must differ by their seed only. The report in
``OUT``: ``transfer.json``, ``transfer.md`` and ``figures/<family>.png`` with, per family, level,
policy and word, the mean success over the runs and the worst run's, and two operating envelopes:
of the mean, and of the worst run (the largest level up to which every run succeeds at least
``transfer.ENVELOPE_RATE`` of the time).
"""

from __future__ import annotations

import pathlib

import numpy as np

from imitation import storage, transfer
from imitation.results import WORDS, package_versions
from imitation.runstate import differing_keys

SUMMARY_VERSION = 1
#: Keys of a run's configuration that may differ between the runs of one report.
FREE_KEYS = ("seed",)


def expand_sources(paths) -> list[pathlib.Path]:
    """Returns the run folders named by ``paths``: a run folder as it is, a sweep folder (one
    with ``sweep.json`` and ``cells/``) as its cells in name order; ValueError in one line when
    two runs share a folder name (each run's grid is ``OUT/<run folder name>/``)."""
    runs = []
    for path in map(pathlib.Path, paths):
        if (path / "sweep.json").is_file() and (path / "cells").is_dir():
            runs += sorted(p for p in (path / "cells").iterdir() if (p / "state.json").is_file())
        else:
            runs.append(path)
    names = [run.name for run in runs]
    for name in names:
        if names.count(name) > 1:
            raise ValueError(
                f"--reuse-from names two runs in folders called {name!r}; each run's grid is "
                "OUT/<run folder name>/, so the names must differ"
            )
    return [run.resolve() for run in runs]


def check_same_settings(sources) -> None:
    """ValueError in one line unless the runs' configurations differ only by ``FREE_KEYS``."""
    first = transfer.source_run(sources[0]).to_dict()
    for source in sources[1:]:
        keys = [
            k
            for k in differing_keys(first, transfer.source_run(source).to_dict())
            if k not in FREE_KEYS
        ]
        if keys:
            raise ValueError(
                f"--reuse-from {source} differs from {sources[0]} in {', '.join(keys)}; the runs "
                f"of one transfer report may differ by {', '.join(FREE_KEYS)} only"
            )


def transfer_runs(sources, out, *, progress: bool = True, **options) -> dict:
    """Runs (or resumes) the transfer of every run in ``sources`` (at least two) in
    ``OUT/<run folder>/`` with the same ``options`` (those of ``transfer.transfer``, without
    ``compare``), then writes the combined report in ``out``; returns its summary. A run whose
    cells fail does not stop the others: ``transfer.CellsFailed`` names them all at the end."""
    sources = [pathlib.Path(s).resolve() for s in sources]
    if len(sources) < 2:
        raise ValueError(f"transfer_runs needs at least two runs, got {len(sources)}")
    check_same_settings(sources)
    out = pathlib.Path(out).resolve()
    summaries, failed = {}, []
    for source in sources:
        if progress:
            print(
                f"[transfer] run {source.name} ({len(summaries) + len(failed) + 1} of {len(sources)})"
            )
        try:
            summaries[source.name] = transfer.transfer(
                source, out / source.name, progress=progress, **options
            )
        except transfer.CellsFailed as error:
            failed.append(f"{source.name}: {error}")
    if failed:
        raise transfer.CellsFailed("; ".join(failed))
    summary = combine(summaries)
    storage.write_json(out / "transfer.json", summary)
    storage.write_text(out / "transfer.md", markdown(summary))
    transfer.figures(summary, out / "figures")
    return summary


def _grid(summary: dict) -> dict:
    """Returns what must agree between the runs' summaries: families and their level labels,
    vision mode, trials per row, policies, recognition steps and base perturbations."""
    return {
        "families": {
            f: [lv["label"] for lv in d["levels"]] for f, d in summary["families"].items()
        },
        "combined": (summary.get("combined") or {}).get("preset"),
        **{
            key: summary[key]
            for key in (
                "vision",
                "trials_per_row",
                "policies",
                "recognition_steps",
                "base_perturbations",
            )
        },
    }


def _gather(levels: list, field: str) -> dict:
    """Returns ``{name: {word: [value per run]}}`` of one level's ``field`` over the runs (a run
    without the value, e.g. a word none of whose steps was seen, gives None)."""
    names = sorted({name for level in levels for name in level[field]})
    return {
        name: {
            word: [level[field].get(name, {}).get(word) for level in levels]
            for word in WORDS
            if any(word in level[field].get(name, {}) for level in levels)
        }
        for name in names
    }


def _mean(values: list):
    known = [v for v in values if v is not None]
    return float(np.mean(known)) if known else None


def _worst(values: list):
    known = [v for v in values if v is not None]
    return float(min(known)) if known else None


def _map(gathered: dict, reduce) -> dict:
    return {n: {w: reduce(v) for w, v in words.items()} for n, words in gathered.items()}


def combine(summaries: dict) -> dict:
    """Returns the combined summary of one-run transfer summaries ``{run name: summary}``: per
    family and level the mean ``performance`` and ``recognition`` over the runs, their
    ``worst_performance`` and ``worst_recognition``, the runs' own rates (``per_run``), the pooled
    ``trials`` and the mean ``seen_fraction``; per family the ``envelope`` of the mean and the
    ``worst_envelope`` (every run). ValueError in one line when the runs' grids differ."""
    names = list(summaries)
    first = summaries[names[0]]
    for name in names[1:]:
        mine, theirs = _grid(first), _grid(summaries[name])
        if mine != theirs:
            keys = differing_keys(mine, theirs)
            raise ValueError(
                f"the transfers of {names[0]} and {name} differ in {', '.join(keys)}; rerun them "
                "with the same families, levels, vision, preset and trials"
            )
    policies = first["policies"]
    families = {}
    for family, data in first["families"].items():
        levels, mean_results, worst_results = [], [], []
        for i, level in enumerate(data["levels"]):
            runs = [summaries[name]["families"][family]["levels"][i] for name in names]
            combined = {
                "index": level["index"],
                "label": level["label"],
                "settings": level["settings"],
                **_over_runs(dict(zip(names, runs, strict=True))),
            }
            levels.append(combined)
            mean_results.append(transfer.CellResult({}, 1.0, combined["performance"], {}))
            worst_results.append(transfer.CellResult({}, 1.0, combined["worst_performance"], {}))
        settings = [level["settings"] for level in levels]
        families[family] = {
            "levels": levels,
            "envelope": transfer.envelope(settings, mean_results, policies),
            "worst_envelope": transfer.envelope(settings, worst_results, policies),
        }
    out = {
        "version": SUMMARY_VERSION,
        "runs": {name: summaries[name]["source"] for name in names},
        "vision": first["vision"],
        "randomisation": first["randomisation"],
        "policies": policies,
        "envelope_rate": transfer.ENVELOPE_RATE,
        "base_perturbations": first["base_perturbations"],
        "trials_per_row": first["trials_per_row"],
        "recognition_steps": first["recognition_steps"],
        "cpu_seconds": sum(s["cpu_seconds"] for s in summaries.values()),
        "families": families,
        "versions": package_versions(),
    }
    if "combined" in first:
        runs = {name: summaries[name]["combined"] for name in names}
        out["combined"] = {
            "preset": first["combined"]["preset"],
            "cell": first["combined"]["cell"],
            **_over_runs(runs),
        }
    return out


def _over_runs(runs: dict) -> dict:
    """Returns one cell's numbers over the runs ``{run name: cell numbers}``: the mean and the
    worst run's performance and recognition, the pooled trials, the mean seen fraction and
    each run's own rates."""
    cells = list(runs.values())
    performance = _gather(cells, "performance")
    recognition = _gather(cells, "recognition")
    return {
        "performance": _map(performance, _mean),
        "worst_performance": _map(performance, _worst),
        "recognition": _map(recognition, _mean),
        "worst_recognition": _map(recognition, _worst),
        "trials": _map(_gather(cells, "trials"), lambda v: int(sum(x or 0 for x in v))),
        "seen_fraction": _mean([c["seen_fraction"] for c in cells]),
        "per_run": {
            name: {"performance": c["performance"], "recognition": c["recognition"]}
            for name, c in runs.items()
        },
    }


def _pct(value) -> str:
    return "-" if value is None else f"{100 * value:.0f}"


def _mean_worst(cell: dict, field: str, name: str, word: str) -> str:
    """Returns "mean (worst run)" of one word's rate of a combined level or cell, percent."""
    mean = cell[field].get(name, {}).get(word)
    worst = cell[f"worst_{field}"].get(name, {}).get(word)
    return f"{_pct(mean)} ({_pct(worst)})"


def markdown(summary: dict) -> str:
    """Returns the combined ``transfer.md``: the envelopes of the mean and of the worst run, then
    per family the mean (worst run) of every level's numbers."""
    policies, runs = summary["policies"], summary["runs"]
    rate = f"{100 * summary['envelope_rate']:.0f}%"
    lines = [
        f"# Transfer over {len(runs)} runs ({summary['vision']} vision): {', '.join(runs)}",
        "",
        f"{summary['trials_per_row']} trials per row, policy and run; recognition on "
        f"{summary['recognition_steps']} watched steps a run (the hierarchical associator over "
        "time, or the paper's network without it). Every number: the mean over the runs "
        "(the worst run), percent. Per-run reports: <run>/transfer.md. Perturbations: "
        "docs/transfer.md.",
        "",
        f"## Operating envelope: largest level with success >= {rate}, of the mean over the runs "
        "(of the worst run)",
        "",
        "| family | " + " | ".join(f"{p} {w}" for p in policies for w in WORDS) + " |",
        "|---|" + "---|" * (len(policies) * len(WORDS)),
    ]
    for family, data in summary["families"].items():
        cells = []
        for policy in policies:
            for word in WORDS:
                if word not in data["envelope"].get(policy, {}):
                    cells.append("-")
                    continue
                mean = data["envelope"][policy][word] or "none"
                worst = data["worst_envelope"].get(policy, {}).get(word) or "none"
                cells.append(f"{mean} ({worst})")
        lines.append(f"| {family} | " + " | ".join(cells) + " |")
    if "combined" in summary:
        combined = summary["combined"]
        lines += transfer.combined_table(
            combined,
            policies,
            show=lambda field, name, word: _mean_worst(combined, field, name, word),
        )
    for family, data in summary["families"].items():
        lines += [
            "",
            f"## {family}",
            "",
            "| level | seen | recognition go / pick / lift | "
            + " | ".join(f"{p} go / pick / lift" for p in policies)
            + " |",
            "|---|---|---|" + "---|" * len(policies),
        ]
        for level in data["levels"]:
            readout = transfer.over_time_readout(level["recognition"])
            rec = " / ".join(_mean_worst(level, "recognition", readout, w) for w in WORDS)
            perf = [
                " / ".join(_mean_worst(level, "performance", p, w) for w in WORDS) for p in policies
            ]
            lines.append(
                f"| {level['label']} | {100 * level['seen_fraction']:.0f}% | {rec} | "
                + " | ".join(perf)
                + " |"
            )
    return "\n".join(lines) + "\n"
