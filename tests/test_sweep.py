"""``peoplebot sweep`` (``imitation.sweep``): the grid, the statistics on known inputs, and tiny
sweeps through a local Ray (cells equal ``peoplebot reproduce`` runs, a rerun skips finished cells, a
cell whose worker dies is retried) and through a two-node cluster on this machine.

A tiny cell: 2,000 training and 1,000 test steps, one 5 s trial per row and policy, no videos.
"""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import json
import math

import numpy as np
import pytest

from imitation import reproduce, sweep
from imitation.cli import main
from imitation.config import RunConfig

TINY = RunConfig.quick().replace(
    {
        "learning.train_steps": 2000,
        "learning.test_steps": 1000,
        "performance.trials": 1,
        "performance.trial_seconds": 5.0,
        "videos.enabled": False,
        "workers": 1,
    }
)
TINY_OPTIONS = [
    "reproduce",
    "--quick",
    "--train-steps",
    "2000",
    "--test-steps",
    "1000",
    "--trials",
    "1",
    "--trial-seconds",
    "5",
    "--no-videos",
]


def comparable(results: dict) -> dict:
    out = {k: v for k, v in results.items() if k not in ("seconds_per_stage", "total_seconds")}
    out["config"] = {k: v for k, v in results["config"].items() if k != "workers"}
    return out


# ------------------------------------------------------------------------------ the grid
def test_seeds_and_settings_are_parsed():
    assert sweep.parse_seeds("0-4") == (0, 1, 2, 3, 4)
    assert sweep.parse_seeds("0,3,7") == (0, 3, 7)
    assert sweep.parse_setting("network.pose_weight=0.01,0.03") == (
        "network.pose_weight",
        (0.01, 0.03),
    )
    assert sweep.parse_setting("vision.mode=truth,overhead")[1] == ("truth", "overhead")
    assert sweep.parse_setting("videos.enabled=true,false")[1] == (True, False)
    for bad, message in [("4-0", "range like 0-4"), ("a,b", "range like 0-4"), ("1,1", "repeats")]:
        with pytest.raises(ValueError, match=message):
            sweep.parse_seeds(bad)
    with pytest.raises(ValueError, match="KEY=V1,V2"):
        sweep.parse_setting("network.eta")
    with pytest.raises(ValueError, match="--seeds"):
        sweep.parse_setting("seed=1,2")


def test_the_grid_is_the_product_of_seeds_and_settings():
    cells = sweep.grid(
        TINY,
        (0, 1),
        [
            ("hierarchical.pose_weight", (0.01, 0.03)),
            ("performance.drive", ("graded", "directive")),
        ],
    )
    assert len(cells) == 8
    assert len({c.name for c in cells}) == 8
    cell = next(
        c for c in cells if c.seed == 1 and dict(c.settings)["performance.drive"] == "directive"
    )
    assert cell.config.seed == 1 and cell.config.performance.drive == "directive"
    assert cell.name.startswith("seed1,")
    with pytest.raises(ValueError, match="unknown config key 'network.etta'"):
        sweep.grid(TINY, (0,), [("network.etta", (0.1,))])
    with pytest.raises(ValueError, match="performance.trials must be a positive integer"):
        sweep.grid(TINY, (0,), [("performance.trials", (0,))])


# ------------------------------------------------------------------------------ statistics
def test_statistics_on_known_inputs():
    stats = sweep.statistics([0.2, 0.4, 0.6], bounds=(-math.inf, math.inf))
    assert stats["n"] == 3 and stats["mean"] == pytest.approx(0.4)
    half = 4.3027 * 0.2 / math.sqrt(3)  # t(0.975, 2) sd / sqrt(n)
    assert stats["ci95"] == pytest.approx([0.4 - half, 0.4 + half])
    assert (stats["min"], stats["max"]) == (0.2, 0.6)
    # A fraction's interval is clipped to [0, 1]; one value has no interval.
    assert sweep.statistics([0.2, 0.4, 0.6])["ci95"][0] == 0.0
    assert sweep.statistics([0.7])["ci95"] is None
    # The t quantiles: the table, then the expansion, against known values.
    assert sweep.t_quantile_975(4) == pytest.approx(2.7764, abs=1e-4)
    for df, known in ((31, 2.0395), (60, 2.0003), (120, 1.9799), (1000, 1.9623)):
        assert sweep.t_quantile_975(df) == pytest.approx(known, abs=2e-4)


