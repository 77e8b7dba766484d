"""A run folder's bookkeeping: which stages are done and what they wrote, so an interrupted run resumes
and a folder's numbers always belong to the settings it names.

``state.json`` holds the run's configuration, the package version that made it, and per finished
stage its results and the content hash of every file it wrote; a checksum over the whole guards it.
A folder is used by one process at a time (``run.lock``, held while a run is alive).
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import pathlib
import shutil

from imitation import storage
from imitation.results import package_versions

#: What a run writes into its folder (``--fresh`` removes exactly these before starting over).
RUN_FILES = (
    "state.json",
    "config.toml",
    "results.json",
    "results.md",
    "network.npz",
    "hierarchical.npz",
    "recognised_test.npy",
    "performance_trials.json",
    "fig4_traces.npz",
    "index.html",
    # The videos and their logs (imitation.videos): every policy and word, and side by side.
    *(
        f"{policy}_{word}.{ext}"
        for policy in ("teacher", "student", "student_hierarchical")
        for word in ("go", "pick", "lift")
        for ext in ("mp4", "mcap")
    ),
    *(f"side_by_side_{word}.mp4" for word in ("go", "pick", "lift")),
)
RUN_FOLDERS = ("streams", "figures")
#: Settings that change how a run is carried out but not its results: a folder resumes with others.
RUNTIME_SETTINGS = ("workers",)
_FORMAT = "peoplebot-run"


class RunState:
    """The state of one run folder, locked for this process while it lives.

    Args:
      folder: the run folder (created if missing).
      config: the run's configuration as plain JSON values; a folder holding another configuration,
        or made by another version of the package, is refused (start a fresh folder, or pass
        ``fresh``).
      fresh: remove everything an earlier run wrote into the folder first.
      defaults: the configuration's default values; a setting the saved configuration lacks
        counts as its default there (a setting added later within the same version, which
        defaults to the behaviour before it). None: every setting must be saved.
    """

    def __init__(self, folder, config: dict, fresh: bool = False, defaults: dict | None = None):
        config = json.loads(json.dumps(config))  # as it will read back: tuples become lists
        self._defaults = None if defaults is None else json.loads(json.dumps(defaults))
        self.folder = pathlib.Path(folder)
        if self.folder.exists() and not self.folder.is_dir():
            raise ValueError(f"--out {self.folder} is a file, not a folder; choose a folder")
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            self._lock = _lock(self.folder / "run.lock")
        except PermissionError:
            raise ValueError(
                f"cannot write into {self.folder} (permission denied); choose another --out"
            ) from None
        self.path = self.folder / "state.json"
        self.version = package_versions()["peoplebot-imitation"]
        try:
            if fresh:
                clear(self.folder)
            if self.path.exists():
                self.data = self._read(config)
            else:
                self.data = {
                    "format": _FORMAT,
                    "version": self.version,
                    "config": config,
                    "stages": {},
                    "artifacts": {},
                    "seconds": {},
                }
                self._write()
        except BaseException:
            self.close()
            raise

    def _read(self, config: dict) -> dict:
        fix = f"pass --fresh to start {self.folder} over, or choose another --out"
        try:
            saved = json.loads(self.path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as error:
            raise ValueError(f"{self.path} is corrupt ({error}); {fix}") from None
        if not isinstance(saved, dict) or saved.get("format") != _FORMAT:
            raise ValueError(f"{self.path} is not a run state of this package; {fix}")
        checksum = saved.pop("checksum", None)
        keys = {"version", "config", "stages", "artifacts", "seconds"}
        if checksum != _checksum(saved) or not keys <= set(saved):
            raise ValueError(f"{self.path} is corrupt (its checksum does not match); {fix}")
        if saved["version"] != self.version:
            raise ValueError(
                f"{self.folder} was made by peoplebot-imitation {saved['version']}, this is "
                f"{self.version}; {fix}"
            )
        made = saved["config"]
        if self._defaults is not None:
            made = with_defaults(made, self._defaults)
        if _identity(made) != _identity(config):
            changed = differing_keys(_identity(made), _identity(config))
            raise ValueError(
                f"{self.folder} holds a run with other settings ({', '.join(changed)}); use "
                "another --out folder or --fresh to start over"
            )
        saved["config"] = config
        return saved

    def done(self, stage: str) -> bool:
        """Returns whether ``stage`` has finished."""
        return stage in self.data["stages"]

    def result(self, stage: str):
        """Returns the saved result of a finished stage."""
        return self.data["stages"][stage]

    def finish(self, stage: str, result, files=(), seconds: float = 0.0) -> None:
        """Records ``stage`` as finished with its (JSON-able) result, the files it wrote (paths in
        the folder; their content hashes are kept) and its wall-clock seconds. A stage run again
        by ``replace`` that wrote other files or another result makes the stages after it run
        again too."""
        self.data["stages"][stage] = json.loads(json.dumps(result))
        self.data["artifacts"][stage] = {
            _relative(path, self.folder): storage.file_digest(path) for path in files
        }
        self.data["seconds"][stage] = float(seconds)
        earlier = self.data.get("replaced", {}).pop(stage, None)
        if earlier is not None and (
            earlier["result"] != self.data["stages"][stage]
            or earlier["artifacts"] != self.data["artifacts"][stage]
        ):
            later = [s for s in earlier["later"] if self.done(s)]
            if later:
                print(
                    f"[{stage}] its new files differ from the earlier ones: {', '.join(later)} "
                    "run again"
                )
            self.forget(earlier["later"])  # writes the state
            return
        self._write()

    def intact(self, stage: str) -> bool:
        """Returns whether every file a finished stage wrote is still there, unchanged."""
        for name, digest in self.data["artifacts"].get(stage, {}).items():
            path = self.folder / name
            if not path.is_file() or storage.file_digest(path) != digest:
                return False
        return True

    def forget(self, stages) -> None:
        """Marks ``stages`` as not done (they run again)."""
        for stage in stages:
            for key in ("stages", "artifacts", "seconds", "replaced"):
                self.data.get(key, {}).pop(stage, None)
        self._write()

    def replace(self, stage: str, later) -> None:
        """Marks ``stage`` as not done, keeping its record: the stages ``later`` (which read its
        files) stay finished if its rerun writes the same files and result (the run is
        deterministic), and run again otherwise (see ``finish``)."""
        record = {
            "result": self.data["stages"][stage],
            "artifacts": self.data["artifacts"].get(stage, {}),
            "later": list(later),
        }
        for key in ("stages", "artifacts", "seconds"):
            self.data[key].pop(stage, None)
        self.data.setdefault("replaced", {})[stage] = record
        self._write()

    def replacing(self, stage: str) -> bool:
        """Returns whether ``stage`` is to run again with its earlier record kept (``replace``)."""
        return stage in self.data.get("replaced", {})

    def _write(self) -> None:
        payload = dict(self.data)
        payload["checksum"] = _checksum(self.data)
        storage.write_json(self.path, payload)

    def close(self) -> None:
        """Releases the folder's lock."""
        if self._lock is not None:
            os.close(self._lock)
            self._lock = None


