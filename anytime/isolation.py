"""Child processes of their own: what `isolation="process"` runs a module in.

A `Child` is a fork of the caller that leads a process group of its own, so that whatever it
starts can be ended with it, and that a terminal's Ctrl-C reaches the caller, which then ends
it. The child sends messages (pickled, one at a time, as they come) to the caller over a pipe;
the caller reads them as they arrive, learns when the child has gone and how (its exit code, or
the signal that killed it), and ends it and everything it started: SIGTERM to the group, then
SIGKILL to what is left of it after a grace period.

Forking (not spawning a fresh interpreter) is what lets a module defined anywhere, a closure
or a lambda included, and arguments of any kind, run in the child without being pickled; only
what the child sends back must pickle. The cost is a fork per run (about a millisecond), and
what forking a threaded process always risks: a lock another thread of the caller held at the
fork stays held in the child.

This is POSIX-only (fork, process groups); on other systems `Child` refuses with `OSError`.
"""

from __future__ import annotations

import math
import os
import pickle
import select
import signal
import struct
import sys
import threading
import time
import traceback
from collections.abc import Callable, Generator, Iterator, Sequence
from contextlib import contextmanager, suppress
from functools import partial
from pathlib import Path
from typing import Any, Literal, NoReturn

from attrs import field, frozen

from anytime.errors import AnytimeError

Isolation = Literal["none", "process"]
ISOLATIONS: tuple[Isolation, ...] = ("none", "process")
#: Wall-clock seconds an isolated run (or trial) is given to answer by default, whatever its
#: own clock says.
WATCHDOG = 60.0
#: Seconds a child (and its group) is given to end after SIGTERM before SIGKILL.
GRACE = 0.05
#: Seconds a caller waits, once its child has gone, for the end of the pipe (every writer gone)
#: when no message is waiting: what the child sent is read before its exit is judged, also if
#: a process it started holds the pipe open for a moment.
DRAIN = 1.0
_HEADER = struct.Struct("<Q")  # the length of each pickled message
# Held from making a child's pipe until the caller has closed its write end: a child forked
# meanwhile by another thread would hold that end open, and its pipe would not end with it.
_FORKING = threading.Lock()
#: The signals that stop the caller (`counting_interrupts`), held while a child is forked.
_INTERRUPTS = (signal.SIGINT, signal.SIGTERM)


@contextmanager
def _holding_interrupts() -> Iterator[list[int]]:
    """While the block runs, a SIGINT or SIGTERM is noted in the list yielded instead of handled
    (in the main thread, where Python runs every handler; elsewhere nothing changes). The
    earlier handlers are put back after: the caller raises the signals noted."""
    held: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield held
        return
    earlier = {
        sig: signal.signal(sig, lambda signum, frame: held.append(signum)) for sig in _INTERRUPTS
    }
    try:
        yield held
    finally:
        for sig, handler in earlier.items():
            signal.signal(sig, handler)


def _deliver_held() -> None:
    """Nothing: a call of Python code, where Python raises what a signal's handler raises (a
    signal unblocked in C is only handled at such a point)."""


def _new_forking_lock() -> None:
    global _FORKING
    _FORKING = threading.Lock()  # a fork's copy may be held (by a thread it does not have)


os.register_at_fork(after_in_child=_new_forking_lock)
_SUPERVISOR_FAILED = 70  # the child's exit code when its target could not run (EX_SOFTWARE)


class IsolationError(AnytimeError, ValueError):
    """An isolation option is not usable; the message names it."""


def _limit(name: str) -> Callable[[Any, Any, float | None], None]:
    def check(_instance: Any, _attribute: Any, value: float | None) -> None:
        if value is None:
            return
        if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
            raise IsolationError(f"Limits: {name}: expected a positive number, got {value!r}")
        if math.isinf(value):
            raise IsolationError(f"Limits: {name}: expected a finite number, got {value!r}")

    return check


@frozen
class Limits:
    """Resource limits of an isolated run (POSIX rlimits, set in the child before it runs).

    Attributes:
        memory: bytes of address space the run may map beyond what its process had when it
            started (a fork of the caller, with everything the caller had mapped); past it,
            allocations fail (a `MemoryError` in Python: the record says `crashed`).
        cpu: CPU seconds the run may use; past them the kernel kills it (SIGXCPU).
    """

    memory: int | None = field(default=None, validator=_limit("memory"))
    cpu: float | None = field(default=None, validator=_limit("cpu"))


