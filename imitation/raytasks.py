"""Runs independent jobs as Ray tasks: the one scheduler of ``peoplebot sweep``'s and ``peoplebot
transfer``'s cells.

Ray runs on this machine by default (a local Ray started for the call and shut down after it), or
on an existing cluster: ``address``, else the ``RAY_ADDRESS`` environment variable. A task whose
worker process dies is retried by Ray (``MAX_RETRIES``); a task that raises is reported with its
root cause, not raised. Results come back to the driver through Ray, so the driver's folder holds
them even when the workers' disks are not shared.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Iterator

import ray
from tqdm import tqdm

#: Attempts Ray makes at a task whose worker process dies.
MAX_RETRIES = 3


@dataclasses.dataclass(frozen=True)
class TaskOutcome:
    """What became of one job: its key, and the function's return value or (when it raised or its
    worker kept dying) the root cause in one line."""

    key: str
    value: object = None
    error: str | None = None


def address_of(address: str | None) -> str | None:
    """Returns the cluster to join: ``address``, else ``RAY_ADDRESS``, else None (a local Ray)."""
    return address or os.environ.get("RAY_ADDRESS") or None


def run_tasks(
    function: Callable,
    jobs: dict,
    *,
    address: str | None = None,
    workers: int | None = None,
    cpus_per_task: int = 1,
    env: dict | None = None,
    progress: bool = True,
    description: str = "cells",
) -> Iterator[TaskOutcome]:
    """Runs ``function(*args)`` for every ``key -> args`` of ``jobs`` as a Ray task of
    ``cpus_per_task`` CPUs and yields each outcome as it finishes.

    ``workers``: jobs at once (a local Ray gets ``workers * cpus_per_task`` CPUs, default this
    machine's cores; on a cluster at most ``workers`` tasks are submitted at a time, default all);
    ``env``: environment variables set in the workers. Ray is started here unless the caller has
    already started it, and shut down after the last outcome."""
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers!r}")
    if cpus_per_task < 1:
        raise ValueError(f"cpus_per_task must be at least 1, got {cpus_per_task!r}")
    cluster = address_of(address)
    started_here = not ray.is_initialized()
    if started_here:
        options = {"include_dashboard": False, "log_to_driver": False}
        if env:
            options["runtime_env"] = {"env_vars": dict(env)}
        if cluster:
            ray.init(address=cluster, **options)
        else:
            # "local": a new Ray of our own, even where another runs on this machine (a bare
            # ray.init would join that one, whose CPUs cannot be set).
            cores = os.cpu_count() or 1
            ray.init(address="local", num_cpus=max(workers or cores, 1) * cpus_per_task, **options)
    try:
        task = ray.remote(num_cpus=cpus_per_task, max_retries=MAX_RETRIES)(function)
        waiting = list(jobs.items())
        limit = workers or len(waiting)
        running: dict = {}
        bar = tqdm(total=len(waiting), desc=description, unit="cell", disable=not progress)
        failed = 0
        while waiting or running:
            while waiting and len(running) < limit:
                key, args = waiting.pop(0)
                running[task.remote(*args)] = key
            done, _ = ray.wait(list(running), num_returns=1)
            key = running.pop(done[0])
            try:
                outcome = TaskOutcome(key, value=ray.get(done[0]))
            except Exception as error:  # noqa: BLE001 (a task's failure is reported, not raised)
                failed += 1
                outcome = TaskOutcome(key, error=root_cause(error))
            bar.update(1)
            bar.set_postfix(
                finished=bar.n - failed, running=len(running), failed=failed, refresh=True
            )
            yield outcome
        bar.close()
    finally:
        if started_here:
            ray.shutdown()


def root_cause(error: Exception) -> str:
    """Returns the root cause of a Ray task's failure in one line."""
    cause = getattr(error, "cause", None) or error
    return " ".join(f"{type(cause).__name__}: {cause}".split())[:2000]


def node_id() -> str | None:
    """Returns the Ray node this process runs on (None outside Ray)."""
    return ray.get_runtime_context().get_node_id() if ray.is_initialized() else None
