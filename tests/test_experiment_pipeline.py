"""``peoplebot reproduce`` end to end at a tiny scale (``imitation.reproduce``): every artefact
is produced and parseable, an interrupted run resumes to the same results, a run folder refuses
other settings, and the CLI maps its options onto the same run. Not the scientific numbers.

The shared run (about 15-25 s on 2 cores): 3,000 training and 2,000 test steps, one trial per row
and policy of 6 s, 320 x 240 videos of 6 s.
"""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import copy
import hashlib
import json
import os
import shutil

import imageio.v2 as imageio
import numpy as np
import pytest

from associator import persistence
from imitation import config as run_config
from imitation import performance, reproduce, trials, videos
from imitation.cli import main
from imitation.config import RunConfig
from imitation.reproduce import STAGES
from imitation.results import SCHEMA_VERSION, TrialRecord
from imitation.runstate import RunState
from imitation.streams import TeacherStream

WORDS = ("go", "pick", "lift")
TINY = {
    "learning.train_steps": 3000,
    "learning.test_steps": 2000,
    "vision.test_steps": 50,
    "performance.trials": 1,
    "performance.trial_seconds": 6.0,
    "workers": 2,
    "videos.mcap": True,
}
#: The same settings as command-line options (videos at quick's default 320 x 240).
TINY_CLI = [
    "--quick",
    "--train-steps",
    "3000",
    "--test-steps",
    "2000",
    "--vision-test-steps",
    "50",
    "--trials",
    "1",
    "--trial-seconds",
    "6",
    "--workers",
    "2",
    "--mcap",
]
FRAMES = 60  # trial_seconds / 0.1 s


def tiny_config(**overrides) -> RunConfig:
    """Returns the tiny run's configuration with dotted keys changed."""
    return RunConfig.quick().replace({**TINY, **overrides})


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    """Returns ``(folder, results)`` of one uninterrupted tiny run."""
    folder = tmp_path_factory.mktemp("reproduce") / "run"
    results = reproduce.run(tiny_config(), folder)
    return folder, results.to_json()


def comparable(results: dict) -> dict:
    """Returns the results without what legitimately differs between runs: wall-clock timings,
    package versions and the teacher reference rows (see
    ``test_teacher_reference_trials_are_seeded``)."""
    out = copy.deepcopy(results)
    for key in ("seconds_per_stage", "total_seconds", "versions"):
        out.pop(key)
    out["performance"].pop("teacher_reference")
    return out


# ------------------------------------------------------------------------------ artefacts
def test_run_returns_what_results_json_holds(run_folder):
    folder, results = run_folder
    assert json.loads((folder / "results.json").read_text()) == results
    assert results["schema_version"] == SCHEMA_VERSION


def test_config_toml_makes_the_same_run_again(run_folder, tmp_path, capsys):
    """The run folder's config.toml reads back as the run's configuration, and ``--config`` with
    it finds the finished run's settings in a copy of its folder (every stage kept)."""
    folder, reference = run_folder
    assert run_config.load(folder / "config.toml") == tiny_config()
    copy_folder = tmp_path / "copy"
    shutil.copytree(folder, copy_folder)
    assert (
        main(["reproduce", "--config", str(folder / "config.toml"), "--out", str(copy_folder)]) == 0
    )
    out = capsys.readouterr().out
    for stage in STAGES:
        assert f"[{stage}] done earlier, kept" in out
    assert comparable(json.loads((copy_folder / "results.json").read_text())) == comparable(
        reference
    )


def test_results_json_recognition(run_folder):
    folder, _ = run_folder
    results = json.loads((folder / "results.json").read_text())
    rec = results["recognition"]
    assert set(rec["confusion"]) == set(WORDS)
    for true in WORDS:
        row = rec["confusion"][true]
        assert set(row) == set(WORDS)
        assert all(0.0 <= v <= 1.0 for v in row.values())
        assert sum(row.values()) == pytest.approx(1.0)
        # Fractions and counts agree.
        counts = rec["counts_matrix"][true]
        assert sum(counts.values()) == rec["counts"][true]
        for recognised in WORDS:
            assert row[recognised] == pytest.approx(counts[recognised] / rec["counts"][true])
    assert sum(rec["counts"].values()) == TINY["learning.test_steps"]
    assert all(rec["counts"][w] > 0 for w in WORDS), "the test stream should show every word"
    assert rec["paper"]["counts"]["go"] == 746211
    # The recognised words saved beside the stream give the same table.
    recognised = np.load(folder / "recognised_test.npy")
    stream = TeacherStream.load(folder / "streams" / "test.npz")
    assert recognised.shape == (TINY["learning.test_steps"],)
    for i, true in enumerate(WORDS):
        for j, name in enumerate(WORDS):
            assert rec["counts_matrix"][true][name] == int(
                np.sum((stream.word == i) & (recognised == j))
            )