class Unsent(IsolationError):
    """A child's message did not pickle; sent in its place (and raised in the child), so that
    its end is reported so (`Child.unsent`), without a traceback on the caller's stderr."""


class Channel:
    """The child's end of the pipe: `send` one picklable message at a time."""

    def __init__(self, fd: int) -> None:
        self._fd = fd

    def send(self, message: Any) -> None:
        try:
            data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # the caller is told why instead (`Child.unsent`)
            unsent = Unsent(
                f"what its process answered does not pickle: {type(exc).__name__}: {exc}"
            )
            self.send(unsent)
            raise unsent from exc
        view = memoryview(_HEADER.pack(len(data)) + data)
        while view:
            view = view[os.write(self._fd, view) :]


class Child:
    """`target(channel)` run in a forked child process that leads its own process group.

    The child ends when `target` returns (exit code 0), or however the target makes it end.
    Read what it sends with `receive`; end it (and its group) with `end`, which every user of
    a `Child` must call, also when it has exited by itself (it reaps the child, and ends what
    the child started and left behind)."""

    def __init__(self, target: Callable[[Channel], None], limits: Limits | None = None) -> None:
        if not hasattr(os, "fork"):
            raise OSError("process isolation needs fork() and process groups (POSIX)")
        for stream in (sys.stdout, sys.stderr):  # else the child would print the caller's buffer
            with suppress(Exception):
                stream.flush()
        # A Ctrl-C during the fork would be raised in an at-fork hook (logging's), which Python
        # ignores: the caller would go on as if it had not come. Held until the child is set up,
        # then raised here, the child ended with it.
        with _holding_interrupts() as held:
            with _FORKING:
                read, write = os.pipe()
                parent = os.getpid()
                pid = os.fork()
                if pid == 0:  # the child: never returns into the caller's code
                    _run_child(target, limits, read, write, parent)
                with suppress(OSError):  # as the child does: whichever runs first makes the group
                    os.setpgid(pid, pid)
                os.close(write)
            os.set_blocking(read, False)
            self.pid = pid
            self.exit_code: int | None = None  # once it has gone: its exit code, or -signal
            self._read: int | None = read
            self._eof = False  # the pipe has ended: every process holding its write end is gone
            self._buffer = bytearray()
            self._reaped = False
            self._pidfd: int | None = None
            self.unsent: str | None = None  # why a message of the child's did not pickle
            with suppress(AttributeError, OSError):
                self._pidfd = os.pidfd_open(pid)
        try:
            for signum in held:  # raised by the caller's handlers, as they would have been
                signal.raise_signal(signum)
            _deliver_held()
        except BaseException:
            self.end()
            raise

    @property
    def gone(self) -> bool:
        """Whether the child has exited (or been killed)."""
        return self._exited()

    def receive(self, timeout: float) -> list[Any]:
        """The messages that have come, waiting up to `timeout` seconds for one (or for the
        child to go) when none is waiting."""
        messages = self._parse()
        if not messages and self._read is not None and not self._exited():
            watched = [self._read] if self._pidfd is None else [self._read, self._pidfd]
            step = timeout if self._pidfd is not None else min(timeout, 0.005)
            with suppress(InterruptedError):
                select.select(watched, [], [], max(0.0, step))
            messages = self._parse()
        if not messages and self._exited():  # what it sent before it went is in the pipe
            messages = self._drain()
        return messages

    def _drain(self) -> list[Any]:
        """(The child has gone.) The messages it sent, read up to the end of the pipe, which
        comes once every process holding its write end is gone: the child, and what it started
        (waited for `DRAIN` seconds at most; `end` ends them). Until then, a message still on
        its way is not taken for none: the exit is judged on everything the child sent."""
        deadline = time.monotonic() + DRAIN
        while True:
            messages = self._parse()
            left = deadline - time.monotonic()
            if messages or self._eof or self._read is None or left <= 0:
                return messages
            with suppress(InterruptedError):
                select.select([self._read], [], [], left)

    def end(self, grace: float = GRACE) -> None:
        """End the child and its process group: SIGTERM, then SIGKILL to whatever is left
        after `grace` seconds; reap the child. Safe to call more than once."""
        if self._reaped:
            return
        exiting = time.monotonic() + 0.02  # one that has answered ends its escaped itself
        while not self._exited() and time.monotonic() < exiting:  # (no /proc scan, 3 ms)
            self._wait_exit(max(0.0, exiting - time.monotonic()) if self._pidfd else 0.001)
        if not self._exited():  # its orphans are re-parented to it only while it lives
            with suppress(OSError):
                os.kill(self.pid, signal.SIGSTOP)  # so that it starts none meanwhile
            end_escaped(self.pid)
            with suppress(OSError):
                os.kill(self.pid, signal.SIGCONT)
        _signal_group(self.pid, signal.SIGTERM)
        deadline = time.monotonic() + grace
        while not self._exited() and time.monotonic() < deadline:
            self._wait_exit(min(0.005, max(0.0, deadline - time.monotonic())))
        if not self._exited():
            _signal_group(self.pid, signal.SIGKILL)
        _, status = os.waitpid(self.pid, 0)
        if self.exit_code is None:
            self.exit_code = os.waitstatus_to_exitcode(status)
        self._reaped = True
        # What the child started and left behind is still in its group (which keeps the group's
        # number from being reused); zombies of it that nobody reaps are not alive.
        while _group_alive(self.pid) and time.monotonic() < deadline:
            time.sleep(0.002)
        if _group_alive(self.pid):
            _signal_group(self.pid, signal.SIGKILL)
        for fd in (self._read, self._pidfd):
            if fd is not None:
                os.close(fd)
        self._read = self._pidfd = None

    def _exited(self) -> bool:
        """Whether the child has gone; notes its exit code without reaping it (so its pid,
        which names its process group, stays reserved until `end`)."""
        if self.exit_code is not None:
            return True
        try:
            info = os.waitid(os.P_PID, self.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
        except ChildProcessError:  # reaped elsewhere (a SIGCHLD handler of the caller's)
            self.exit_code = -1
            return True
        if info is None:
            return False
        self.exit_code = info.si_status if info.si_code == os.CLD_EXITED else -info.si_status
        return True

    def _wait_exit(self, seconds: float) -> None:
        if self._pidfd is not None and not self._exited():
            with suppress(InterruptedError):
                select.select([self._pidfd], [], [], seconds)
        else:
            time.sleep(seconds)

    def _parse(self) -> list[Any]:
        """Read what is waiting in the pipe; the complete messages in it."""
        while self._read is not None:
            try:
                data = os.read(self._read, 1 << 16)
            except BlockingIOError:
                break
            if not data:
                self._eof = True
                break
            self._buffer += data
        messages = []
        buffer = self._buffer
        while len(buffer) >= _HEADER.size:
            (size,) = _HEADER.unpack_from(buffer)
            if len(buffer) < _HEADER.size + size:
                break
            message = pickle.loads(buffer[_HEADER.size : _HEADER.size + size])
            del buffer[: _HEADER.size + size]
            if isinstance(message, Unsent):
                self.unsent = str(message)
            else:
                messages.append(message)
        return messages


# --- whose KeyboardInterrupt -------------------------------------------------------------------
#
# A KeyboardInterrupt is the user's when a SIGINT (a Ctrl-C) or a SIGTERM reached this process
# while the code that raised it ran; one raised with no such signal is the code's own (a module
# that raises it in a trial is a failed trial, not a stop of the command). A child process of its
# own (`Child`) leads its own process group, so a terminal's Ctrl-C never reaches it: there,
# every KeyboardInterrupt is its code's. Pool workers ignore SIGINT likewise.

_signals = [0]  # the SIGINTs and SIGTERMs this process has received while they were counted


def interrupt_signals() -> int:
    """How many SIGINTs and SIGTERMs this process has received while `counting_interrupts`
    counted them (compare two readings: a change means the user asked to stop)."""
    return _signals[0]


def _counting(earlier: Any) -> Callable[[int, Any], Any]:
    def handler(signum: int, frame: Any) -> Any:
        _signals[0] += 1
        return earlier(signum, frame)

    handler.counts = True  # type: ignore[attr-defined]
    return handler


@contextmanager
def counting_interrupts() -> Iterator[None]:
    """While the block runs, count the SIGINTs and SIGTERMs that reach this process (see
    `interrupt_signals`); their handlers still run as before. Only the main thread can install
    handlers: elsewhere, and for a signal Python does not handle (ignored, or left to kill the
    process), nothing changes (such a signal raises no KeyboardInterrupt anyway)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    earlier: dict[int, Any] = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(sig)
        if callable(handler) and not getattr(handler, "counts", False):
            earlier[sig] = handler
            signal.signal(sig, _counting(handler))
    try:
        yield
    finally:
        for number, put_back in earlier.items():
            signal.signal(number, put_back)


def _run_child(
    target: Callable[[Channel], None], limits: Limits | None, read: int, write: int, parent: int
) -> NoReturn:
    """(In a `Child`.) Run the target and exit (0, or `_SUPERVISOR_FAILED` if it raised)."""
    code = 0
    try:
        os.close(read)
        os.setpgid(0, 0)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)  # the caller's stop kills it
        # Not the caller's counting handler: no Ctrl-C of the user's reaches a group of its
        # own, so every KeyboardInterrupt here is its code's (see `counting_interrupts`).
        signal.signal(signal.SIGINT, signal.default_int_handler)
        _die_with(parent, adopt=True)
        _apply(limits)
        target(Channel(write))
    except (BrokenPipeError, KeyboardInterrupt, Unsent):  # the caller stopped listening, or
        code = _SUPERVISOR_FAILED  # a Ctrl-C reached it before it left the caller's group, or
        # a message that did not pickle, which the caller reports (its traceback is noise)
    except BaseException:
        code = _SUPERVISOR_FAILED
        with suppress(BaseException):
            traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            with suppress(BaseException):
                stream.flush()
        with suppress(BaseException):  # waitid fails (ECHILD) if it started no process:
            os.waitid(os.P_ALL, 0, os.WEXITED | os.WNOHANG | os.WNOWAIT)  # no /proc scan then
            end_escaped(os.getpid())
        os._exit(code)


_PR_SET_PDEATHSIG, _PR_SET_CHILD_SUBREAPER = 1, 36


def die_with_parent(parent: int) -> None:
    """Have the kernel kill this process (forked by `parent`) when the thread that forked it
    ends (Linux): a parent killed outright (SIGKILL) cannot end its children, which would
    otherwise run on, orphaned. Isolated children and the local pool's workers
    (`anytime.pool`) ask for it as they start; it exits at once if `parent` is already gone.
    Elsewhere a thread watches for the parent's end (this process is then adopted) and exits."""
    _die_with(parent)
    if not sys.platform.startswith("linux"):
        threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(0.5)
    os._exit(_SUPERVISOR_FAILED)


def _die_with(parent: int, adopt: bool = False) -> None:
    """Have the kernel kill this child when the thread that forked it ends (Linux): a caller
    killed outright (SIGKILL, or a worker process its own parent terminates) cannot end its
    child, which would otherwise run on in a process group of its own."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    with suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        if adopt:  # its orphaned descendants become its, not init's (see `end_escaped`)
            libc.prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
    if os.getppid() != parent:  # it went before the request was made
        os._exit(_SUPERVISOR_FAILED)


def _descendants(pid: int) -> dict[int, ProcessInfo]:
    below: dict[int, list[ProcessInfo]] = {}
    for info in processes():
        below.setdefault(info.parent, []).append(info)
    found: dict[int, ProcessInfo] = {}
    todo = [pid]
    while todo:
        for info in below.get(todo.pop(), []):
            if info.pid not in found:
                found[info.pid] = info
                todo.append(info.pid)
    return found


def end_escaped(pid: int) -> None:
    """Kill the live descendants of `pid` (a `Child`, their subreaper while it lives) outside
    its process group (setsid), which the group's signals miss. All are stopped, walk by walk
    until none is new (one forked meanwhile is in the next); then those killed, the rest go on."""
    stopped: set[int] = set()
    for _ in range(100):  # a fork bomb's new processes are stopped walk by walk
        found = _descendants(pid).values()
        new = [p.pid for p in found if p.pid not in stopped and p.state not in "ZX"]
        if not new:
            break
        for each in new:
            with suppress(OSError):
                os.kill(each, signal.SIGSTOP)
        stopped.update(new)
    if not stopped:
        return
    now = _descendants(pid)  # their groups as they are now that none of them runs
    for each in stopped:
        escaped = each in now and now[each].group != pid
        with suppress(OSError):
            os.kill(each, signal.SIGKILL if escaped else signal.SIGCONT)


def _apply(limits: Limits | None) -> None:
    if limits is None:
        return
    import resource

    if limits.memory is not None:
        mapped = _address_space()
        wanted = mapped + int(limits.memory)
        resource.setrlimit(resource.RLIMIT_AS, (wanted, wanted))
    if limits.cpu is not None:
        used = resource.getrusage(resource.RUSAGE_SELF)
        seconds = math.ceil(used.ru_utime + used.ru_stime + limits.cpu)
        resource.setrlimit(resource.RLIMIT_CPU, (seconds, seconds + 1))


def _address_space() -> int:
    """The bytes of address space this process has mapped (0 where it cannot be read)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 0
    return pages * os.sysconf("SC_PAGE_SIZE")


def _signal_group(pgid: int, sig: int) -> None:
    with suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, sig)


