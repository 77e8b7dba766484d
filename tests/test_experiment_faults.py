"""Run folders that never lie: a run killed with SIGKILL at many points resumes to the results of an
uninterrupted run; every file a run folder holds, truncated, emptied or with bytes flipped, is
either recovered by the rerun or refused in one line, and ``--fresh`` always recovers; ``--fresh``
after a run of other settings equals a clean run; workers die with their parent; every user mistake
is one line and exit status 2.

The runs here are tiny (1,500 training and 1,000 test steps, one 5 s trial per row and policy,
160 x 120 videos of 5 s), each in its own process group so that a kill takes its workers too.
"""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from associator import persistence
from imitation import storage
from imitation.cli import main
from imitation.streams import TeacherStream

TINY = [
    "reproduce",
    "--quick",
    "--train-steps",
    "1500",
    "--test-steps",
    "1000",
    "--trials",
    "1",
    "--trial-seconds",
    "5",
    "--workers",
    "1",
]
#: The tiny run's videos are smaller still (a config file sets them).
VIDEO_CONFIG = "[videos]\nwidth = 160\nheight = 120\n"


def run_cli(folder: pathlib.Path, *extra: str, kill_at: int | None = None, timeout=300):
    """Runs ``peoplebot`` on ``folder`` in a new process group; returns the finished process (its
    return code is -9 when the kill point was reached)."""
    env = {k: v for k, v in os.environ.items() if k != storage.KILL_ENV}
    if kill_at is not None:
        env[storage.KILL_ENV] = str(kill_at)
    config = folder.parent / f"{folder.name}.videos.toml"
    config.write_text(VIDEO_CONFIG)
    command = [sys.executable, "-m", "imitation.cli", *TINY, "--config", str(config)]
    return subprocess.run(
        [*command, "--out", str(folder), *extra],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        start_new_session=True,
    )


def comparable(folder: pathlib.Path) -> dict:
    """Returns everything a run folder's results say, without wall-clock timings and versions."""
    results = json.loads((folder / "results.json").read_text())
    for key in ("seconds_per_stage", "total_seconds", "versions"):
        results.pop(key)
    results["config"].pop("workers")  # how a run is carried out, not what it finds
    return results


def assert_same_run(folder: pathlib.Path, reference: pathlib.Path) -> None:
    """The results, trials, recognised words, streams, networks and figures of two run folders are
    the same (videos: the same frames count and first frame)."""
    assert comparable(folder) == comparable(reference)
    for name in ("performance_trials.json", "results.md"):
        a, b = (f / name for f in (folder, reference))
        if name == "results.md":  # its last table holds the timings
            assert a.read_text().split("## Time")[0] == b.read_text().split("## Time")[0]
        else:
            assert a.read_text() == b.read_text(), name
    np.testing.assert_array_equal(
        np.load(folder / "recognised_test.npy"), np.load(reference / "recognised_test.npy")
    )
    for name in ("train", "test"):
        a, b = (TeacherStream.load(f / "streams" / f"{name}.npz") for f in (folder, reference))
        np.testing.assert_array_equal(a.pose_world, b.pose_world)
        np.testing.assert_array_equal(a.directive, b.directive)
    for name in ("network.npz", "hierarchical.npz"):
        a, b = (persistence.load(f / name) for f in (folder, reference))
        np.testing.assert_array_equal(
            a.W_bu_ if hasattr(a, "W_bu_") else a.lower_.W_bu_,
            b.W_bu_ if hasattr(b, "W_bu_") else b.lower_.W_bu_,
        )
    with np.load(folder / "fig4_traces.npz") as a, np.load(reference / "fig4_traces.npz") as b:
        for key in b.files:
            np.testing.assert_array_equal(a[key], b[key])
    for png in sorted((reference / "figures").glob("*.png")):
        assert (folder / "figures" / png.name).read_bytes() == png.read_bytes(), png.name
    for video in sorted(reference.glob("student_*.mp4")):
        assert (folder / video.name).stat().st_size > 1000, video.name


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> pathlib.Path:
    """An uninterrupted tiny run."""
    folder = tmp_path_factory.mktemp("faults") / "reference"
    done = run_cli(folder)
    assert done.returncode == 0, done.stderr[-2000:]
    return folder