def test_results_json_performance_and_settings(run_folder):
    folder, _ = run_folder
    results = json.loads((folder / "results.json").read_text())
    perf = results["performance"]
    for row in ("go", "pick", "lift", "pick_other_wall"):
        assert perf[row]["trials"] == TINY["performance.trials"]
        assert 0.0 <= perf[row]["success_rate"] <= 1.0
        assert perf[row]["successes"] == round(perf[row]["success_rate"] * perf[row]["trials"])
    assert set(perf["teacher_reference"]) == set(WORDS)
    assert results["vision"] == "truth" and results["motor_source"] == "teacher"
    assert results["seed"] == 0
    assert results["config"] == tiny_config().to_dict()
    for name in ("python", "mujoco", "dm-control", "numpy"):
        assert isinstance(results["versions"][name], str), name
    assert set(results["seconds_per_stage"]) == set(STAGES)
    assert all(s > 0 for s in results["seconds_per_stage"].values())
    assert results["total_seconds"] == pytest.approx(sum(results["seconds_per_stage"].values()))
    assert results["learning"]["steps"] == TINY["learning.train_steps"]
    assert results["learning"]["hierarchical"]["steps"] == TINY["learning.train_steps"]
    for name in ("hierarchical", "hierarchical_over_time"):
        hierarchical = results["recognition"][name]
        for t in WORDS:
            assert sum(hierarchical["confusion"][t].values()) == pytest.approx(1.0), name
        assert hierarchical["counts"] == results["recognition"]["counts"], name
    for row in ("go", "pick", "lift", "pick_other_wall"):
        assert results["performance"]["hierarchical"][row]["trials"] == TINY["performance.trials"]
    assert {k: v["steps"] for k, v in results["streams"].items()} == {
        "train": TINY["learning.train_steps"],
        "test": TINY["learning.test_steps"],
    }


def test_performance_trials_follow_the_plan(run_folder):
    """One record per planned trial (paired starts; no teacher row for other walls), each lasting
    at most the trial length, ending where the record says."""
    folder, _ = run_folder
    records = [
        TrialRecord.from_json(r)
        for r in json.loads((folder / "performance_trials.json").read_text())
    ]
    plan = trials.trial_plan(tiny_config())
    key = lambda t: (t.row, t.policy, t.index)  # noqa: E731
    assert sorted(map(key, records)) == sorted(map(key, plan))
    # student, hierarchical student and teacher per row; no teacher row for other walls.
    assert len(plan) == len(performance.ROWS) * 3 - 1
    planned = {key(p): p for p in plan}
    for r in records:
        assert r.start == planned[key(r)].start
        assert r.wall == planned[key(r)].wall
        assert 0 < r.seconds <= TINY["performance.trial_seconds"] + 1e-9
        assert len(r.end_pose) == 3 and np.all(np.isfinite(r.end_pose))
        # In the truth mode every policy acts on its true pose: no own-pose error.
        assert r.own_pose_error_cm_median == 0.0, (r.policy, r.own_pose_error_cm_median)
        assert r.own_heading_error_deg_median == r.own_heading_error_deg_p95 == 0.0, r


def test_results_md_has_the_tables(run_folder):
    folder, results = run_folder
    text = (folder / "results.md").read_text()
    assert "Table I" in text
    assert "seed 0" in text and "vision: truth" in text
    for word in WORDS:
        assert f"| '{word}' |" in text
    # Our count and the paper's, side by side.
    assert f"{results['recognition']['counts']['go']} (746211)" in text
    assert "success rates" in text.lower()
    for stage in STAGES:
        assert f"| {stage} |" in text


