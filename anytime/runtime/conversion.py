"""Contract -> interruptible: run a contract algorithm on a schedule of growing allocations.

"Interruptible algorithms produce results of the quality advertised by their performance
profiles even when interrupted unexpectedly; contract algorithms must be given a particular time
allocation in advance." `make_interruptible` closes the gap the papers' way: run the contract
with allocations t0, r t0, r^2 t0, ... and answer with the last completed result; with r = 2 it
reaches at time 4t the quality the contract reaches at t (Russell & Zilberstein 1991), and on m
processors the round-robin schedule of `schedules` does better. `interruptible_profile` gives the
constructed algorithm's performance profile from the contract's, without running anything.
"""

from __future__ import annotations

import concurrent.futures as futures
import inspect
import math
import time
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from anytime.clocks import WallClock
from anytime.compiler.compile import CompiledProgram
from anytime.errors import AnytimeError
from anytime.modules import AnytimeModule, Context, ModuleError, Registry, Result
from anytime.profiles.io import load_profile
from anytime.profiles.profile import (
    Array,
    ConditionalPerformanceProfile,
    new_profile,
    point_mass,
)
from anytime.runtime.modes import Budget
from anytime.runtime.program import program_module, run_program
from anytime.runtime.schedules import (
    Schedule,
    geometric,
    optimal_base,
    randomised,
    round_robin,
)
from anytime.vocabulary import first_useful_time

ScheduleName = Literal["geometric", "round-robin", "randomised"]
SCHEDULES: tuple[ScheduleName, ...] = ("geometric", "round-robin", "randomised")

#: How often (seconds) a multi-worker run looks for an outside stop while contracts run.
POLL = 0.005


class ConversionError(AnytimeError, ValueError):
    """A contract cannot be made interruptible as asked; the message says what and why."""


# --- the analytic profile -----------------------------------------------------------------------


def interruptible_profile(
    contract_profile: ConditionalPerformanceProfile,
    schedule: Schedule,
    time: ArrayLike | None = None,
    *,
    module: str | None = None,
    offsets: int = 256,
) -> ConditionalPerformanceProfile:
    """The profile of the contract algorithm run on `schedule`, answering with the longest
    contract completed so far.

    At time T, for every input quality, the output distribution is the contract's at the length
    of the longest contract completed by T, and the no-result distribution (all mass on quality
    0) before the first completes. Each contract is taken to use exactly its allocation. For a
    randomised schedule it is the average over the offset U (a midpoint rule with `offsets`
    points), which is what one run gives in expectation.

    Args:
        time: the time grid (default: the contract profile's, with each contract's finish time
            and the instant before it added for a deterministic schedule, so that the profile
            is the schedule's exact step function). The table is exact at its grid times;
            between them the profile's linear interpolation ramps each step.
        module: the name the profile is for (default: the contract profile's).

    Returns:
        A profile of kind interruptible on the same input grids, bins and time unit.
    """
    t = contract_profile.time if time is None else np.asarray(time, dtype=np.float64).reshape(-1)
    grid_end = float(t.max()) if len(t) else 0.0
    if schedule.randomised:
        u: Array = (np.arange(offsets) + 0.5) / offsets
    else:
        u = np.zeros(1)
        if time is None:
            t = _with_steps(t, schedule.contracts(grid_end, u[0]).finish)
    longest = schedule.contracts(grid_end, u).longest_completed(t)  # (U, T)
    grids = contract_profile.input_grids
    cells = tuple(len(g) for g in grids)
    if grids:
        q = np.stack(np.meshgrid(*grids, indexing="ij"), axis=-1)  # (*cells, m)
    else:
        q = np.zeros((0,))
    q = np.broadcast_to(q.reshape((*cells, 1, len(grids))), (*cells, len(t), len(grids)))
    nothing = point_mass(0.0, contract_profile.bins)
    probability = np.zeros((*cells, len(t), contract_profile.n_bins))
    mean = np.zeros((*cells, len(t)))
    for lengths in longest:  # one pass per offset, each over the whole table
        at = np.broadcast_to(lengths, (*cells, len(t)))
        done = (at > 0)[..., None]
        probability += np.where(done, contract_profile.distribution(q, at), nothing)
        mean += np.where(done[..., 0], contract_profile.expected(q, at), 0.0)
    return new_profile(
        input_grids=grids,
        time=t,
        bins=contract_profile.bins,
        probability=probability / len(longest),
        mean=np.clip(mean / len(longest), 0.0, 1.0),
        inputs=contract_profile.inputs,
        module=contract_profile.module if module is None else module,
        kind="interruptible",
        time_unit=contract_profile.time_unit,
    )


