"""The Dask cluster that batches run on: a ``LocalCluster`` sized to the machine, or an existing scheduler
(``--scheduler tcp://host:8786``, e.g. one started by dask-jobqueue on SLURM or PBS). Shared by ``animbatch batch``
(:mod:`animbatch.farm.batch`) and class grading (:mod:`animbatch.teaching.classroom`)."""

from __future__ import annotations

import logging
import os
from typing import Any

#: Environment for worker processes: one software-rasteriser thread per worker.
WORKER_ENV = {"LP_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def connect(workers: int | None, scheduler: str | None) -> tuple[Any, Any]:
    """A Dask client: to ``scheduler`` when given, else to a new LocalCluster of ``workers`` single-threaded worker
    processes (default: one per core). Returns (client, cluster or None)."""
    from distributed import Client, LocalCluster  # optional and heavy: only for Dask batches

    if scheduler:
        return Client(scheduler), None
    # silence_logs: workers' own chatter (heartbeats cut off at shutdown) is not the user's business
    cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                           env=WORKER_ENV, dashboard_address=None, silence_logs=logging.CRITICAL)
    return Client(cluster), cluster