def test_figures_are_valid_images(run_folder):
    folder, results = run_folder
    names = {"fig3", "fig4", "fig4_random", "fig5", "fig6", "fig7"}
    assert set(results["figures"]) == names
    for name, relative in results["figures"].items():
        path = folder / relative
        assert path.suffix == ".png" and path.name.startswith(name)
        image = imageio.imread(path)
        assert image.ndim == 3 and image.shape[2] in (3, 4), name
        assert min(image.shape[:2]) >= 100 and max(image.shape[:2]) >= 400, (name, image.shape)
        assert image.std() > 5, f"{name} should not be blank"


def test_fig4_traces(run_folder):
    """The paper's network's traces under their old keys, and every policy's from the paper's
    start and from the trials' first random starts (one per row here)."""
    folder, _ = run_folder
    with np.load(folder / "fig4_traces.npz") as traces:
        for word in WORDS:
            trace = traces[word]
            assert trace.shape == (FRAMES, 3) and np.all(np.isfinite(trace))
            np.testing.assert_allclose(trace[0, :2], performance.FIG4_START[:2], atol=0.05)
            assert traces[f"{word}_directives"].shape == (FRAMES,)
            for policy in videos.video_policies(tiny_config()):
                np.testing.assert_array_equal(
                    traces[f"fig4_{policy}_{word}"][0, :2].round(1), trace[0, :2].round(1)
                )
                assert traces[f"random_{policy}_{word}"].shape == (1, FRAMES, 3)
                assert traces[f"random_{policy}_{word}_success"].shape == (1,)
        np.testing.assert_array_equal(traces["fig4_student_go"], traces["go"])


def test_videos_have_their_size_rate_and_length(run_folder):
    """Every policy's video of every word and the side-by-side ones: 320 x 240 (side by side:
    one panel per policy), 20 frames/s (2x real time), one frame per control step and the held
    verdict; the side-by-side panels are the policies' own videos, frame for frame."""
    folder, results = run_folder
    policies = videos.video_policies(tiny_config())
    assert policies == ("teacher", "student", "student_hierarchical")
    expected = [videos.video_name(p, w) for p in policies for w in WORDS]
    expected += [videos.side_by_side_name(w) for w in WORDS]
    assert results["videos"] == sorted(expected)
    length = FRAMES + int(round(videos.HOLD_S / 0.1))
    for word in WORDS:
        own = {}
        for policy in policies:
            with imageio.get_reader(folder / videos.video_name(policy, word)) as reader:
                assert reader.get_meta_data()["fps"] == 20.0
                own[policy] = [frame for frame in reader]
            assert len(own[policy]) == length, (policy, word)
            assert own[policy][0].shape == (240, 320, 3)
            # The caption's clock changes from frame to frame.
            assert np.abs(own[policy][0].astype(int) - own[policy][-1]).mean() > 0.1
        with imageio.get_reader(folder / videos.side_by_side_name(word)) as reader:
            side = [frame for frame in reader]
        assert len(side) == length and side[0].shape == (240, 320 * len(policies), 3)
        for k, policy in enumerate(policies):
            panel = side[0][:, 320 * k : 320 * (k + 1)].astype(int)
            assert np.abs(panel - own[policy][0]).mean() < 6, (word, policy)


def test_every_video_starts_from_the_paper_start(run_folder):
    """The side-by-side panels come from the same start: every policy's run from the paper's
    start begins at ``FIG4_START``, and the verdict of each is recorded with its reason."""
    folder, _ = run_folder
    with np.load(folder / "fig4_traces.npz") as traces:
        for policy in videos.video_policies(tiny_config()):
            for word in WORDS:
                first = traces[f"fig4_{policy}_{word}"][0]
                np.testing.assert_allclose(first[:2], performance.FIG4_START[:2], atol=0.05)
    state = json.loads((folder / "state.json").read_text())
    verdicts = state["stages"]["videos"]["verdicts"]
    assert len(verdicts) == 9 and all(isinstance(v["reason"], str) for v in verdicts)


def test_student_episodes_are_logged_as_mcap(run_folder):
    """Beside each video, its episode as a ROS 2 log: one message per simulated step on the
    wheel command, odometry and camera topics."""
    from mcap.reader import make_reader

    folder, results = run_folder
    for word in WORDS:
        with open(folder / f"student_{word}.mcap", "rb") as handle:
            summary = make_reader(handle).get_summary()
        counts = {
            c.topic: summary.statistics.channel_message_counts[i]
            for i, c in summary.channels.items()
        }
        for topic in ("/cmd_vel", "/odom", "/camera/image/compressed", "/word"):
            assert counts[topic] == FRAMES, (word, topic)