def test_a_run_killed_at_many_points_resumes_to_the_same_results(reference, tmp_path):
    """SIGKILL (of the whole process group, workers included) at write event 1 of the first
    attempt, 2 of the second, 3 of the third, ... (each process counts its own writes): inside
    every stage, between a temporary file and its rename and right after renames; every rerun
    resumes, and the last one ends with the uninterrupted run's results."""
    folder = tmp_path / "killed"
    kills = []
    point = 1
    for _ in range(60):
        done = run_cli(folder, "--workers", "2", kill_at=point)
        if done.returncode == 0:
            break
        assert done.returncode == -signal.SIGKILL, done.stderr[-2000:]
        state = (
            json.loads((folder / "state.json").read_text())
            if (folder / "state.json").exists()
            else {"stages": {}}
        )
        kills.append((point, tuple(state["stages"])))
        point += 1
    else:
        pytest.fail(f"the run never finished after {len(kills)} kills")
    print(f"kill points covered: {len(kills)}: {kills}")
    finished_before_kill = {stages for _, stages in kills}
    assert len(kills) >= 10 and len(finished_before_kill) >= 5, kills
    assert_same_run(folder, reference)
    leftovers = [p.name for p in folder.rglob("*") if ".tmp" in p.name or ".part" in p.name]
    assert leftovers == []


