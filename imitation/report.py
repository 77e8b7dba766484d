"""The figures and the results files of ``peoplebot reproduce``."""

from __future__ import annotations

import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402, F401  (imitation.sweep draws with it)
import numpy as np  # noqa: E402

from associator import figures as network_figures  # noqa: E402
from imitation import learning, storage, tracefigures  # noqa: E402
from imitation.performance import FIG4_START, POLICIES, dock_pose_at  # noqa: E402
from imitation.results import PAPER_TABLE_I, Results  # noqa: E402
from imitation.streams import TeacherStream  # noqa: E402
from peoplebot_sim import directives  # noqa: E402
from perception.wallframe import world_to_wall_batch  # noqa: E402

#: Samples per word for Fig. 7's recognition sums.
FIG7_SAMPLES = 20_000


def figures(config, folder: pathlib.Path, model, encoder) -> dict:
    """Writes Figs. 3-7 into ``folder/figures``; returns their paths (relative to the folder)."""
    out_dir = folder / "figures"
    out_dir.mkdir(exist_ok=True)

    def saved(name: str, draw) -> pathlib.Path:
        """Draws a figure into a temporary file (``draw(path)``), then commits it as ``name``."""
        path = out_dir / name
        tmp = storage.temporary_name(path)
        draw(tmp)
        return storage.commit(tmp, path)

    paths = {
        "fig3": saved("fig3_word_codes.png", network_figures.fig3_word_codes),
        "fig5": saved(
            "fig5_language_weights.png", lambda p: network_figures.fig5_language_weights(model, p)
        ),
        "fig6": saved(
            "fig6_motor_weights.png", lambda p: network_figures.fig6_motor_weights(model, p)
        ),
    }
    traces = dict(np.load(folder / "fig4_traces.npz", allow_pickle=False))
    if "fig4_student_go" not in traces:  # traces of an earlier version: the paper's network only
        traces.update({f"fig4_student_{w}": traces[w] for w in directives.WORDS})
    dock = dock_pose_at("top", teacher=config.teacher)
    success = config.performance.success
    tolerance = (success.dock_position_tol_m, success.dock_heading_tol_deg)
    order = ("teacher", *(p for p in POLICIES if p != "teacher"))
    paths["fig4"] = saved(
        "fig4_traces.png",
        lambda p: tracefigures.fig4_all(traces, p, FIG4_START, order, dock, tolerance),
    )
    if any(k.startswith("random_") for k in traces):
        paths["fig4_random"] = saved(
            "fig4_random_starts.png",
            lambda p: tracefigures.fig4_random_starts(traces, p, order, dock, tolerance),
        )
    stream = TeacherStream.load(folder / "streams" / "test.npz")
    recognition_inputs, performance_inputs = {}, {}
    for i, word in enumerate(directives.WORDS):
        rows = np.flatnonzero(stream.word == i)[:FIG7_SAMPLES]
        vision, _, motor, _ = learning.encode_stream(
            stream.rows(rows), encoder, config.learning.motor_source, config.task.control_timestep
        )
        recognition_inputs[word] = (vision, motor)
        trace = traces[word]
        x, y, phi, _ = world_to_wall_batch(trace[:, 0], trace[:, 1], trace[:, 2])
        performance_inputs[word] = encoder.encode_batch(x, y, phi, clip=True)
    paths["fig7"] = saved(
        "fig7_hidden_activations.png",
        lambda p: network_figures.fig7_hidden_activations(
            model, p, recognition_inputs, performance_inputs
        ),
    )
    return {k: str(pathlib.Path(v).relative_to(folder)) for k, v in paths.items()}


def _pct(value) -> str:
    return "-" if value is None else f"{100 * value:.1f}%"


def _rate(rate) -> str:
    return f"{_pct(rate.success_rate)} ({rate.successes}/{rate.trials})"


def perturbed_settings(config: dict | None) -> list[str]:
    """Returns ``key = value`` for every perturbation a run's configuration turns on."""
    out = []

    def walk(node, prefix):
        for key, value in node.items():
            if isinstance(value, dict):
                walk(value, f"{prefix}{key}.")
            elif value and key != "occlusion_burst_s":
                out.append(f"{prefix}{key} = {value}")

    walk((config or {}).get("perturbations") or {}, "")
    return out


