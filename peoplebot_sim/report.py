"""The figures and the results files of ``peoplebot reproduce``."""

from __future__ import annotations

import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from associator import figures as network_figures  # noqa: E402
from peoplebot_sim import directives, learning  # noqa: E402
from peoplebot_sim.recognition import PAPER_TABLE_I  # noqa: E402
from peoplebot_sim.streams import TeacherStream  # noqa: E402
from peoplebot_sim.teacher import TABLE_BOX  # noqa: E402
from perception.wallframe import world_to_wall_batch  # noqa: E402

#: Samples per word for Fig. 7's recognition sums.
FIG7_SAMPLES = 20_000


def fig4_traces(traces: dict, path, start) -> str:
    """Fig. 4: the student's traces over the arena, one panel per word, from the same start."""
    words = ("go", "pick", "lift")
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.9))
    for ax, word in zip(axes, words, strict=True):
        ax.add_patch(plt.Rectangle((-2, -2), 4, 4, fill=False, lw=2, color="0.2"))
        ax.add_patch(
            plt.Rectangle(
                (TABLE_BOX[0], TABLE_BOX[2]),
                TABLE_BOX[1] - TABLE_BOX[0],
                TABLE_BOX[3] - TABLE_BOX[2],
                color="#8b5a2b",
            )
        )
        ax.plot([-2, 2], [-2, 2], "--", color="0.6", lw=0.8)
        ax.plot([-2, 2], [2, -2], "--", color="0.6", lw=0.8)
        ax.fill([-2, 2, 0], [2, 2, 0], color="0.9", zorder=0)
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
        ax.set_xlim(-2.1, 2.1)
        ax.set_ylim(-2.1, 2.1)
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
    paths = {
        "fig3": network_figures.fig3_word_codes(out_dir / "fig3_word_codes.png"),
        "fig5": network_figures.fig5_language_weights(model, out_dir / "fig5_language_weights.png"),
        "fig6": network_figures.fig6_motor_weights(model, out_dir / "fig6_motor_weights.png"),
    }
    traces = dict(np.load(folder / "fig4_traces.npz", allow_pickle=False))
    from peoplebot_sim.performance import FIG4_START

    paths["fig4"] = fig4_traces(traces, out_dir / "fig4_traces.png", FIG4_START)
    stream = TeacherStream.load(folder / "streams" / "test.npz")
    recognition_inputs, performance_inputs = {}, {}
    for i, word in enumerate(directives.WORDS):
        rows = np.flatnonzero(stream.word == i)[:FIG7_SAMPLES]
        vision, _, motor, _ = learning.encode_stream(
            stream.rows(rows), encoder, config.motor_source
        )
        recognition_inputs[word] = (vision, motor)
        trace = traces[word]
        x, y, phi, _ = world_to_wall_batch(trace[:, 0], trace[:, 1], trace[:, 2])
        performance_inputs[word] = encoder.encode_batch(x, y, phi, clip=True)
    paths["fig7"] = network_figures.fig7_hidden_activations(
        model, out_dir / "fig7_hidden_activations.png", recognition_inputs, performance_inputs
    )
    return {k: str(pathlib.Path(v).relative_to(folder)) for k, v in paths.items()}


def results(config, state, folder: pathlib.Path) -> dict:
    """Returns the run's results (what ``results.json`` holds)."""
    from peoplebot_sim.reproduce import versions

    stages = state.data["stages"]
    recognition = stages.get("recognition", {})
    truth = recognition.get("truth", {})
    performance = stages.get("performance", {})
    perf = {}
    for row in ("go", "pick", "lift", "pick_other_wall"):
        if row in performance and performance[row].get("student"):
            perf[row] = performance[row]["student"]
    perf["hierarchical"] = {
        row: performance[row]["student_hierarchical"]
        for row in ("go", "pick", "lift", "pick_other_wall")
        if row in performance and performance[row].get("student_hierarchical")
    }
    perf["teacher_reference"] = {
        row: performance[row]["teacher"]
        for row in ("go", "pick", "lift")
        if row in performance and performance[row].get("teacher")
    }
    return {
        "paper": "Elshaw, Weber, Zochios and Wermter: an associator network approach to robot "
        "learning by imitation through vision, motor control and language",
        "vision": config.vision,
        "motor_source": config.motor_source,
        "seed": config.seed,
        "recognition": {
            "confusion": truth.get("confusion"),
            "counts": truth.get("counts"),
            "counts_matrix": truth.get("counts_matrix"),
            "paper": PAPER_TABLE_I,
            "motor_weighted": recognition.get("truth_motor_weighted"),
            "hierarchical": recognition.get("truth_hierarchical"),
            "hierarchical_over_time": recognition.get("truth_hierarchical_over_time"),
            "readouts": recognition.get("readouts"),
            **({"vision": recognition["vision"]} if "vision" in recognition else {}),
            **(
                {"vision_motor_weighted": recognition["vision_motor_weighted"]}
                if "vision_motor_weighted" in recognition
                else {}
            ),
            **{
                key: recognition[key]
                for key in ("vision_hierarchical", "vision_hierarchical_over_time")
                if key in recognition
            },
        },
        "performance": perf,
        "fig4": performance.get("fig4"),
        "streams": stages.get("streams"),
        "learning": stages.get("learning"),
        "figures": stages.get("figures"),
        "videos": stages.get("videos", {}).get("videos"),
        "seconds_per_stage": state.data.get("seconds", {}),
        "total_seconds": float(sum(state.data.get("seconds", {}).values())),
        "config": config.as_dict(),
        "versions": versions(),
    }


