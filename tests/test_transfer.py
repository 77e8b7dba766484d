"""``peoplebot transfer`` end to end at a tiny scale: the report, the envelope, resuming."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import dataclasses
import json
import math

import pytest

from associator import encoding
from imitation import reproduce, transfer, transfer_runs
from imitation.cli import main
from imitation.config import RunConfig
from imitation.runstate import RunState
from perception.wallframe import ArenaGeometry

ENCODER = encoding.VisionEncoder(half_side_m=ArenaGeometry().half_side_m)
TINY = {
    "learning.train_steps": 1500,
    "learning.test_steps": 600,
    "vision.test_steps": 50,
    "performance.trials": 1,
    "performance.trial_seconds": 5.0,
    "hierarchical.enabled": False,
    "videos.enabled": False,
    "workers": 1,
}


def _numbers(path):
    """Returns a transfer.json without its CPU seconds (which differ from run to run)."""

    def strip(value):
        if isinstance(value, dict):
            return {k: strip(v) for k, v in value.items() if k != "cpu_seconds"}
        if isinstance(value, list):
            return [strip(v) for v in value]
        return value

    return strip(json.loads(path.read_text()))


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray of two CPUs for the module's transfers (``raytasks.run_tasks`` uses a Ray that
    is already started and leaves it running)."""
    import ray

    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def _trained(folder, config: RunConfig):
    """Finishes the streams and learning stages of ``config`` in ``folder`` (what a transfer
    reads); returns the folder."""
    state = RunState(folder, config.to_dict())
    streams = reproduce.stage_streams(config, folder)
    state.finish(
        "streams",
        {k: v.to_json() for k, v in streams.items()},
        [folder / v.path for v in streams.values()],
    )
    learned = reproduce.stage_learning(config, folder, ENCODER)
    state.finish("learning", learned.to_json(), [folder / learned.paper.network])
    state.close()
    return folder


@pytest.fixture(scope="module")
def trained_run(tmp_path_factory):
    """Returns a tiny run folder with its networks trained without domain randomisation."""
    config = RunConfig.quick().replace({**TINY, "randomisation.families": []})
    return _trained(tmp_path_factory.mktemp("source"), config)


@pytest.fixture(scope="module")
def randomised_run(tmp_path_factory):
    """Returns the same tiny run trained with the perception faults randomised."""
    config = RunConfig.quick().replace({**TINY, "randomisation.families": ["pose_noise"]})
    return _trained(tmp_path_factory.mktemp("randomised"), config)


@pytest.fixture(scope="module")
def other_seed_run(tmp_path_factory):
    """Returns the tiny run of ``trained_run`` with another seed (streams and networks new)."""
    config = RunConfig.quick().replace({**TINY, "randomisation.families": [], "seed": 1})
    return _trained(tmp_path_factory.mktemp("seedone"), config)