def markdown(res: Results) -> str:
    """Returns ``results.md``: the tables beside the paper's."""
    words = directives.WORDS
    paper = PAPER_TABLE_I
    lines = [
        f"# Reproduction results (vision: {res.vision}, motor source: "
        f"{res.motor_source}, seed {res.seed})",
        "",
    ]
    perturbed = perturbed_settings(res.config)
    if perturbed:
        lines += [
            "**Perturbed robot** (transfer test, docs/transfer.md): " + ", ".join(perturbed) + ".",
            "",
        ]
    rec = res.recognition
    if rec is not None:
        truth = rec.truth
        lines += [
            "## Recognition (Table I)",
            "",
            "Rows: the behaviour performed; columns: the word recognised. Ours, with the "
            "paper's in brackets.",
            "",
            "| Performing | 'go' | 'pick' | 'lift' | Count (paper) |",
            "|---|---|---|---|---|",
        ]
        for t in words:
            cells = [f"{_pct(truth.fraction(t, r))} ({_pct(paper.confusion[t][r])})" for r in words]
            lines.append(
                f"| '{t}' | " + " | ".join(cells) + f" | {truth.totals()[t]} ({paper.counts[t]}) |"
            )
        lines.append("")
        mw = rec.truth_motor_weighted
        lines += [
            "With the motor area weighted by 3 in the read-out (same network; see "
            "docs/fidelity.md):",
            "",
            "| Performing | 'go' | 'pick' | 'lift' |",
            "|---|---|---|---|",
        ]
        for t in words:
            lines.append(f"| '{t}' | " + " | ".join(_pct(mw.fraction(t, r)) for r in words) + " |")
        lines.append("")
        rows = [
            ("paper", paper),
            ("ours, paper's read-out", truth),
            ("ours, motor-weighted read-out", mw),
            ("ours, hierarchical associator, one step (improvement)", rec.truth_hierarchical),
            (
                "ours, hierarchical associator, over time (improvement)",
                rec.truth_hierarchical_over_time,
            ),
        ]
        lines += [
            "Correct recognition (the diagonal):",
            "",
            "| | 'go' | 'pick' | 'lift' |",
            "|---|---|---|---|",
        ]
        for name, table in rows:
            if table is not None:
                lines.append(
                    f"| {name} | " + " | ".join(_pct(table.correct(t)) for t in words) + " |"
                )
        lines.append("")
    if rec is not None and rec.vision is not None:
        v, vw = rec.vision, rec.vision_motor_weighted
        lines += [
            f"### Recognition through the {res.vision} camera",
            "",
            f"{v.steps} steps watched; the teacher's pose was known on "
            f"{_pct(v.seen_fraction)} of them (median position error "
            f"{v.teacher_position_error_cm.median:.2f} cm). Correct recognition on "
            "those steps, from the camera and from the truth:",
            "",
            "| Performing | camera | truth, same steps | camera, motor-weighted | "
            "truth, same steps, motor-weighted |",
            "|---|---|---|---|---|",
        ]
        for t in words:
            lines.append(
                f"| '{t}' | {_pct(v.vision.correct(t))} | {_pct(v.truth_same_steps.correct(t))} | "
                f"{_pct(vw.vision.correct(t))} | {_pct(vw.truth_same_steps.correct(t))} |"
            )
        vh, vt = rec.vision_hierarchical, rec.vision_hierarchical_over_time
        if vh is not None:
            lines += [
                "",
                "Hierarchical associator on the same steps (one step; over time):",
                "",
                "| Performing | camera | truth, same steps | camera, over time | "
                "truth, same steps, over time |",
                "|---|---|---|---|---|",
            ]
            for t in words:
                lines.append(
                    f"| '{t}' | {_pct(vh.vision.correct(t))} | "
                    f"{_pct(vh.truth_same_steps.correct(t))} | {_pct(vt.vision.correct(t))} | "
                    f"{_pct(vt.truth_same_steps.correct(t))} |"
                )
        lines.append("")
    perf = res.performance
    if perf is not None:
        lines += [
            "## Performance on instruction (success rates)",
            "",
            "| Instruction | student (paper's network) | student (hierarchical) | "
            "teacher (reference) |",
            "|---|---|---|---|",
        ]
        names = {
            "go": "'go' (anywhere)",
            "pick": "'pick' (table's wall)",
            "pick_other_wall": "'pick' started at another wall",
            "lift": "'lift' (docked)",
        }
        for row in ("go", "pick", "pick_other_wall", "lift"):
            student = perf.rate(row, "student")
            if student is None:
                continue
            hierarchical = perf.rate(row, "student_hierarchical")
            teacher = perf.rate(row, "teacher")
            lines.append(
                f"| {names[row]} | {_rate(student)} | "
                + (_rate(hierarchical) if hierarchical else "-")
                + " | "
                + (_rate(teacher) if teacher else "n/a")
                + " |"
            )
        lines.append("")
    lines += ["## Time", "", "| Stage | seconds |", "|---|---|"]
    for stage, seconds in res.seconds_per_stage.items():
        lines.append(f"| {stage} | {seconds:.0f} |")
    lines += [f"| total | {res.total_seconds:.0f} |", ""]
    return "\n".join(lines)
