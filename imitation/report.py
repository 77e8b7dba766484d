"""The figures and the results files of ``peoplebot reproduce``."""

from __future__ import annotations

import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from associator import figures as network_figures  # noqa: E402
from imitation import learning, storage  # noqa: E402
from imitation.performance import FIG4_START  # noqa: E402
from imitation.results import PAPER_TABLE_I, Results  # noqa: E402
from imitation.streams import TeacherStream  # noqa: E402
from peoplebot_sim import directives  # noqa: E402
from perception.wallframe import ArenaGeometry, world_to_wall_batch  # noqa: E402

#: Samples per word for Fig. 7's recognition sums.
FIG7_SAMPLES = 20_000


def fig4_traces(traces: dict, path, start, arena: ArenaGeometry = ArenaGeometry()) -> str:
    """Fig. 4: the student's traces over the arena, one panel per word, from the same start."""
    words = ("go", "pick", "lift")
    h = arena.half_side_m
    x0, x1, y0, y1 = arena.table_box
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.9))
    for ax, word in zip(axes, words, strict=True):
        ax.add_patch(plt.Rectangle((-h, -h), 2 * h, 2 * h, fill=False, lw=2, color="0.2"))
        ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, color="#8b5a2b"))
        ax.plot([-h, h], [-h, h], "--", color="0.6", lw=0.8)
        ax.plot([-h, h], [h, -h], "--", color="0.6", lw=0.8)
        ax.fill([-h, h, 0], [h, h, 0], color="0.9", zorder=0)
        trace = traces[word]
        ax.plot(trace[:, 0], trace[:, 1], lw=1.2, color="tab:blue")
        ax.plot(trace[-1, 0], trace[-1, 1], "s", color="tab:red", ms=5, label="end")
        ax.annotate(
            "",
            xy=(start[0] + 0.35 * np.cos(start[2]), start[1] + 0.35 * np.sin(start[2])),
            xytext=start[:2],
            arrowprops={"arrowstyle": "->", "color": "k"},
        )
        ax.set_title(f"'{word}'")
        ax.set_xlim(-h - 0.1, h + 0.1)
        ax.set_ylim(-h - 0.1, h + 0.1)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle("Student performing on instruction from the same start (paper's Fig. 4)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return str(path)


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
    paths["fig4"] = saved("fig4_traces.png", lambda p: fig4_traces(traces, p, FIG4_START))
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


def markdown(res: Results) -> str:
    """Returns ``results.md``: the tables beside the paper's."""
    words = directives.WORDS
    paper = PAPER_TABLE_I
    lines = [
        f"# Reproduction results (vision: {res.vision}, motor source: "
        f"{res.motor_source}, seed {res.seed})",
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
