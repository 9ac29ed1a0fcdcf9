"""Issue 37, item 10: an executor whose workers cannot import the module's code (a Dask cluster
without the plugin installed, a module defined in a script) is one line that says so, not an
internal error."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future
from typing import Any

import pytest

from anytime.measure.builder import build_profile
from anytime.modules import Context, Registry, Result, interruptible
from anytime.problems import BuildError, Instance

LAB = Registry()


@interruptible("counter", inputs=[], registry=LAB)
def counter(ctx: Context) -> Iterator[Result]:
    for k in range(1, 3):
        ctx.tick()
        yield Result(k, k / 2)


class Unimportable(Executor):
    """Workers that fail to unpickle every task, as a Dask worker without the module does."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        future: Future[Any] = Future()
        future.set_exception(ModuleNotFoundError("No module named 'my_lab'"))
        return future


class Problems:
    def instance(self, rng: Any, qualities: Any) -> Instance:
        return Instance(args=(), reference=None)

    def score(self, instance: Instance, value: Any) -> float:
        return 1.0

    def __iter__(self) -> Iterator[Any]:  # pragma: no cover - not iterated
        return iter(())


def test_workers_that_cannot_import_the_module_are_one_clear_error() -> None:
    module = counter
    with pytest.raises(BuildError) as caught:
        build_profile(module, Problems(), time=[0, 1], trials=2, executor=Unimportable())
    assert str(caught.value) == (
        f"the executor's workers cannot import what the trials of '{module.name}' need"
        " (ModuleNotFoundError: No module named 'my_lab'): install its package where the"
        " workers run (a module defined in a script or notebook does not travel); no profile"
        " was made"
    )