@frozen
class ProcessInfo:
    """What /proc says of a process."""

    pid: int
    state: str  # R, S, D, Z (a zombie), ...
    parent: int
    group: int
    session: int


def processes() -> list[ProcessInfo]:
    """Every process /proc lists (empty on a system without /proc)."""
    found = []
    with suppress(OSError):
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                stat = (entry / "stat").read_text()
            except OSError:  # it ended meanwhile
                continue
            fields = stat[stat.rfind(")") + 2 :].split()  # after "pid (comm) "
            if len(fields) > 3:
                state, parent, group, session = fields[0], *map(int, fields[1:4])
                found.append(ProcessInfo(int(entry.name), state, parent, group, session))
    return found


def group_members(pgid: int) -> list[int]:
    """The live processes of process group `pgid` (zombies left to a parent that does not
    reap them are not alive); on a system without /proc, the group itself if it exists."""
    if not Path("/proc").is_dir():
        try:
            os.killpg(pgid, 0)
        except (ProcessLookupError, PermissionError):
            return []
        return [pgid]
    return [p.pid for p in processes() if p.group == pgid and p.state not in ("Z", "X")]


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except (ProcessLookupError, PermissionError):
        return False
    return bool(group_members(pgid))  # only zombies, perhaps


@frozen
class Lost:
    """A call made by `calls` that did not come back: its process died, or it took longer
    than the watchdog allows; `reason` says which, in words."""

    reason: str
    exit_code: int | None = None