def test_network_loads_with_its_training(run_folder):
    folder, results = run_folder
    model = persistence.load(folder / "network.npz")
    assert model.n_steps_ == TINY["learning.train_steps"]
    assert model.get_params()["n_steps_total"] == TINY["learning.train_steps"]
    assert np.all(np.isfinite(model.W_bu_)) and np.all(np.isfinite(model.W_td_))
    assert results["learning"]["params"]["hidden_shape"] == list(model.hidden_shape)


def test_streams_are_saved_whole(run_folder):
    folder, _ = run_folder
    for name, steps in (
        ("train", TINY["learning.train_steps"]),
        ("test", TINY["learning.test_steps"]),
    ):
        stream = TeacherStream.load(folder / "streams" / f"{name}.npz")
        assert len(stream) == steps
        assert np.all(np.isfinite(stream.pose_world))


def test_no_temporary_files_are_left(run_folder):
    folder, _ = run_folder
    leftovers = [
        p.name
        for p in folder.rglob("*")
        if "partial" in p.name
        or p.name.endswith(".progress")
        or ".part" in p.name
        or p.name.endswith(".state.json")
    ]
    assert leftovers == []


# ------------------------------------------------------------------------------ resume
class Interrupt(KeyboardInterrupt):
    """Simulated Ctrl-C."""


def test_interrupted_run_resumes_to_the_same_results(run_folder, tmp_path, monkeypatch):
    """Interrupted in the recognition stage, then run again: the finished stages are kept (not
    redone) and the results equal the uninterrupted run's."""
    reference_folder, reference = run_folder
    folder = tmp_path / "run"

    def interrupt(*args, **kwargs):
        raise Interrupt("simulated interruption")

    with monkeypatch.context() as patch:
        patch.setattr(reproduce, "stage_recognition", interrupt)
        with pytest.raises(Interrupt):
            reproduce.run(tiny_config(), folder)
    state = json.loads((folder / "state.json").read_text())
    assert set(state["stages"]) == {"streams", "learning"}
    assert not (folder / "results.json").exists()

    def redone(*args, **kwargs):
        raise AssertionError("a finished stage was run again")

    with monkeypatch.context() as patch:
        patch.setattr(reproduce, "stage_streams", redone)
        patch.setattr(reproduce, "stage_learning", redone)
        results = reproduce.run(tiny_config(), folder).to_json()
    assert comparable(results) == comparable(reference)
    assert set(results["seconds_per_stage"]) == set(STAGES)
    a, b = (persistence.load(f / "network.npz") for f in (folder, reference_folder))
    np.testing.assert_array_equal(a.W_bu_, b.W_bu_)
    np.testing.assert_array_equal(a.W_td_, b.W_td_)
    np.testing.assert_array_equal(
        np.load(folder / "recognised_test.npy"), np.load(reference_folder / "recognised_test.npy")
    )
    with (
        np.load(folder / "fig4_traces.npz") as x,
        np.load(reference_folder / "fig4_traces.npz") as y,
    ):
        for word in WORDS:
            np.testing.assert_array_equal(x[word], y[word])


def test_teacher_reference_trials_are_seeded(run_folder):
    """The teacher agent of a planned trial is built from the run's seed: two builds of the same
    trial's agent start in the same state (its turn jitter included), so the reference row is
    reproducible and resumes like the student's."""
    config = tiny_config()
    env = trials.student_environment(config)
    try:
        first = trials.make_agent(config, "teacher", "lift", env, None, None, rng=[0, 3, 1])
        second = trials.make_agent(config, "teacher", "lift", env, None, None, rng=[0, 3, 1])
        other = trials.make_agent(config, "teacher", "lift", env, None, None, rng=[0, 3, 2])
        assert first.controller.get_state() == second.controller.get_state()
        assert first.controller.get_state()["rng"] != other.controller.get_state()["rng"]
        with pytest.raises(ValueError, match="rng"):
            trials.make_agent(config, "teacher", "lift", env, None, None)
    finally:
        env.close()


def test_trial_plan_is_seeded_and_paired():
    config = tiny_config(**{"performance.trials": 3, "seed": 4})
    a, b = trials.trial_plan(config), trials.trial_plan(config)
    assert a == b
    assert trials.trial_plan(config.replace({"seed": 5})) != a
    for row in performance.ROWS:
        student = [p.start for p in a if p.row == row and p.policy == "student"]
        teacher = [p.start for p in a if p.row == row and p.policy == "teacher"]
        assert len(student) == 3
        assert teacher == ([] if row == "pick_other_wall" else student)