def test_summary_groups_cells_by_their_settings_and_finds_the_worst_seed():
    def results(pick):
        return {
            "recognition": {
                "confusion": {w: {w: 0.5 if w != "pick" else pick} for w in sweep.WORDS}
            },
            "performance": {"pick": {"success_rate": pick}},
        }

    cells = sweep.grid(TINY, (0, 1, 2), [("hierarchical.pose_weight", (0.01, 0.03))])
    outcomes = [
        sweep.CellOutcome(
            c,
            "finished",
            results(0.1 * (c.seed + 1) + dict(c.settings)["hierarchical.pose_weight"]),
        )
        for c in cells
    ]
    summary = sweep.summarise(outcomes, (0, 1, 2), [("hierarchical.pose_weight", (0.01, 0.03))])
    assert [g["settings"] for g in summary["groups"]] == [
        {"hierarchical.pose_weight": 0.01},
        {"hierarchical.pose_weight": 0.03},
    ]
    pick = summary["groups"][1]["metrics"]["performance.student.pick"]
    assert pick["mean"] == pytest.approx(0.23) and pick["n"] == 3
    assert pick["worst_seed"] == 0 and pick["min"] == pytest.approx(0.13)
    assert summary["groups"][0]["metrics"]["recognition.paper.pick"]["max"] == pytest.approx(0.31)
    text = sweep.markdown(summary)
    assert "## hierarchical.pose_weight = 0.03 (seeds 0, 1, 2)" in text
    assert "| student (paper's network) | - | 23.0 [" in text


# ------------------------------------------------------------------------------ on Ray
@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    """A two-cell sweep (seeds 0 and 1) through a local Ray, via the command line."""
    out = tmp_path_factory.mktemp("sweep") / "out"
    code = main(["sweep", "--out", str(out), "--seeds", "0,1", "--workers", "2", *TINY_OPTIONS])
    return out, code


def test_both_cells_finish_and_equal_reproduce_runs(local_sweep, tmp_path):
    out, code = local_sweep
    assert code == 0
    summary = json.loads((out / "sweep.json").read_text())
    assert summary["counts"] == {"finished": 2, "skipped": 0, "failed": 0}
    assert (out / "sweep.md").read_text().startswith("# Sweep")
    assert (out / "figures" / "performance.student_hierarchical.pick.png").stat().st_size > 1000
    direct = reproduce.run(TINY.replace({"seed": 1}), tmp_path / "direct").to_json()
    cell = json.loads((out / "cells" / "seed1" / "results.json").read_text())
    assert comparable(cell) == comparable(direct)
    stats = summary["groups"][0]["metrics"]["recognition.paper.go"]
    by_seed = [
        json.loads((out / "cells" / f"seed{s}" / "results.json").read_text())["recognition"][
            "confusion"
        ]["go"]["go"]
        for s in (0, 1)
    ]
    assert stats["mean"] == pytest.approx(np.mean(by_seed))
    # The two cells watched their own streams, generated once into the shared cache.
    assert len(list((out / "stream-cache").glob("stream-*.npz"))) == 4


def test_a_rerun_skips_finished_cells(local_sweep, monkeypatch):
    out, _ = local_sweep

    def never(*args, **kwargs):
        raise AssertionError("a finished cell ran again")

    monkeypatch.setattr(sweep, "_run_on_ray", never)
    summary = sweep.sweep(TINY, (0, 1), [], out, progress=False)
    assert summary["counts"] == {"finished": 0, "skipped": 2, "failed": 0}


def test_without_an_address_a_local_ray_is_started_even_beside_a_running_cluster():
    """A Ray cluster already running on this machine (it leaves its address in Ray's temporary
    folder, where a bare ``ray.init`` would find and join it): with no address and no
    ``RAY_ADDRESS`` (set aside for the tests, conftest.py), the tasks run on a new local Ray of
    ``workers`` CPUs, not on that cluster."""
    import ray
    from ray.cluster_utils import Cluster

    from imitation import raytasks

    def _node_and_cpus(_):  # defined here, so Ray sends it by value
        return ray.get_runtime_context().get_node_id(), ray.cluster_resources()["CPU"]

    cluster = Cluster(
        initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False}
    )
    cluster_node = cluster.head_node.node_id
    try:
        outcomes = list(raytasks.run_tasks(_node_and_cpus, {"a": (0,)}, workers=2, progress=False))
        assert not ray.is_initialized(), "the local Ray should be shut down after the tasks"
    finally:
        cluster.shutdown()
    assert outcomes[0].error is None
    node, cpus = outcomes[0].value
    assert node != cluster_node
    assert cpus == 2


def test_a_two_node_cluster_runs_cells_on_both_nodes_and_retries_a_dying_worker(
    tmp_path, monkeypatch
):
    """Two nodes of one CPU each on this machine (``ray.cluster_utils.Cluster``): a sweep joined by
    address runs its two cells at once, one on each node; the first cell attempt to start dies
    (``DIE_ONCE_ENV``: ``os._exit`` in the worker), Ray retries it and both cells finish."""
    import ray
    from ray.cluster_utils import Cluster

    marker = tmp_path / "died-once"
    monkeypatch.setenv(sweep.DIE_ONCE_ENV, str(marker))

    cluster = Cluster(
        initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False}
    )
    cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    try:
        summary = sweep.sweep(
            TINY, (3, 4), [], tmp_path / "out", address=cluster.address, progress=False
        )
    finally:
        ray.shutdown()
        cluster.shutdown()
    assert marker.exists(), "the first attempt should have died"
    assert summary["counts"] == {"finished": 2, "skipped": 0, "failed": 0}
    assert sorted(c["results"]["seed"] for c in summary["cells"]) == [3, 4]
    nodes = {c["node"] for c in summary["cells"]}
    assert len(nodes) == 2 and None not in nodes
