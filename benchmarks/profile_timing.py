"""How long measuring a plugin's profiles takes on 1 and 2 local workers and on a Dask cluster of
2 workers, and whether the three make the same profile (what bench_routing and bench_motion
print)."""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from tables import table

from anytime import AnytimeLibrary
from anytime.measure.builder import ProfileRequest, profile_module


def profile_times(trials: Mapping[str, int], problem_sets: Mapping[str, Any]) -> str:
    """The table: a row per module (`trials` trials per cell, measured on `problem_sets`)."""
    from dask.distributed import LocalCluster

    library = AnytimeLibrary.default()
    rows = []
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        for name, count in trials.items():
            entry = library.get(name)
            assert entry is not None and entry.module is not None
            requests = [
                ProfileRequest(trials=count, workers=1, quiet=True),
                ProfileRequest(trials=count, workers=2, quiet=True),
                ProfileRequest(trials=count, scheduler=cluster.scheduler_address, quiet=True),
            ]
            seconds, tables = [], []
            for request in requests:
                started = time.perf_counter()
                build = profile_module(entry.module, request, measurement=problem_sets[name])
                seconds.append(time.perf_counter() - started)
                tables.append(build.profile.probability)
            same = all(np.array_equal(tables[0], t) for t in tables[1:])
            cells = "x".join(str(n) for n in build.profile.cell_shape)
            rows.append(
                [
                    name,
                    f"{count} x {cells}",
                    *(f"{s:.1f}" for s in seconds),
                    *(f"{seconds[0] / s:.2f}" for s in seconds[1:]),
                    "yes" if same else "NO",
                ]
            )
    header = [
        "module",
        "trials x cells",
        "1 worker (s)",
        "2 workers (s)",
        "Dask, 2 workers (s)",
        "2 workers",
        "Dask",
        "same profile",
    ]
    return "**Measuring the profiles** (seconds, and speed-up over 1 worker):\n\n" + table(
        header, rows
    )
