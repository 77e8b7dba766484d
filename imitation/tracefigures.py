"""Fig. 4 of the paper for every policy, and its companion from random starts, drawn from a run's
``fig4_traces.npz`` (see ``imitation.trials.fig4_traces``): the arena (world frame, metres), the
table, the wall areas, the docking tolerance, a 1 m scale bar and the robot's outline."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Circle, Patch, Polygon, Rectangle, Wedge  # noqa: E402

from perception.wallframe import ArenaGeometry  # noqa: E402

WORDS = ("go", "pick", "lift")
#: Each policy's row title.
TITLES = {
    "teacher": "teacher (reference)",
    "student": "student: paper's network",
    "student_hierarchical": "student: hierarchical associator",
}
#: The robot's footprint, metres (length along x, width along y; models/peoplebot/README.md).
FOOTPRINT_M = (0.513, 0.425)


def _arena(ax, arena: ArenaGeometry, dock, tolerance) -> None:
    """Draws the walls, the wall areas (the top wall's shaded), the table, the docking tolerance
    (a circle of the position tolerance with the heading tolerance as a wedge) and a 1 m bar."""
    h = arena.half_side_m
    x0, x1, y0, y1 = arena.table_box
    ax.add_patch(Rectangle((-h, -h), 2 * h, 2 * h, fill=False, lw=2, color="0.2"))
    ax.fill([-h, h, 0], [h, h, 0], color="0.9", zorder=0)
    ax.plot([-h, h], [-h, h], "--", color="0.6", lw=0.8)
    ax.plot([-h, h], [h, -h], "--", color="0.6", lw=0.8)
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color="#8b5a2b"))
    if dock is not None:
        position_m, heading_deg = tolerance
        ax.add_patch(Circle(dock[:2], position_m, fill=False, color="tab:green", lw=1.2))
        yaw = math.degrees(dock[2])
        ax.add_patch(
            Wedge(dock[:2], 0.3, yaw - heading_deg, yaw + heading_deg, color="tab:green", alpha=0.3)
        )
    ax.plot([-h + 0.1, -h + 1.1], [-h - 0.06, -h - 0.06], color="k", lw=2)
    ax.text(-h + 0.6, -h - 0.1, "1 m", ha="center", va="top", fontsize=7)
    ax.set_xlim(-h - 0.1, h + 0.1)
    ax.set_ylim(-h - 0.3, h + 0.1)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def _outline(ax, pose, colour, style="-") -> None:
    """Draws the robot's footprint at ``pose`` (x m, y m, yaw rad) with a tick to its front."""
    length, width = FOOTPRINT_M
    x, y, yaw = (float(v) for v in pose)
    c, s = math.cos(yaw), math.sin(yaw)
    corners = np.array(
        [[sx * length / 2, sy * width / 2] for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
    )
    world = corners @ np.array([[c, s], [-s, c]]) + (x, y)
    ax.add_patch(Polygon(world, closed=True, fill=False, color=colour, lw=1.0, ls=style))
    ax.plot([x, x + 0.3 * c], [y, y + 0.3 * s], color=colour, lw=1.0, ls=style)


def _legend(fig) -> None:
    handles = [
        Line2D([], [], color="tab:blue", lw=1.2, label="path"),
        Line2D([], [], marker=r"$\rightarrow$", color="k", ls="", ms=10, label="start, heading"),
        Line2D([], [], marker="s", color="tab:red", ls="", ms=5, label="end"),
        Patch(fill=False, ec="0.3", label="robot outline (start dashed, end solid)"),
        Patch(fc="tab:green", alpha=0.4, ec="tab:green", label="docking tolerance ('pick')"),
        Patch(fc="#8b5a2b", label="table"),
        Patch(fc="0.9", label="top wall's area"),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=8, frameon=False)


def fig4_all(
    traces: dict,
    path,
    start,
    policies,
    dock,
    tolerance,
    arena: ArenaGeometry = ArenaGeometry(),
) -> str:
    """Fig. 4 for every policy (one row each, the paper's layout: one panel per word, all from
    ``start``, x m, y m, yaw rad); ``dock``: the docked pose, drawn with ``tolerance`` (metres,
    degrees). ``traces``: ``fig4_<policy>_<word>`` (n, 3) world poses and
    ``fig4_<policy>_<word>_success``."""
    policies = [p for p in policies if f"fig4_{p}_go" in traces]
    fig, axes = plt.subplots(
        len(policies), 3, figsize=(10.5, 3.6 * len(policies) + 0.8), squeeze=False
    )
    for row, policy in enumerate(policies):
        for ax, word in zip(axes[row], WORDS, strict=True):
            _arena(ax, arena, dock if word == "pick" else None, tolerance)
            trace = traces[f"fig4_{policy}_{word}"]
            ax.plot(trace[:, 0], trace[:, 1], lw=1.2, color="tab:blue")
            _outline(ax, start, "0.3", "--")
            _outline(ax, trace[-1], "k")
            ax.plot(trace[-1, 0], trace[-1, 1], "s", color="tab:red", ms=5)
            ax.annotate(
                "",
                xy=(start[0] + 0.35 * np.cos(start[2]), start[1] + 0.35 * np.sin(start[2])),
                xytext=start[:2],
                arrowprops={"arrowstyle": "->", "color": "k"},
            )
            ok = bool(traces.get(f"fig4_{policy}_{word}_success", False))
            ax.set_title(f"'{word}': {'success' if ok else 'failure'}", fontsize=9)
        axes[row, 0].set_ylabel(TITLES.get(policy, policy), fontsize=9)
    fig.suptitle("Performing on instruction from the same start (the paper's Fig. 4)")
    fig.tight_layout(rect=(0, 0.06, 1, 0.97))
    _legend(fig)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


def fig4_random_starts(
    traces: dict,
    path,
    policies,
    dock,
    tolerance,
    arena: ArenaGeometry = ArenaGeometry(),
) -> str:
    """Fig. 4's companion: every policy (rows) from the first random starts of each word's trials
    (columns); successful paths blue, failed ones red, starts as outlines. ``traces``:
    ``random_<policy>_<word>`` (k, n, 3), NaN after a trial's end, and ``..._success`` (k,)."""
    policies = [p for p in policies if f"random_{p}_go" in traces]
    fig, axes = plt.subplots(
        len(policies), 3, figsize=(10.5, 3.6 * len(policies) + 0.8), squeeze=False
    )
    for row, policy in enumerate(policies):
        for ax, word in zip(axes[row], WORDS, strict=True):
            _arena(ax, arena, dock if word in ("pick", "lift") else None, tolerance)
            paths = traces[f"random_{policy}_{word}"]
            success = traces[f"random_{policy}_{word}_success"]
            for trace, ok in zip(paths, success, strict=True):
                trace = trace[np.all(np.isfinite(trace), axis=1)]
                colour = "tab:blue" if ok else "tab:red"
                ax.plot(trace[:, 0], trace[:, 1], lw=0.8, color=colour, alpha=0.8)
                _outline(ax, trace[0], "0.4", "--")
                ax.plot(trace[-1, 0], trace[-1, 1], "s", color=colour, ms=3)
            ax.set_title(f"'{word}': {int(np.sum(success))} of {len(success)} succeed", fontsize=9)
        axes[row, 0].set_ylabel(TITLES.get(policy, policy), fontsize=9)
    fig.suptitle("Performing on instruction from the trials' first random starts")
    fig.tight_layout(rect=(0, 0.05, 1, 0.97))
    handles = [
        Line2D([], [], color="tab:blue", lw=1, label="success"),
        Line2D([], [], color="tab:red", lw=1, label="failure"),
        Line2D([], [], marker="s", color="0.3", ls="", ms=4, label="end"),
        Patch(fill=False, ec="0.4", ls="--", label="robot at its start"),
        Patch(fc="tab:green", alpha=0.4, ec="tab:green", label="docking tolerance"),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=5, fontsize=8, frameon=False)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)