def test_transfer_reports_each_level_and_the_envelope_and_resumes(trained_run, tmp_path, local_ray):
    out = tmp_path / "transfer"
    argv = [
        "transfer",
        "--reuse-from",
        str(trained_run),
        "--out",
        str(out),
        "--families",
        "latency,command_latency",
        "--levels",
        "0,3",
        "--trials",
        "1",
        "--vision-test-steps",
        "50",
        "--workers",
        "2",
    ]
    assert main(argv) == 0
    summary = json.loads((out / "transfer.json").read_text())
    latency = summary["families"]["latency"]
    assert [level["label"] for level in latency["levels"]] == ["0", "latency_ms=200"]
    assert [level["cell"] for level in latency["levels"]] == ["baseline", "latency-3"]
    baseline = latency["levels"][0]
    assert set(baseline["performance"]) == {"student", "teacher"}
    assert baseline["trials"]["teacher"]["lift"] == 1
    assert 0 <= baseline["recognition"]["paper"]["go"] <= 1
    assert baseline["seen_fraction"] == 1.0
    assert latency["levels"][1]["seen_fraction"] < 1.0  # the first two steps are not yet seen
    # The envelope: the largest level up to which a word succeeds >= 80% (None: level 0 fails).
    levels, results = (
        [{}, {"perception.latency_ms": 200}],
        [
            transfer.CellResult({}, 1.0, {"teacher": {"lift": 1.0, "go": 0.5}}, {}),
            transfer.CellResult({}, 1.0, {"teacher": {"lift": 0.8, "go": 1.0}}, {}),
        ],
    )
    assert transfer.envelope(levels, results)["teacher"] == {"go": None, "lift": "latency_ms=200"}
    for family in ("latency", "command_latency"):
        assert (out / "figures" / f"{family}.png").stat().st_size > 10_000
        assert set(summary["families"][family]["envelope"]) == {"student", "teacher"}
    text = (out / "transfer.md").read_text()
    assert "Operating envelope" in text and "latency_ms=200" in text
    # The combined row: every family at once at the realistic preset's levels, one more cell.
    combined = summary["combined"]
    assert (combined["preset"], combined["cell"]) == ("realistic", "combined-realistic")
    assert combined["trials"]["teacher"]["lift"] == 1 and combined["seen_fraction"] < 1.0
    cell_config = json.loads((out / "cells" / "combined-realistic" / "state.json").read_text())
    assert cell_config["config"]["perturbations"]["actuation"]["linear_accel_mps2"] == 0.3
    assert "Every family at once: the `realistic` preset's levels" in text

    # A rerun keeps every finished cell; a cell whose trials file was lost runs its trials again
    # (on Ray: the cells ran there, through the same machinery as peoplebot sweep's).
    before = _numbers(out / "transfer.json")
    kept = out / "cells" / "baseline" / "performance_trials.json"
    kept_mtime = kept.stat().st_mtime_ns
    lost = out / "cells" / "latency-3" / "performance_trials.json"
    lost.unlink()
    assert main(argv) == 0
    assert lost.is_file() and kept.stat().st_mtime_ns == kept_mtime
    assert _numbers(out / "transfer.json") == before

    # Other settings in a finished cell are refused in one line; --fresh starts over.
    trials_2 = [*argv, "--trials", "2"]  # the last --trials counts
    assert main(trials_2) == 2
    assert main([*trials_2, "--fresh", "--combined", "none"]) == 0
    again = json.loads((out / "transfer.json").read_text())
    assert again["families"]["latency"]["levels"][0]["trials"]["teacher"]["lift"] == 2
    assert "combined" not in again


def test_a_compared_run_appears_in_the_same_report(
    trained_run, randomised_run, tmp_path, local_ray
):
    out = tmp_path / "transfer"
    argv = ["transfer", "--reuse-from", str(trained_run), "--compare", str(randomised_run)]
    argv += ["--out", str(out), "--families", "pose_noise", "--levels", "0,4", "--trials", "1"]
    assert main([*argv, "--vision-test-steps", "50"]) == 0
    summary = json.loads((out / "transfer.json").read_text())
    assert summary["compare"]["label"] == "randomised"
    assert summary["compare"]["randomisation"]["families"] == ["pose_noise"]
    assert summary["policies"] == [
        "student",
        "student_hierarchical",
        "teacher",
        "student (randomised)",
        "student_hierarchical (randomised)",
    ]
    level = summary["families"]["pose_noise"]["levels"][1]
    assert set(level["performance"]) == {"student", "teacher", "student (randomised)"}
    assert level["trials"]["student (randomised)"]["go"] == 1
    assert set(level["recognition"]) == {"paper", "paper (randomised)"}
    assert "student (randomised)" in summary["families"]["pose_noise"]["envelope"]
    # The compared run's cells hold its students only; the teacher runs once, in the main cells.
    trials = json.loads(
        (out / "compare" / "cells" / "pose_noise-4" / "performance_trials.json").read_text()
    )
    assert {t["policy"] for t in trials} == {"student"}
    text = (out / "transfer.md").read_text()
    assert "student (randomised) go" in text and "recognition (randomised)" in text


def test_the_report_counts_the_recognition_steps_that_were_watched(trained_run):
    """In the 'truth' mode recognition reads the source's test stream (600 steps here), so a
    report asked for more says 600; through a camera it watches as many as asked."""
    config = RunConfig.quick().replace({**TINY, "vision.test_steps": 5000})
    assert transfer._recognition_steps(config, trained_run) == 600
    assert transfer._recognition_steps(config.replace({"vision.test_steps": 50}), trained_run) == 50
    overhead = config.replace({"vision.mode": "overhead"})
    assert transfer._recognition_steps(overhead, trained_run) == 5000


def test_a_camera_cell_watches_as_its_run_is_configured(monkeypatch, tmp_path):
    """A camera-mode cell's recognition watches with the run's own pose source and overhead
    camera registration, not the defaults."""
    seen = {}

    class Watched(Exception):
        pass

    def watch(*args, **kwargs):
        seen.update(kwargs)
        raise Watched

    monkeypatch.setattr(transfer.recognition, "watch_with_vision", watch)
    config = RunConfig.quick().replace(
        {
            "vision.mode": "overhead",
            "vision.self_localisation": "odometry",
            "vision.overhead_registration": "floor_markers",
        }
    )
    with pytest.raises(Watched):
        transfer._recognition(config, tmp_path)
    assert seen["self_localisation"] == "odometry"
    assert seen["overhead_registration"] == "floor_markers"