# ------------------------------------------------------------------------------ run folder state
def opened(folder, config: dict, fresh: bool = False) -> RunState:
    """Returns a run state read (or made) and closed again, or raises what opening it raised."""
    state = RunState(folder, config, fresh=fresh)
    state.close()
    return state


def test_run_state_refuses_other_settings_and_accepts_fresh(tmp_path):
    base = tiny_config().to_dict()
    state = RunState(tmp_path, base)
    state.finish("streams", {"steps": 1})
    state.close()
    other = tiny_config(**{"performance.trials": 2, "seed": 7}).to_dict()
    with pytest.raises(ValueError, match=r"other settings \(performance\.trials, seed\)"):
        opened(tmp_path, other)
    # Refusing leaves the folder's state alone.
    assert opened(tmp_path, base).done("streams")
    assert not opened(tmp_path, other, fresh=True).done("streams")
    assert opened(tmp_path, other).data["config"] == other


def test_run_state_refuses_a_corrupt_file(tmp_path):
    opened(tmp_path, {"seed": 0})
    path = tmp_path / "state.json"
    for text in ("{not json", "[]", path.read_text().replace('"seed": 0', '"seed": 1')):
        path.write_text(text)
        with pytest.raises(ValueError, match="state.json is (corrupt|not a run state)"):
            opened(tmp_path, {"seed": 0})
    assert opened(tmp_path, {"seed": 0}, fresh=True).data["stages"] == {}


def test_run_state_refuses_another_version(tmp_path):
    opened(tmp_path, {"seed": 0})
    path = tmp_path / "state.json"
    data = json.loads(path.read_text())
    data.pop("checksum")
    data["version"] = "0.0.1"
    data["checksum"] = hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="made by peoplebot-imitation 0.0.1"):
        opened(tmp_path, {"seed": 0})


def test_run_folder_is_used_by_one_process_at_a_time(tmp_path):
    first = RunState(tmp_path, {"seed": 0})
    with pytest.raises(
        ValueError, match=rf"in use by a running peoplebot process \(pid {os.getpid()}\)"
    ):
        RunState(tmp_path, {"seed": 0})
    first.close()
    opened(tmp_path, {"seed": 0})


def test_run_state_resumes_with_network_settings(tmp_path):
    """A run with associator settings (a tuple among them) resumes in its own folder."""
    changes = {"network.hidden_shape": (8, 24), "network.eta": 0.002}
    state = RunState(tmp_path, tiny_config(**changes).to_dict())
    state.finish("streams", {})
    state.close()
    assert opened(tmp_path, tiny_config(**changes).to_dict()).done("streams")


# ------------------------------------------------------------------------------ command line
def test_cli_maps_its_options_onto_the_same_run(run_folder, tmp_path, capsys):
    """``peoplebot reproduce --quick ... --out`` on a copy of the finished run finds its own
    settings (so it keeps every stage) and prints results.md."""
    folder, reference = run_folder
    copy_folder = tmp_path / "copy"
    shutil.copytree(folder, copy_folder)
    assert main(["reproduce", *TINY_CLI, "--out", str(copy_folder)]) == 0
    out = capsys.readouterr().out
    for stage in STAGES:
        assert f"[{stage}] done earlier, kept" in out
    assert "Table I" in out
    assert comparable(json.loads((copy_folder / "results.json").read_text())) == comparable(
        reference
    )