def _with_steps(time: Array, finish: Array) -> Array:
    """`time` with each contract's finish time, and the instant before it, inside its range:
    the profile then steps there exactly, where linear interpolation between the contract's
    grid times would ramp each step (errors up to 0.1 were measured)."""
    inside = finish[(finish > time[0]) & (finish <= time[-1])]
    return np.unique(np.concatenate([time, inside, np.nextafter(inside, -np.inf)]))


# --- the interruptible module -------------------------------------------------------------------


def make_interruptible(
    contract: AnytimeModule | CompiledProgram,
    *,
    r: float | None = None,
    t0: float | None = None,
    workers: int = 1,
    schedule: ScheduleName | Schedule = "geometric",
    name: str | None = None,
    registry: Registry | None = None,
    seed: int | np.random.Generator | None = None,
) -> AnytimeModule:
    """An interruptible module that runs `contract` with growing allocations.

    The module is a generator `f(ctx, *params)` taking the contract's parameters. It runs
    contract k with allocation `t0 * r^(k + U)` under its own `Context`, whose clock is the outer
    `ctx.clock` (so `WorkClock` ticks accumulate across contracts), and yields the result of
    each contract that completes in time: the last completed, which is also the longest, so the
    results follow the schedule's analytic profile (a stochastic contract may give a lower
    quality for a longer run; the executor keeps the best, and this module does not pick).

    When the outer context has a finite allocation, a contract that cannot finish before it is
    not started: its result would come too late to be the answer, and the module ends at once,
    handing the rest of the time back to the caller instead of spending it on a run that cannot
    count. When the outer context is stopped from outside (`ctx.stop`, an interruption whose
    time nobody knew), the running contract sees the same stop, and whatever it returns is
    abandoned: a contract cut short has no profile to vouch for it. (Worker processes cannot
    see `ctx.stop`: their contracts are abandoned where they are and end at their own
    allocations, which the not-started rule keeps within the outer one.)

    Args:
        contract: a contract module, or a compiled program (a contract algorithm itself).
        r: the base of the schedule, the ratio of successive lengths (default: the schedule's
            optimum: 2 for geometric, (m + 1)^(1/m) for round-robin on m workers, e for
            randomised).
        t0: the first allocation (default: the first time on the contract's profile grid with
            an expected quality above 0, for the best inputs).
        workers: m. With m > 1 the contracts run in m worker processes
            (`ProcessPoolExecutor`), queued in order so that the process freed by contract k
            takes contract k + m, which is the round-robin schedule; a module pickles by
            reference, so it must be defined at the top level of an importable module, and a
            compiled program pickles by value with its modules. A `WorkClock` is per process
            and cannot see the workers' ticks, so a multi-worker run needs a wall clock
            (`WallClock`) in its context, t0 is in seconds, and the profile holds for a
            contract profiled in seconds.
        schedule: "geometric", "round-robin" or "randomised" (U uniform on [0, 1), drawn per
            run), or a `Schedule`, which then fixes t0, r and workers.
        name: the module's name (default: the contract's, with "-interruptible").
        registry: where to register the module (default: nowhere).
        seed: for the randomised schedule's offsets.

    Returns:
        The module, with `profile_source` the analytic profile (`interruptible_profile`) when
        the contract has a profile.
    """
    module = program_module(contract) if isinstance(contract, CompiledProgram) else contract
    if module.kind != "contract":
        raise ConversionError(
            f"module '{module.name}' is {module.kind}, not a contract module: only a contract "
            "algorithm needs converting"
        )
    profile = _profile_of(module)
    plan = _plan(module, profile, schedule, r, t0, workers)
    module_name = (name or f"{module.name}-interruptible").lower()
    function = OnSchedule(contract, module, plan, np.random.default_rng(seed), module_name)
    result = AnytimeModule(
        name=module_name,
        kind="interruptible",
        function=function,
        parameters=module.parameters,
        inputs=module.inputs,
        profile_source=(
            None if profile is None else interruptible_profile(profile, plan, module=module_name)
        ),
        origin=f"{module.name} made interruptible ({_describe(plan)})",
    )
    return registry.add(result) if registry is not None else result