def calls(
    function: Callable[[Any], Any],
    items: Sequence[Any],
    *,
    watchdog: float,
    limits: Limits | None = None,
    grace: float = GRACE,
) -> Iterator[Any]:
    """`function(item)` for each item, in order, in child processes; each value is given as it
    comes, or `Lost` for a call whose process died or that took more than `watchdog` seconds
    of wall time (its process is then ended, and a new one goes on with the next items). One
    process makes the calls in turn, so a run of calls costs one fork, not one per call. An
    exception `function` raises is raised here, after the values before it."""
    start = 0
    while start < len(items):
        process = Child(partial(_calling, function, items, start), limits)
        try:
            start = yield from _answers(process, items, start, watchdog)
        finally:
            process.end(grace)


def _calling(
    function: Callable[[Any], Any], items: Sequence[Any], start: int, out: Channel
) -> None:
    for index in range(start, len(items)):
        try:
            value = function(items[index])
        except BaseException as exc:
            out.send(("raised", portable(exc)))
            return
        out.send(("value", value))


def _answers(
    process: Child, items: Sequence[Any], start: int, watchdog: float
) -> Generator[Any, None, int]:
    """The values `process` sends from item `start` on; returns the first item it did not
    answer for (after giving it as `Lost`), or len(items)."""
    index = start
    since = time.monotonic()
    while index < len(items):
        gone = process.gone  # before the read: then what it sent before it went is read too
        messages = process.receive(min(0.05, max(0.0, since + watchdog - time.monotonic())))
        for kind, value in messages:
            if kind == "raised":
                raise value
            yield value
            index += 1
            since = time.monotonic()
        if messages:
            continue
        if gone:
            yield Lost(process.unsent or died(process.exit_code), process.exit_code)
            return index + 1
        if time.monotonic() - since >= watchdog:
            yield Lost(f"watchdog: no answer after {watchdog:g} s of wall time")
            return index + 1
    return index


def portable(exc: BaseException) -> BaseException:
    """`exc` if it pickles, for a child to send to its caller; else a RuntimeError carrying its
    traceback's text (an interrupt that does not pickle, a plain KeyboardInterrupt: it still
    interrupts the caller)."""
    try:
        pickle.loads(pickle.dumps(exc))
    except Exception:
        if isinstance(exc, KeyboardInterrupt):
            return KeyboardInterrupt(str(exc))
        text = "".join(traceback.format_exception(exc)).rstrip()
        return RuntimeError(f"in an isolated process:\n{text}")
    return exc


def died(exit_code: int | None) -> str:
    """How a child process ended, in words."""
    if exit_code is None:
        return "its process ended"
    if exit_code < 0:
        try:
            name = signal.Signals(-exit_code).name
        except ValueError:
            name = f"signal {-exit_code}"
        return f"its process was killed by {name} (signal {-exit_code})"
    return f"its process exited with code {exit_code} before it answered"