def _corruptions(path: pathlib.Path):
    data = path.read_bytes()
    flipped = bytearray(data)
    for i in range(len(data) // 3, len(data), max(1, len(data) // 7)):
        flipped[i] ^= 0xFF
    return {"truncated": data[: len(data) // 2], "emptied": b"", "flipped": bytes(flipped)}


def test_every_file_damaged_is_recovered_or_refused_in_one_line(reference, tmp_path, capsys):
    """Each file of a finished run folder (one video and one figure stand for the others: each
    damaged one reruns its whole stage) truncated, emptied or with bytes flipped, the three in turn from
    file to file, and ``state.json`` in all three ways: the rerun ends with the reference results,
    or stops with one line and exit status 2, and then ``--fresh`` recovers."""
    files = sorted(
        p.relative_to(reference)
        for p in reference.rglob("*")
        if p.is_file()
        and p.name != "run.lock"
        and (p.suffix != ".mp4" or p.name == "student_go.mp4")
        and (p.parent.name != "figures" or p.name == "fig3_word_codes.png")
    )
    assert len(files) >= 14, files
    modes = ("truncated", "emptied", "flipped")
    cases = [(name, modes[i % 3]) for i, name in enumerate(files)]
    cases += [(pathlib.Path("state.json"), mode) for mode in modes]
    cases = sorted(set(cases))
    outcomes = {}
    for i, (name, mode) in enumerate(cases):
        folder = tmp_path / f"case{i}"
        shutil.copytree(reference, folder)
        (folder / name).write_bytes(_corruptions(folder / name)[mode])
        config = tmp_path / "videos.toml"
        config.write_text(VIDEO_CONFIG)
        code = main([*TINY, "--config", str(config), "--out", str(folder)])
        err = capsys.readouterr().err.strip()
        if code == 0:
            assert_same_run(folder, reference)
            outcomes[f"{name} ({mode})"] = "recovered"
            shutil.rmtree(folder)
            continue
        else:
            errors = [line for line in err.splitlines() if line.startswith("peoplebot ")]
            assert code == 2 and len(errors) == 1 and "--fresh" in errors[0], (name, err)
            assert main([*TINY, "--config", str(config), "--out", str(folder), "--fresh"]) == 0
            assert_same_run(folder, reference)
            outcomes[f"{name} ({mode})"] = "refused in one line; --fresh recovered"
        shutil.rmtree(folder)
    print(f"damaged files: {len(outcomes)}: {json.dumps(outcomes, indent=1)}")
    assert len(outcomes) == len(cases) and {name for name, _ in cases} == set(files)
    assert sum(v == "recovered" for v in outcomes.values()) >= len(files) - 1, outcomes


def test_fresh_after_a_run_of_other_settings_equals_a_clean_run(reference, tmp_path):
    """``--fresh`` on a folder holding a run of another seed gives the clean run's results (nothing
    of the other run is reused), and without ``--fresh`` the folder is refused."""
    folder = tmp_path / "other"
    assert run_cli(folder, "--seed", "5").returncode == 0
    refused = run_cli(folder)
    assert refused.returncode == 2 and "other settings (seed)" in refused.stderr
    assert run_cli(folder, "--fresh").returncode == 0
    assert_same_run(folder, reference)


def test_workers_die_with_their_parent_and_the_folder_is_locked(tmp_path):
    """SIGKILL of the parent alone (not its group) during the streams stage: its pool workers end
    within seconds; while the parent lives, a second run on the folder is refused by name."""
    folder = tmp_path / "orphans"
    config = tmp_path / "videos.toml"
    config.write_text(VIDEO_CONFIG)
    command = [sys.executable, "-m", "imitation.cli", *TINY, "--config", str(config)]
    command[command.index("1500")] = "400000"  # a long streams stage, in two workers
    command[command.index("--workers") + 1] = "2"
    parent = subprocess.Popen(
        [*command, "--out", str(folder)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        workers = []
        for _ in range(200):
            workers = _children(parent.pid)
            if len(workers) >= 2 and (folder / "state.json").exists():
                break
            time.sleep(0.1)
        assert workers, "the streams stage started no workers"
        second = subprocess.run(
            [*command, "--out", str(folder)], capture_output=True, text=True, timeout=120
        )
        assert second.returncode == 2
        assert f"in use by a running peoplebot process (pid {parent.pid})" in second.stderr
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=10)
        deadline = time.monotonic() + 10
        while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(_alive(pid) for pid in workers), "a worker outlived its parent"
    finally:
        if parent.poll() is None:
            os.killpg(parent.pid, signal.SIGKILL)


def _children(pid: int) -> list[int]:
    out = []
    for stat in pathlib.Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["reproduce", "--trials", "0"], "--trials: must be a positive integer"),
        (["reproduce", "--vision", "sonar"], "--vision: invalid choice: 'sonar'"),
        (["reproduce", "--seed", "-1"], "seed must be an integer in [0, 2147483646]"),
        (["reproduce", "--seed", str(2**31)], "seed must be an integer in [0, 2147483646]"),
        (["reproduce", "--out", "{file}"], "is a file, not a folder"),
        (["reproduce", "--out", "{readonly}/run"], "permission denied"),
        (["reproduce", "--out", "{state_list}"], "state.json is not a run state"),
        (["reproduce", "--config", "{missing}"], "cannot read config"),
        (["reproduce", "--config", "{bad_config}"], "unknown config key 'learning.train_step'"),
        (["reproduce", "--reuse-from", "{file}"], "is not a run folder"),
        (["figures", "--network", "{npy}"], "not a valid associator file"),
        (["figures", "--network", "{missing}"], "not a valid associator file"),
        (["figures", "--network", "{bad_params}"], "not a valid associator file"),
        (["demo", "--seconds", "0.05"], "seconds must be at least one control step"),
        (["demo", "--seconds", "1e300"], "seconds must be at least one control step"),
        (["demo", "--width", "7"], "width must be an even number of pixels"),
    ],
)
def test_user_mistakes_are_one_line_and_exit_status_2(tmp_path, capsys, argv, fragment):
    if os.geteuid() == 0 and "{readonly}" in " ".join(argv):
        readonly = tmp_path / "readonly"
        readonly.write_text("a file where a folder should be")  # root ignores permissions
        fragment = "not a directory"
    else:
        readonly = tmp_path / "readonly"
        readonly.mkdir()
        readonly.chmod(0o500)
    (tmp_path / "file").write_text("not a folder")
    state_list = tmp_path / "state_list"
    state_list.mkdir()
    (state_list / "state.json").write_text("[]")
    np.save(tmp_path / "weights.npy", np.zeros(3))
    (tmp_path / "bad.toml").write_text("[learning]\ntrain_step = 3\n")
    bad_params = tmp_path / "bad_params.npz"
    np.savez(
        bad_params, format=np.array("associator"), format_version=np.array(1), params=np.array("{")
    )
    names = {
        "file": tmp_path / "file",
        "readonly": readonly,
        "state_list": state_list,
        "missing": tmp_path / "missing.toml",
        "bad_config": tmp_path / "bad.toml",
        "npy": tmp_path / "weights.npy",
        "bad_params": bad_params,
    }
    argv = [a.format(**names) for a in argv]
    try:
        if argv[0] == "reproduce":
            argv = [*argv, "--quick"] + (
                [] if "--out" in argv else ["--out", str(tmp_path / "run")]
            )
        code = main(argv)
    except SystemExit as error:  # argparse's own refusals
        code = error.code
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and fragment in err, err
