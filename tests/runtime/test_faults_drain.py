"""Issue 37, item 5: the exit of an isolated child is judged on everything it sent. A message
that reaches the pipe after the child is seen gone (sent by a process it started, here, as the
child's last message may be still on its way) is read before the caller says it crashed; and
many isolated runs of a well-behaved module are never reported crashed."""

from __future__ import annotations

import os
import threading
import time
from collections import Counter
from collections.abc import Iterator

import pytest

from anytime.clocks import WallClock
from anytime.isolation import Channel, Child
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.runtime import Budget, Isolated, Status, run

MODULES = Registry()


def _sends_after_its_exit(channel: Channel) -> None:
    """The child exits at once; a process it started sends the message once it has gone."""
    child = os.getpid()
    if os.fork() == 0:
        while os.getppid() == child:  # until the child has exited (this one is reparented)
            time.sleep(0.001)
        time.sleep(0.02)  # and a little more: the caller has seen the exit by then
        channel.send("late")
        os._exit(0)


def test_a_message_that_comes_after_the_exit_is_read_before_the_exit_is_judged() -> None:
    process = Child(_sends_after_its_exit)
    try:
        deadline = time.monotonic() + 60  # only a hang reaches it
        while not process.gone and time.monotonic() < deadline:
            time.sleep(0.001)
        assert process.gone and process.exit_code == 0
        assert process.receive(0.0) == ["late"]
        assert process.receive(0.0) == []  # the pipe has ended: nothing waits
    finally:
        process.end()


@interruptible("well-behaved", registry=MODULES, inputs=())
def well_behaved(ctx: Context) -> Iterator[Result]:
    for i in range(1, 4):
        ctx.tick(1)
        yield Result(i, i / 10)


@contract("well-behaved-contract", registry=MODULES, inputs=())
def well_behaved_contract(ctx: Context) -> Result:
    ctx.tick(1)
    return Result(1, 0.5)


@pytest.mark.slow
@pytest.mark.parametrize("clock", [None, WallClock], ids=["work", "wall"])
def test_many_isolated_runs_of_a_well_behaved_module_never_crash(clock: type | None) -> None:
    """4 threads x 250 runs of each kind (the reported race: 2 in 2,000)."""
    seen: Counter[tuple[str, Status, str | None]] = Counter()
    lock = threading.Lock()

    def runs() -> None:
        for name in ("well-behaved", "well-behaved-contract"):
            module = MODULES.get(name)
            assert module is not None
            for _ in range(250):
                budget = Budget(10.0) if clock is None else Budget(10.0, clock=clock())
                record = run(module, budget=budget, mode=Isolated(60.0))
                with lock:
                    seen[(name, record.status, record.error)] += 1

    threads = [threading.Thread(target=runs) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert seen == {
        ("well-behaved", Status.COMPLETED, None): 1000,
        ("well-behaved-contract", Status.COMPLETED, None): 1000,
    }


def test_an_interrupt_during_the_fork_is_raised_once_the_child_is_set_up(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A Ctrl-C (here a SIGTERM, which the `anytime` command turns into one) that comes while a
    child is forked is held, not lost in an at-fork hook that Python ignores, then raised by the
    constructor, which ends the child first."""
    import signal

    from anytime.launch import Terminated, sigterm_interrupts

    forked: list[int] = []
    fork = os.fork

    def fork_under_a_signal() -> int:
        os.kill(os.getpid(), signal.SIGTERM)  # arrives now: held until the child is set up
        pid = fork()
        if pid:
            forked.append(pid)
        return pid

    monkeypatch.setattr(os, "fork", fork_under_a_signal)
    with sigterm_interrupts(), pytest.raises(Terminated):
        Child(lambda channel: time.sleep(30))
    (pid,) = forked
    with pytest.raises(ChildProcessError):  # ended and reaped
        os.waitpid(pid, os.WNOHANG)
