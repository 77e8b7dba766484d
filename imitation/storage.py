"""Crash-safe files of a run folder: every write goes to a temporary name, is flushed and fsynced,
then renamed over the final name (and the folder fsynced), so a file is either whole or absent.

``file_digest`` gives a file's content hash, which the run state records to check artifacts by
content. For fault-injection tests, ``PEOPLEBOT_KILL_AT_WRITE=N`` makes the process group kill
itself with SIGKILL at the N-th write event of the process: each write has two events, after its
temporary file is written and after the rename.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import pathlib
import shutil
import signal

import numpy as np

KILL_ENV = "PEOPLEBOT_KILL_AT_WRITE"
_events = 0


def _event() -> None:
    """Counts a write event; SIGKILLs the process group at the one ``PEOPLEBOT_KILL_AT_WRITE``
    names (a crash at an exact point, for tests)."""
    global _events
    _events += 1
    target = os.environ.get(KILL_ENV)
    if target and _events == int(target):
        os.killpg(os.getpgrp(), signal.SIGKILL)


def write_bytes(path, data: bytes) -> pathlib.Path:
    """Writes ``data`` to ``path`` atomically and durably; returns the path."""
    path = pathlib.Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "wb") as handle:
        handle.write(data)
    return commit(tmp, path)


def write_text(path, text: str) -> pathlib.Path:
    """Writes ``text`` (UTF-8) to ``path`` atomically and durably."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path, data) -> pathlib.Path:
    """Writes ``data`` as indented JSON to ``path`` atomically and durably."""
    return write_text(path, json.dumps(data, indent=2))


def save_npz(path, compressed: bool = False, **arrays) -> pathlib.Path:
    """Writes arrays as an ``.npz`` archive to ``path`` atomically and durably."""
    buffer = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buffer, **arrays)
    return write_bytes(path, buffer.getvalue())


def save_npy(path, array) -> pathlib.Path:
    """Writes one array as ``.npy`` to ``path`` atomically and durably."""
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=False)
    return write_bytes(path, buffer.getvalue())


def commit(tmp, path) -> pathlib.Path:
    """Makes the file written at ``tmp`` (by us, or by another library: a video, a figure) durable
    and renames it over ``path``, then makes the rename durable."""
    tmp, path = pathlib.Path(tmp), pathlib.Path(path)
    with open(tmp, "rb+") as handle:
        os.fsync(handle.fileno())
    _event()
    os.replace(tmp, path)
    _fsync_folder(path.parent)
    _event()
    return path


def link(source, path) -> pathlib.Path:
    """Puts the (never modified in place) file ``source`` at ``path`` too: a hard link where the
    file system allows, else a copy; crash-safe either way."""
    source, path = pathlib.Path(source), pathlib.Path(path)
    tmp = temporary_name(path)
    tmp.unlink(missing_ok=True)
    try:
        os.link(source, tmp)
    except OSError:
        shutil.copyfile(source, tmp)
    return commit(tmp, path)


def temporary_name(path) -> pathlib.Path:
    """Returns the temporary name ``write_bytes`` uses for ``path`` (for writers that need a file
    name, followed by ``commit``)."""
    path = pathlib.Path(path)
    return path.with_name(f".{path.name}.tmp{path.suffix}")


def file_digest(path) -> str:
    """Returns the SHA-256 of a file's content, hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _fsync_folder(folder: pathlib.Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # pragma: no cover (a platform without directory handles)
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
