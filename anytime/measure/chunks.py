"""Measuring chunks of a build's trials: isolated (the default, mode `Isolated`) in a child
process that runs them in turn (`anytime.measure.isolated_trials`), else in the builder's
process (or worker), each trial's run soft or hard as the mode says."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from itertools import islice

import numpy as np

from anytime.measure.isolated_trials import isolated_outcomes
from anytime.measure.trials import Chunk, Done, Measured, measured, trial_of
from anytime.runtime.modes import Isolated


def measure_chunk(chunk: Chunk) -> Done:
    """Run one chunk of trials. Isolated (the default), they run in turn in a child process
    (see `isolated_outcomes`): a trial whose process dies, or that takes longer than the
    mode's watchdog, is a failed trial that keeps what its run had registered before, as
    `anytime.runtime.run` keeps it, and the next trials go on in a new process. Soft or hard,
    they run here, each trial's run in that mode."""
    return next(measure_chunks([chunk]))


def measure_chunks(chunks: Sequence[Chunk]) -> Iterator[Done]:
    """`measure_chunk` of each of `chunks` (of one build) in turn; isolated, one process runs
    them all (a process per chunk would cost a fork each)."""
    if not chunks:
        return
    first = chunks[0]
    flats = [flat for chunk in chunks for flat in range(chunk.start, chunk.stop)]
    outcomes: Iterator[Measured]
    if isinstance(first.mode, Isolated):
        outcomes = isolated_outcomes(first, flats, first.mode)
    else:
        outcomes = (measured(first, flat) for flat in flats)
    for chunk in chunks:
        yield chunk_done(chunk, islice(outcomes, chunk.stop - chunk.start))


def chunk_done(chunk: Chunk, outcomes: Iterator[Measured]) -> Done:
    """The chunk's measurements from its trials' outcomes (in trial order)."""
    grid = chunk.grid
    quality = np.zeros((chunk.stop - chunk.start, len(grid.time)))
    scored = np.zeros(quality.shape, dtype=np.bool_)  # no result until one is scored
    reported = np.zeros(quality.shape)
    finished = np.full(len(quality), float(grid.time[-1]))
    failures = overruns = 0
    step = 0.0
    first: tuple[int, str] | None = None
    reasons: dict[str, int] = {}
    flats = range(chunk.start, chunk.stop)
    for row, (flat, outcome) in enumerate(zip(flats, outcomes, strict=True)):
        quality[row], scored[row], reported[row] = outcome.row
        finished[row] = outcome.finished
        failed = outcome.failed
        overruns += outcome.overruns
        step = max(step, outcome.step)
        failures += len(failed)
        for headline, _ in failed:
            reasons[headline] = reasons.get(headline, 0) + 1
        if failed and first is None:
            headline, details = failed[0]
            first = (flat, f"{headline} ({trial_of(chunk, flat).where})\n{details}".rstrip())
    return Done(
        chunk.start, quality, failures, overruns, first, step, scored, reported, finished, reasons
    )