def test_transfer_refuses_a_folder_that_is_not_a_finished_run(tmp_path, capsys):
    assert main(["transfer", "--reuse-from", str(tmp_path), "--out", str(tmp_path / "t")]) == 2
    assert "is not a run folder" in capsys.readouterr().err
    with pytest.raises(ValueError, match="unknown family 'nope'; allowed: pose_noise"):
        transfer.parse_families("nope")
    with pytest.raises(ValueError, match="--levels"):
        transfer.parse_levels("a,1")


def test_the_figures_intervals_are_wilsons():
    assert transfer.wilson_interval(0.5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    assert transfer.wilson_interval(1.0, 3) == pytest.approx((0.4385, 1.0), abs=1e-4)
    for trials in range(1, 60):  # it holds the rate, rounding included
        for k in range(trials + 1):
            low, high = transfer.wilson_interval(k / trials, trials)
            assert low <= k / trials <= high
    assert all(math.isnan(v) for v in transfer.wilson_interval(None, 0))


def test_the_default_grid_is_what_the_help_says():
    from imitation import perturbations

    counts = [
        sum(perturbations.acts_in(f, mode) for f in perturbations.FAMILIES)
        for mode in ("truth", "overhead", "head")
    ]
    assert counts == [10, 21, 22]  # the numbers in --families's help
    assert set(perturbations.ANCHOR_LEVELS) == set(perturbations.FAMILIES)
    for family, (anchor, past) in perturbations.ANCHOR_LEVELS.items():
        assert 0 < anchor < past < len(perturbations.FAMILIES[family]), family
    base = RunConfig.quick()
    rows, cells = transfer.plan(base, transfer.parse_families(None, "truth"))
    assert len(cells) == 21 and len(rows) == 30  # --help: 21 cells in the 'truth' mode
    quick = transfer.SCALES["quick"]
    assert len(transfer.plan(base, quick.families)[1]) == 9
    # Plus the combined cell (22 and 10 in --help), which a base at the preset's levels lacks.
    assert transfer.combined_cell(base, "realistic").config.perturbations == (
        perturbations.preset("realistic")
    )
    preset_base = dataclasses.replace(base, perturbations=perturbations.preset("realistic"))
    assert transfer.combined_cell(preset_base, "realistic") is None
    assert transfer.combined_cell(base, None) is None
    assert (transfer.SCALES["default"].trials, quick.trials) == (10, 3)


def test_ray_tasks_report_each_outcome_and_a_failure_in_one_line(local_ray):
    from imitation import raytasks

    def _square(x):  # defined here, so Ray sends it by value (workers cannot import tests)
        if x < 0:
            raise ValueError(f"negative: {x}")
        return x * x

    outcomes = {
        o.key: o
        for o in raytasks.run_tasks(
            _square, {"a": (2,), "b": (-1,), "c": (3,)}, workers=1, progress=False
        )
    }
    assert (outcomes["a"].value, outcomes["c"].value) == (4, 9)
    assert outcomes["b"].value is None and outcomes["b"].error == "ValueError: negative: -1"
    with pytest.raises(ValueError, match="workers must be at least 1"):
        next(raytasks.run_tasks(_square, {}, workers=0))


def test_several_runs_give_the_envelope_over_seeds_and_resume(
    trained_run, other_seed_run, tmp_path, local_ray
):
    out = tmp_path / "seeds"
    argv = ["transfer", "--reuse-from", str(trained_run), str(other_seed_run), "--out", str(out)]
    argv += ["--families", "latency", "--levels", "0,3", "--trials", "1"]
    argv += ["--vision-test-steps", "50", "--workers", "2"]
    assert main(argv) == 0
    runs = [
        json.loads((out / r.name / "transfer.json").read_text())
        for r in (trained_run, other_seed_run)
    ]
    summary = json.loads((out / "transfer.json").read_text())
    assert list(summary["runs"]) == [trained_run.name, other_seed_run.name]
    for i, level in enumerate(summary["families"]["latency"]["levels"]):
        mine = [r["families"]["latency"]["levels"][i] for r in runs]
        for policy in ("student", "teacher"):
            for word in ("go", "pick", "lift"):
                rates = [m["performance"][policy][word] for m in mine]
                assert level["performance"][policy][word] == pytest.approx(sum(rates) / 2)
                assert level["worst_performance"][policy][word] == min(rates)
                assert level["trials"][policy][word] == 2  # pooled: one a run
        rates = [m["recognition"]["paper"]["go"] for m in mine]  # 50 steps: 'go' only
        assert level["worst_recognition"]["paper"]["go"] == min(rates)
        assert level["recognition"]["paper"]["go"] == pytest.approx(sum(rates) / 2)
    text = (out / "transfer.md").read_text()
    assert "Transfer over 2 runs" in text and "of the worst run" in text
    rates = [r["combined"]["performance"]["teacher"]["go"] for r in runs]
    assert summary["combined"]["performance"]["teacher"]["go"] == pytest.approx(sum(rates) / 2)
    assert summary["combined"]["worst_performance"]["teacher"]["go"] == min(rates)
    assert "Every family at once" in text
    assert (out / "figures" / "latency.png").stat().st_size > 10_000

    # A rerun keeps every run's finished cells.
    before = _numbers(out / "transfer.json")
    kept = out / other_seed_run.name / "cells" / "latency-3" / "performance_trials.json"
    mtime = kept.stat().st_mtime_ns
    assert main(argv) == 0
    assert kept.stat().st_mtime_ns == mtime and _numbers(out / "transfer.json") == before


def test_the_envelope_over_runs_is_of_their_mean_and_of_the_worst_run():
    def run(go_rates):
        levels = [{}, {"perception.latency_ms": 50}, {"perception.latency_ms": 200}]
        return {
            "source": "run",
            "vision": "truth",
            "randomisation": None,
            "policies": ["teacher"],
            "base_perturbations": {},
            "trials_per_row": 10,
            "recognition_steps": 600,
            "cpu_seconds": 1.0,
            "families": {
                "latency": {
                    "levels": [
                        {
                            "index": i,
                            "label": transfer.level_label(level),
                            "settings": level,
                            "performance": {"teacher": {"go": rate}},
                            "recognition": {"paper": {"go": 0.5}},
                            "trials": {"teacher": {"go": 10}},
                            "seen_fraction": 1.0,
                        }
                        for i, (level, rate) in enumerate(zip(levels, go_rates, strict=True))
                    ]
                }
            },
        }

    combined = transfer_runs.combine({"a": run([1.0, 1.0, 0.9]), "b": run([1.0, 0.7, 0.7])})
    latency = combined["families"]["latency"]
    assert [lv["performance"]["teacher"]["go"] for lv in latency["levels"]] == pytest.approx(
        [1.0, 0.85, 0.8]
    )
    assert latency["envelope"]["teacher"]["go"] == "latency_ms=200"  # the mean holds 80%
    assert latency["worst_envelope"]["teacher"]["go"] == "0"  # run b falls below at 50 ms
    assert "latency_ms=200 (0)" in transfer_runs.markdown(combined)
    other = run([1.0, 1.0, 1.0])
    other["trials_per_row"] = 3
    with pytest.raises(ValueError, match="differ in trials_per_row"):
        transfer_runs.combine({"a": run([1.0, 1.0, 1.0]), "b": other})


def test_several_runs_must_differ_by_seed_only(
    trained_run, randomised_run, other_seed_run, tmp_path, capsys
):
    argv = ["transfer", "--reuse-from", str(trained_run), str(randomised_run)]
    assert main([*argv, "--out", str(tmp_path / "t")]) == 2
    assert "randomisation.families" in capsys.readouterr().err
    argv = ["transfer", "--reuse-from", str(trained_run), str(other_seed_run)]
    assert main([*argv, "--compare", str(randomised_run), "--out", str(tmp_path / "t")]) == 2
    assert "--compare takes one --reuse-from run, got 2" in capsys.readouterr().err
    for parent in ("a", "b"):
        (tmp_path / parent / "run").mkdir(parents=True)
    with pytest.raises(ValueError, match="two runs in folders called 'run'"):
        transfer_runs.expand_sources([tmp_path / "a" / "run", tmp_path / "b" / "run"])
    sweep = tmp_path / "sweep"
    for cell in ("seed2", "seed1"):
        (sweep / "cells" / cell).mkdir(parents=True)
        (sweep / "cells" / cell / "state.json").write_text("{}")
    (sweep / "sweep.json").write_text("{}")
    assert [p.name for p in transfer_runs.expand_sources([sweep])] == ["seed1", "seed2"]