def _pct(value) -> str:
    return "-" if value is None else f"{100 * value:.1f}%"


def markdown(res: dict) -> str:
    """Returns ``results.md``: the tables beside the paper's."""
    words = directives.WORDS
    lines = [
        f"# Reproduction results (vision: {res['vision']}, motor source: "
        f"{res['motor_source']}, seed {res['seed']})",
        "",
    ]
    rec = res["recognition"]
    if rec.get("confusion"):
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
            cells = [
                f"{_pct(rec['confusion'][t][r])} ({_pct(rec['paper']['confusion'][t][r])})"
                for r in words
            ]
            lines.append(
                f"| '{t}' | "
                + " | ".join(cells)
                + f" | {rec['counts'][t]} ({rec['paper']['counts'][t]}) |"
            )
        lines.append("")
        if rec.get("motor_weighted"):
            mw = rec["motor_weighted"]
            lines += [
                "With the motor area weighted by 3 in the read-out (same network; see the "
                "README's fidelity notes):",
                "",
                "| Performing | 'go' | 'pick' | 'lift' |",
                "|---|---|---|---|",
            ]
            for t in words:
                lines.append(
                    f"| '{t}' | " + " | ".join(_pct(mw["confusion"][t][r]) for r in words) + " |"
                )
            lines.append("")
        lines += [
            "Correct recognition (the diagonal):",
            "",
            "| | 'go' | 'pick' | 'lift' |",
            "|---|---|---|---|",
            "| paper | " + " | ".join(_pct(rec["paper"]["confusion"][t][t]) for t in words) + " |",
            "| ours, paper's read-out | "
            + " | ".join(_pct(rec["confusion"][t][t]) for t in words)
            + " |",
        ]
        if rec.get("motor_weighted"):
            lines.append(
                "| ours, motor-weighted read-out | "
                + " | ".join(_pct(rec["motor_weighted"]["confusion"][t][t]) for t in words)
                + " |"
            )
        if rec.get("hierarchical"):
            lines.append(
                "| ours, hierarchical associator, one step (improvement) | "
                + " | ".join(_pct(rec["hierarchical"]["confusion"][t][t]) for t in words)
                + " |"
            )
        if rec.get("hierarchical_over_time"):
            lines.append(
                "| ours, hierarchical associator, over time (improvement) | "
                + " | ".join(_pct(rec["hierarchical_over_time"]["confusion"][t][t]) for t in words)
                + " |"
            )
        lines.append("")
    if "vision" in rec:
        v = rec["vision"]
        lines += [
            f"### Recognition through the {res['vision']} camera",
            "",
            f"{v['steps']} steps watched; the teacher's pose was known on "
            f"{_pct(v['seen_fraction'])} of them (median position error "
            f"{v['teacher_position_error_cm']['median']:.2f} cm). Correct recognition on "
            "those steps, from the camera and from the truth:",
            "",
            "| Performing | camera | truth, same steps | camera, motor-weighted | "
            "truth, same steps, motor-weighted |",
            "|---|---|---|---|---|",
        ]
        vh = rec.get("vision_hierarchical")
        vw = rec.get("vision_motor_weighted")
        for t in words:
            extra = (
                (
                    f" {_pct(vw['vision']['confusion'][t][t])} | "
                    f"{_pct(vw['truth_same_steps']['confusion'][t][t])} |"
                )
                if vw
                else " - | - |"
            )
            lines.append(
                f"| '{t}' | {_pct(v['vision']['confusion'][t][t])} | "
                f"{_pct(v['truth_same_steps']['confusion'][t][t])} |" + extra
            )
        vt = rec.get("vision_hierarchical_over_time")
        if vh:
            lines += [
                "",
                "Hierarchical associator on the same steps (one step; over time):",
                "",
                "| Performing | camera | truth, same steps | camera, over time | "
                "truth, same steps, over time |",
                "|---|---|---|---|---|",
            ]
            for t in words:
                later = (
                    f" {_pct(vt['vision']['confusion'][t][t])} | "
                    f"{_pct(vt['truth_same_steps']['confusion'][t][t])} |"
                    if vt
                    else " - | - |"
                )
                lines.append(
                    f"| '{t}' | {_pct(vh['vision']['confusion'][t][t])} | "
                    f"{_pct(vh['truth_same_steps']['confusion'][t][t])} |" + later
                )
        lines.append("")
    perf = res["performance"]
    if perf:
        ref = perf.get("teacher_reference", {})
        hier = perf.get("hierarchical", {})
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
            if row not in perf:
                continue
            s = perf[row]
            r = ref.get(row)
            h = hier.get(row)
            lines.append(
                f"| {names[row]} | {_pct(s['success_rate'])} ({s['successes']}/"
                f"{s['trials']}) | "
                + (f"{_pct(h['success_rate'])} ({h['successes']}/{h['trials']})" if h else "-")
                + " | "
                + (f"{_pct(r['success_rate'])} ({r['successes']}/{r['trials']})" if r else "n/a")
                + " |"
            )
        lines.append("")
    lines += ["## Time", "", "| Stage | seconds |", "|---|---|"]
    for stage, seconds in res["seconds_per_stage"].items():
        lines.append(f"| {stage} | {seconds:.0f} |")
    lines += [f"| total | {res['total_seconds']:.0f} |", ""]
    return "\n".join(lines)