class OnSchedule:
    """The function of a module made by `make_interruptible`: a generator `f(ctx, *args)`
    running the contract on the schedule. An object, not a closure, so that the module pickles
    by value (its contract by reference) into a worker process wherever it is assigned."""

    def __init__(
        self,
        contract: AnytimeModule | CompiledProgram,
        module: AnytimeModule,
        plan: Schedule,
        rng: np.random.Generator,
        name: str,
    ) -> None:
        self.contract, self.module, self.plan, self.rng = contract, module, plan, rng
        self.__name__ = self.__qualname__ = name.replace("-", "_")
        self.__signature__ = _signature(module)

    def __call__(self, ctx: Context, *args: Any, **kwargs: Any) -> Iterator[Result]:
        offset = self.plan.draw(self.rng)
        if self.plan.workers == 1:
            yield from _sequential(self.module, self.plan, offset, ctx, args, kwargs)
        else:
            name = self.module.name
            yield from _parallel(self.contract, name, self.plan, offset, ctx, args, kwargs)


def _sequential(
    module: AnytimeModule,
    plan: Schedule,
    offset: float,
    ctx: Context,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
) -> Iterator[Result]:
    k = 0
    while not ctx.expired:
        length = plan.length(k, offset)
        if ctx.elapsed + length > ctx.allocation:
            return  # cannot finish in time: not started
        result = module(Context(allocation=length, clock=ctx.clock, stop=ctx.stop), *args, **kwargs)
        if ctx.stop.is_set() or ctx.elapsed > ctx.allocation:
            return  # cut short, or completed too late: abandoned
        yield _checked(module.name, result)
        k += 1


