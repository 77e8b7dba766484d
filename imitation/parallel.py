"""Parallel stages: work split over spawned processes, with one progress bar fed by files.

Workers die with their parent: a killed run leaves no worker writing into its folder.
"""

from __future__ import annotations

import concurrent.futures
import ctypes
import ctypes.util
import multiprocessing
import os
import pathlib
import signal
import sys
import threading
import time

from tqdm import tqdm


def poll(futures: list, progress_files: list, total: int, desc: str) -> list:
    """Shows a progress bar of the counts the workers write into ``progress_files`` until every
    future is done; returns their results in order."""
    bar = tqdm(total=total, desc=desc, unit="step")
    while not all(f.done() for f in futures):
        done = 0
        for path in progress_files:
            try:
                done += int(pathlib.Path(path).read_text() or 0)
            except (FileNotFoundError, ValueError):
                pass
        bar.n = done
        bar.refresh()
        time.sleep(1.0)
    bar.n = total
    bar.close()
    return [f.result() for f in futures]


def run_parallel(fn, jobs: list, args: tuple, workers: int, folder, desc: str, total: int) -> list:
    """Runs ``fn(job, *args, progress_file)`` for every job in up to ``workers`` spawned processes
    (each job's worker writes its count of finished units into its progress file, inside
    ``folder``); returns the results in job order. With one worker the jobs run in this process,
    one after the other."""
    folder = pathlib.Path(folder)
    progress = [folder / f".{desc.replace(' ', '_')}.{i}.progress" for i in range(len(jobs))]
    if workers == 1:
        print(f"{desc}: {total} in this process")
        results = [fn(job, *args, str(p)) for job, p in zip(jobs, progress, strict=True)]
        for p in progress:
            p.unlink(missing_ok=True)
        return results
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(
        max_workers=workers,
        mp_context=context,
        initializer=die_with_parent,
        initargs=(os.getpid(),),
    ) as pool:
        futures = [
            pool.submit(fn, job, *args, str(p)) for job, p in zip(jobs, progress, strict=True)
        ]
        results = poll(futures, progress, total, desc)
    for p in progress:
        p.unlink(missing_ok=True)
    return results


#: Linux's prctl option that sends a signal to a process when its parent dies.
_PR_SET_PDEATHSIG = 1


def die_with_parent(parent_pid: int) -> None:
    """Makes this (worker) process end when ``parent_pid`` does: the kernel's parent-death signal
    where there is one (Linux), and a watcher thread everywhere (within 0.2 s)."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(0.2)
        os._exit(1)

    threading.Thread(target=watch, daemon=True, name="die-with-parent").start()
