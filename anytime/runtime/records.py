"""What a run gives back: its `Status` and its `RunRecord`, and `RunInterrupted`, raised to
the caller of a run that a Ctrl-C ended, once the record is kept."""

from __future__ import annotations

from enum import StrEnum

from attrs import frozen

from anytime.modules import Result


class Status(StrEnum):
    """How a run ended."""

    COMPLETED = "completed"  # the module finished on its own, within its time
    INTERRUPTED = "interrupted"  # its allocation ran out, or it was stopped from outside
    CONTRACT_EXPIRED = "contract-expired"  # a contract module used more than its allocation
    FAILED = "failed"  # it raised, or broke the protocol (see `error`)
    NO_RESULT = "no-result"  # it ended without registering any result
    STOPPED = "stopped"  # its stopping policy stopped it (with its best result, if any)
    CRASHED = "crashed"  # its process died (isolation="process"): a signal, an exit, no memory


@frozen
class RunRecord:
    """What a run gives back.

    Attributes:
        module: the module's name.
        status: how the run ended.
        result: the best `Result` registered in time (highest quality, the later one on ties;
            the latest for an interruptible module that does not report its true quality),
            or None when there is none.
        time_used: time on the run's clock from start to the answer.
        allocation: the time the run was given.
        registered: how many results the module registered in time.
        error: for a failure, what went wrong, in one line.
        traceback: for a failure raised by the module, its traceback.
        looks: how many times its observer (a stopping policy) looked at the run.
        exit_code: for a crashed isolated run, how its process ended: its exit code, or the
            negated number of the signal that killed it (as `subprocess` reports it); None
            when it did not exit (it ran out of memory, or was not isolated).
    """

    module: str
    status: Status
    result: Result | None
    time_used: float
    allocation: float
    registered: int = 0
    error: str | None = None
    traceback: str | None = None
    looks: int = 0
    exit_code: int | None = None

    @property
    def quality(self) -> float:
        """The quality of the answer (0 when there is none)."""
        return self.result.quality if self.result is not None else 0.0


class RunInterrupted(KeyboardInterrupt):
    """A KeyboardInterrupt (Ctrl-C, or SIGTERM in the `anytime` command) during a run, raised
    to the caller once the run's record is kept: `record` has the best result registered
    before it, status `interrupted`. The interrupt that came is its `__cause__`."""

    def __init__(self, record: RunRecord) -> None:
        super().__init__(f"run of '{record.module}' interrupted")
        self.record = record

    def __reduce__(self) -> tuple[type[RunInterrupted], tuple[RunRecord]]:
        # Pickled with its record (a run in a child process reports it to its caller).
        return (type(self), (self.record,))
