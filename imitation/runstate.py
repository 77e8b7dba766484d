"""A run folder's bookkeeping: which stages are done, so an interrupted run resumes.

``state.json`` holds the run's configuration and, per finished stage, its results. Writes go through
a temporary file and an atomic rename, so an interruption never leaves it half-written.
"""

from __future__ import annotations

import json
import os
import pathlib


class RunState:
    """The state file of one run folder.

    Args:
      folder: the run folder (created if missing).
      config: the run's configuration as plain JSON values; a folder holding another configuration
        is refused (start a fresh folder, or pass ``fresh``).
      fresh: forget any earlier state in the folder.
    """

    def __init__(self, folder, config: dict, fresh: bool = False):
        config = json.loads(json.dumps(config))  # as it will read back: tuples become lists
        self.folder = pathlib.Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.path = self.folder / "state.json"
        if self.path.exists() and not fresh:
            try:
                saved = json.loads(self.path.read_text())
            except json.JSONDecodeError as error:
                raise ValueError(
                    f"{self.path} is corrupt ({error}); delete it or pass --fresh"
                ) from None
            if saved.get("config") != config:
                changed = differing_keys(saved.get("config", {}), config)
                raise ValueError(
                    f"{self.folder} holds a run with other settings ({', '.join(changed)}); use "
                    "another --out folder or --fresh to start over"
                )
            self.data = saved
        else:
            self.data = {"config": config, "stages": {}}
            self._write()

    def done(self, stage: str) -> bool:
        """Returns whether ``stage`` has finished."""
        return stage in self.data["stages"]

    def result(self, stage: str):
        """Returns the saved result of a finished stage."""
        return self.data["stages"][stage]

    def finish(self, stage: str, result) -> None:
        """Records ``stage`` as finished with its (JSON-able) result."""
        self.data["stages"][stage] = result
        self._write()

    def _write(self) -> None:
        tmp = self.path.with_suffix(".json.partial")
        tmp.write_text(json.dumps(self.data, indent=2))
        os.replace(tmp, self.path)


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