def clear(folder: pathlib.Path) -> None:
    """Removes everything a run writes from ``folder`` (its lock and unrelated files stay)."""
    for name in RUN_FILES:
        (folder / name).unlink(missing_ok=True)
    for name in RUN_FOLDERS:
        shutil.rmtree(folder / name, ignore_errors=True)
    for path in folder.glob(".*.tmp*"):
        path.unlink(missing_ok=True)
    for path in folder.glob(".*.progress"):
        path.unlink(missing_ok=True)


def _lock(path: pathlib.Path) -> int:
    """Takes the run folder's lock (an exclusive ``flock``, released when the process ends);
    raises ValueError naming the process that holds it."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "another process"
        os.close(fd)
        raise ValueError(
            f"{path.parent} is in use by a running peoplebot process (pid {holder}); wait for it "
            "to finish or choose another --out"
        ) from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, str(os.getpid()).encode(), 0)
    return fd


def _identity(config: dict) -> dict:
    """Returns the settings that decide a run's results (the configuration less the runtime ones)."""
    return {k: v for k, v in config.items() if k not in RUNTIME_SETTINGS}


def _checksum(data: dict) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()


def _relative(path, folder: pathlib.Path) -> str:
    return str(pathlib.Path(path).resolve().relative_to(folder.resolve()))


def with_defaults(config: dict, defaults: dict) -> dict:
    """Returns ``config`` with the keys it lacks (at any depth) taken from ``defaults``."""
    out = dict(config)
    for key, value in defaults.items():
        if key not in out:
            out[key] = value
        elif isinstance(out[key], dict) and isinstance(value, dict):
            out[key] = with_defaults(out[key], value)
    return out


def differing_keys(a: dict, b: dict, prefix: str = "") -> list[str]:
    """Returns the dotted keys whose values differ between two nested dicts, sorted."""
    out = []
    for key in sorted(set(a) | set(b)):
        name = f"{prefix}{key}"
        x, y = a.get(key), b.get(key)
        if isinstance(x, dict) and isinstance(y, dict):
            out += differing_keys(x, y, f"{name}.")
        elif x != y:
            out.append(name)
    return out
