"""Issue 37, item 10: a task that ends its local worker's process (a crash of a trial that is
not isolated) is one error of the tree, `WorkerDied`, not a `BrokenProcessPool` that the command
line would call a bug; `anytime verify --workers` and `anytime profile --workers` say it in one
line."""

from __future__ import annotations

import os

import pytest

from anytime.errors import AnytimeError
from anytime.pool import WorkerDied, spread


def _ends_on_three(task: int) -> int:
    if task == 3:
        os._exit(3)
    return task


def test_a_task_that_ends_its_worker_is_a_worker_died_error() -> None:
    with pytest.raises(WorkerDied) as caught:
        list(spread(_ends_on_three, list(range(8)), workers=2))
    assert isinstance(caught.value, AnytimeError)
    assert str(caught.value) == (
        "a worker process died: a task ended the process it ran in; the tasks that had not"
        " finished are lost"
    )