def test_cli_refuses_a_folder_with_other_settings(run_folder, capsys):
    folder, _ = run_folder
    before = (folder / "state.json").read_text()
    options = list(TINY_CLI)
    options[options.index("--trials") + 1] = "2"
    assert main(["reproduce", *options, "--out", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "trials" in err and "--fresh" in err
    assert (folder / "state.json").read_text() == before


# ------------------------------------------------------------------------------ reuse
def test_reuse_from_takes_the_networks_for_a_camera_run(run_folder, tmp_path):
    """``reuse_from`` copies the finished run's streams and networks (no learning again) into a
    run watching through the overhead camera; its recognition has the camera rows and the same
    truth table. A source with a changed network is refused by name."""
    folder, reference = run_folder
    config = tiny_config(**{"vision.mode": "overhead", "videos.enabled": False})
    results = reproduce.run(config, tmp_path / "overhead", reuse_from=folder).to_json()
    assert results["learning"]["reused_from"] == str(folder)
    assert results["recognition"]["confusion"] == reference["recognition"]["confusion"]
    camera = results["recognition"]["vision"]
    assert camera["steps"] == TINY["vision.test_steps"] and camera["seen_fraction"] > 0.5
    assert camera["teacher_position_error_cm"]["median"] < 5.0
    assert (
        "Recognition through the overhead camera"
        in (tmp_path / "overhead" / "results.md").read_text()
    )
    # The students act on the tracker's estimate of their own pose: small errors, never none.
    records = json.loads((tmp_path / "overhead" / "performance_trials.json").read_text())
    for r in (TrialRecord.from_json(r) for r in records if r["policy"] != "teacher"):
        assert 0 < r.own_pose_error_cm_p95 < 5.0, r
        assert 0 < r.own_heading_error_deg_p95 < 5.0, r
    damaged = tmp_path / "damaged"
    shutil.copytree(folder, damaged)
    (damaged / "network.npz").write_bytes((damaged / "network.npz").read_bytes()[:-9])
    with pytest.raises(ValueError, match="network.npz is missing or changed"):
        reproduce.run(config, tmp_path / "other", reuse_from=damaged)
    with pytest.raises(ValueError, match=r"other seed"):
        reproduce.run(config.replace({"seed": 3}), tmp_path / "third", reuse_from=folder)


def test_reuse_from_performs_on_the_same_network_with_other_read_out_settings(run_folder, tmp_path):
    """A run that differs from the source only in the hierarchical student's performing-only
    settings (``PERFORM_ONLY_PARAMS``) reuses its networks: the copy performs with the run's
    settings (saved in it and in results.json), its learnt arrays and recognition are the
    source's; a setting that changes learning is still refused by name."""
    folder, reference = run_folder
    assert reference["learning"]["hierarchical"]["params"]["pose_tail_dof"] == 10.0
    config = tiny_config(
        **{
            "hierarchical.pose_tail_dof": 0.0,
            "hierarchical.word_bias": 0.1,
            "videos.enabled": False,
        }
    )
    results = reproduce.run(config, tmp_path / "gaussian", reuse_from=folder).to_json()
    assert results["learning"]["reused_from"] == str(folder)
    params = results["learning"]["hierarchical"]["params"]
    assert params == {
        **reference["learning"]["hierarchical"]["params"],
        "pose_tail_dof": 0.0,
        "word_bias": 0.1,
    }
    copied = persistence.load(tmp_path / "gaussian" / "hierarchical.npz")
    assert (copied.pose_tail_dof, copied.word_bias) == (0.0, 0.1)
    assert persistence.load(folder / "hierarchical.npz").pose_tail_dof == 10.0
    with (
        np.load(folder / "hierarchical.npz") as source,
        np.load(tmp_path / "gaussian" / "hierarchical.npz") as copy_,
    ):
        assert set(source.files) == set(copy_.files)
        for name in source.files:
            if name != "hierarchy_params":
                np.testing.assert_array_equal(source[name], copy_[name], err_msg=name)
    assert results["recognition"]["confusion"] == reference["recognition"]["confusion"]
    # Resumed, the run keeps its copy as it is (its recorded digest).
    again = reproduce.run(config, tmp_path / "gaussian", reuse_from=folder).to_json()
    assert again["learning"] == results["learning"]
    with pytest.raises(ValueError, match=r"other hierarchical"):
        reproduce.run(
            tiny_config(**{"hierarchical.motor_gain": 2.0}), tmp_path / "gain", reuse_from=folder
        )


def test_the_run_page_loads_in_a_real_browser(run_folder, tmp_path):
    """``index.html`` in headless Chromium: every figure and video of the run loads, the results
    tables are there; a screenshot is saved (skipped where no Chromium is installed)."""
    import browser

    folder, results = run_folder
    browser.chromium()
    dom = browser.loaded_dom(folder / "index.html")
    states = browser.load_states(dom)
    assert set(states) == set(results["videos"]) | set(results["figures"].values())
    assert set(states.values()) == {"1"}, states
    assert dom.count("<table>") >= 5 and "Performance on instruction" in dom
    shot = imageio.imread(browser.screenshot(folder / "index.html", tmp_path / "index.png"))
    assert shot.std() > 5
