"""Issue 37, item 12: no descendant of an isolated run outlives it, one that left the run's
process group included (`setsid()`, a session of its own, which the group's signals do not
reach): the child is the subreaper of its descendants, and the ones that left its group are
killed when it ends by itself and when the caller ends it. Each grandchild here would sleep
60 s; the tests wait at most 30 s for it to be gone (only a failure waits that long)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator

import pytest

from anytime.isolation import Channel, Child, processes
from anytime.modules import Context, Registry, Result, interruptible
from anytime.runtime import Budget, Isolated, Status, run

MODULES = Registry()


def _escape(channel: Channel | None, *, orphan: bool) -> None:
    """Start a grandchild in a session of its own that sleeps 60 s, and send its pid; with
    `orphan`, through a process that exits at once (the grandchild is then re-parented)."""
    read, write = os.pipe()
    if os.fork() == 0:
        if orphan and os.fork() != 0:
            os._exit(0)
        os.setsid()
        os.write(write, str(os.getpid()).encode())
        time.sleep(60)
        os._exit(0)
    os.close(write)
    pid = int(os.read(read, 64))
    if channel is not None:
        channel.send(pid)


def _alive(pid: int) -> bool:
    return any(p.pid == pid and p.state not in ("Z", "X") for p in processes())


def _gone(pid: int) -> bool:
    deadline = time.monotonic() + 30  # only a process that escaped waits this long
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.01)
    return not _alive(pid)


def _hangs(orphan: bool) -> Callable[[Channel], None]:
    def target(channel: Channel) -> None:
        _escape(channel, orphan=orphan)
        time.sleep(60)

    return target


def _returns(orphan: bool) -> Callable[[Channel], None]:
    return lambda channel: _escape(channel, orphan=orphan)


@pytest.mark.parametrize("orphan", [False, True], ids=["child", "orphan"])
@pytest.mark.parametrize("make", [_hangs, _returns], ids=["ended", "returns"])
def test_a_grandchild_in_a_session_of_its_own_is_ended_with_the_run(
    make: Callable[[bool], Callable[[Channel], None]], orphan: bool
) -> None:
    process = Child(make(orphan))
    try:
        messages: list[int] = []
        deadline = time.monotonic() + 30
        while not messages and time.monotonic() < deadline:
            messages = process.receive(0.05)
        assert len(messages) == 1
    finally:
        process.end()
    assert _gone(messages[0])


@interruptible("escapes", registry=MODULES, inputs=())
def escapes(ctx: Context) -> Iterator[Result]:
    read, write = os.pipe()
    if os.fork() == 0:
        os.setsid()
        os.write(write, str(os.getpid()).encode())
        time.sleep(60)
        os._exit(0)
    os.close(write)
    ctx.tick(1)
    yield Result(int(os.read(read, 64)), 0.5)


def test_an_isolated_run_leaves_no_process_in_another_session() -> None:
    module = MODULES.get("escapes")
    assert module is not None
    record = run(module, budget=Budget(10.0), mode=Isolated(60.0))
    assert record.status is Status.COMPLETED and record.result is not None
    assert _gone(record.result.value)