def _parallel(
    target: AnytimeModule | CompiledProgram,
    name: str,
    plan: Schedule,
    offset: float,
    ctx: Context,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
) -> Iterator[Result]:
    if ctx.clock.unit != "seconds":
        raise ConversionError(
            f"module '{name}' on {plan.workers} workers runs its contracts in other processes, "
            f"whose work ticks a {type(ctx.clock).__name__} cannot see: give it a context with "
            "a WallClock"
        )
    m = plan.workers
    # Time shared with the workers: the monotonic clock is the machine's, not the process's.
    deadline = time.monotonic() + ctx.remaining
    pool = futures.ProcessPoolExecutor(max_workers=m)
    running: dict[futures.Future[Result | None], tuple[int, float]] = {}
    issued = 0
    exhausted = False  # a contract did not fit: every later one is longer

    def issue() -> None:
        nonlocal issued, exhausted
        length = plan.length(issued, offset)
        if exhausted or ctx.elapsed + length > ctx.allocation:
            exhausted = True
            return
        call = (target, length, deadline, tuple(args), dict(kwargs))
        running[pool.submit(_run_contract, *call)] = (issued, length)
        issued += 1

    try:
        # Two rounds queued ahead: the pool hands the oldest queued contract to the first
        # process that frees up, which is contract k + m when contract k completes (finish
        # times grow with k), so the queue is the round-robin schedule, and a worker goes on
        # to its next contract without waiting for this process to notice.
        for _ in range(2 * m):
            issue()
        longest = 0.0
        while running and not ctx.expired:
            done, _ = futures.wait(
                running, timeout=min(ctx.remaining, POLL), return_when=futures.FIRST_COMPLETED
            )
            for future in sorted(done, key=lambda f: running[f][0]):
                _, length = running.pop(future)
                outcome = future.result()
                if outcome is None:  # it would have ended past the deadline: not started
                    exhausted = True
                    continue
                result = _checked(name, outcome)
                if ctx.expired:
                    return  # completed too late: abandoned
                issue()
                if length > longest:
                    longest = length
                    yield result
    finally:
        # Queued contracts are cancelled and running ones stopped: their results would come
        # too late, and a contract that hangs would keep the interpreter waiting at its exit.
        processes = list((pool._processes or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()


def _run_contract(
    target: AnytimeModule | CompiledProgram,
    length: float,
    deadline: float,
    args: tuple[Any, ...],
    kwargs: dict[str, Any],
) -> Result | None:
    """One contract in a worker process, on that process's wall clock; None, without running
    it, when it would end past the deadline (on the machine's monotonic clock)."""
    if time.monotonic() + length > deadline:
        return None
    if isinstance(target, CompiledProgram):
        return run_program(target, args, Budget(length, clock=WallClock())).result
    result: Result = target(Context(allocation=length, clock=WallClock()), *args, **kwargs)
    return result


def _checked(name: str, result: object) -> Result:
    if not isinstance(result, Result):
        raise ModuleError(f"contract module '{name}' returned {result!r}, not a Result")
    return result


# --- arguments ----------------------------------------------------------------------------------


def _profile_of(module: AnytimeModule) -> ConditionalPerformanceProfile | None:
    source = module.profile_source
    if source is None or isinstance(source, ConditionalPerformanceProfile):
        return source
    return load_profile(source)


def _plan(
    module: AnytimeModule,
    profile: ConditionalPerformanceProfile | None,
    schedule: ScheduleName | Schedule,
    r: float | None,
    t0: float | None,
    workers: int,
) -> Schedule:
    where = f"module '{module.name}'"
    if isinstance(schedule, Schedule):
        if r is not None or t0 is not None or workers not in (1, schedule.workers):
            raise ConversionError(
                f"{where}: a Schedule fixes t0, r and workers; give either it or them"
            )
        return schedule
    if schedule not in SCHEDULES:
        raise ConversionError(
            f"{where}: unknown schedule {schedule!r} (expected one of {', '.join(SCHEDULES)})"
        )
    first = _first_useful(profile) if t0 is None else float(t0)
    if first is None:
        raise ConversionError(
            f"{where} has no profile to choose the first allocation from: give t0"
        )
    if not isinstance(workers, int) or workers < 1:
        raise ConversionError(f"{where}: workers must be an integer >= 1, got {workers!r}")
    if schedule == "round-robin":
        return round_robin(workers, first, optimal_base(workers) if r is None else r)
    if schedule == "randomised":
        return randomised(math.e if r is None else r, first, workers)
    if workers == 1:
        return geometric(first, 2.0 if r is None else r)
    return Schedule(unit=first, base=2.0 if r is None else r, workers=workers, name="geometric")


def _first_useful(profile: ConditionalPerformanceProfile | None) -> float | None:
    """The first time above 0 of the contract's grid at which its expected quality, with
    perfect inputs, is above 0 (a shorter contract gives nothing); the last if it never is
    (`first_useful_time`). Time 0 is left out: a schedule's first contract has a length."""
    if profile is None:
        return None
    positive = profile.time > 0
    if not np.any(positive):
        return None
    curve = profile.expected(np.ones((len(profile.time), profile.n_inputs)), profile.time)
    return first_useful_time(profile.time[positive], curve[positive])


def _signature(module: AnytimeModule) -> inspect.Signature:
    """ctx, then the contract's parameters: so the library sees the module's arity."""
    try:
        signature = inspect.signature(module.function)
    except (TypeError, ValueError):
        signature = None
    kinds = (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD)
    if signature is None or any(p.kind in kinds for p in signature.parameters.values()):
        positional = inspect.Parameter.POSITIONAL_OR_KEYWORD
        parameters = [inspect.Parameter(p, positional) for p in ("ctx", *module.parameters)]
        return inspect.Signature(parameters)
    return signature.replace(return_annotation=inspect.Signature.empty)


def _describe(plan: Schedule) -> str:
    offset = " + U" if plan.randomised else ""
    where = f" on {plan.workers} workers" if plan.workers > 1 else ""
    return f"{plan.name} schedule, lengths {plan.unit:g} * {plan.base:.4g}^(k{offset}){where}"
