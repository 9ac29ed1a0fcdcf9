"""`anytime profile`, `anytime calibrate` and `anytime check`: measuring modules."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from anytime.cli.common import (
    EXIT_OK,
    MAX_TRIALS,
    MAX_WORKERS,
    InputError,
    UsageError,
    float_in_range,
    int_in_range,
    isolation_options,
    json_text,
    library_options,
    open_library,
    random_seed,
    refuse_colliding_outputs,
    refuse_overwriting_inputs,
    run_mode,
    trial_count,
    worker_count,
    worker_options,
)
from anytime.cli.schemas import one_schema
from anytime.compiler.model import CompileError
from anytime.dsl import load_schemas
from anytime.files import format_size
from anytime.library import AnytimeLibrary
from anytime.measure.builder import (
    ProfileRequest,
    profile_module,
)
from anytime.measure.calibrate import Calibration, calibrate, convert_profile
from anytime.measure.catalogue import check_module
from anytime.measure.progress import timed_progress
from anytime.measure.upstream import PROBES, Round, UpstreamError, measure_upstream
from anytime.modules import AnytimeModule
from anytime.profiles.dynamic import DEFAULT_STATES, DynamicProfile
from anytime.profiles.dynamic_io import dynamic_profile_path, save_dynamic_profile, save_traces
from anytime.profiles.io import load_profile, save_profile

#: The largest table of measured qualities `anytime profile` makes (trials x cells x times).
MAX_TABLE_BYTES = 1 << 30
#: The most runs `anytime check` makes (each is kept until the checks are done).
MAX_CHECK_RUNS = 100_000
#: The longest calibration (seconds).
MAX_CALIBRATION_SECONDS = 3600
#: The most states of a dynamic profile `anytime profile --dynamic` derives.
MAX_STATES = 100
#: The most rounds of `anytime profile --upstream`.
MAX_ROUNDS = 10
#: The most program runs `anytime profile --upstream --probes` draws a round.
MAX_PROBES = 1_000_000
#: `--upstream` stops when the compiled expectations move by at most this.
UPSTREAM_TOLERANCE = 0.005


def add_commands(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    profile = commands.add_parser(
        "profile",
        help="measure a module's conditional performance profile and write it to a file",
        description="Run a module on generated problem instances over its registered grid of "
        "input qualities and times, score every output, and write the measured profile "
        "(histograms with sample counts, means and standard deviations). The same seed gives "
        "the same file, whatever the number of workers.",
    )
    profile.add_argument("module", metavar="MODULE", help="the module's name")
    profile.add_argument(
        "--trials",
        type=trial_count,
        default=100,
        metavar="N",
        help=f"instances per cell (100; at most {MAX_TRIALS})",
    )
    worker_options(profile, "run the trials")
    profile.add_argument("--seed", type=random_seed, default=0, metavar="S", help="root seed (0)")
    profile.add_argument(
        "--clock",
        choices=["work", "wall"],
        default="work",
        help="time axis in reported ticks (work, reproducible) or in seconds (wall)",
    )
    profile.add_argument("--quiet", action="store_true", help="no progress bar")
    profile.add_argument(
        "-o", "--output", metavar="FILE", help="where to write the profile (MODULE.yaml)"
    )
    profile.add_argument(
        "--dynamic",
        action="store_true",
        help="also write the module's dynamic profile (how a run's quality moves from one time"
        " to the next) beside the profile, as NAME.dynamic.yaml for NAME.yaml",
    )
    profile.add_argument(
        "--states",
        type=int_in_range(1, MAX_STATES),
        metavar="K",
        help=f"quality states of the dynamic profile ({DEFAULT_STATES}; at most {MAX_STATES};"
        " with --dynamic)",
    )
    profile.add_argument(
        "--entered",
        type=int_in_range(1, MAX_STATES),
        metavar="C",
        help="classes of the time a run entered its quality state (1, none: the state is the"
        f" quality bin alone; at most {MAX_STATES}; with --dynamic): a state that remembers how"
        " fast the run got there, for a module that reports a level or an estimate",
    )
    profile.add_argument(
        "--ends",
        action="store_true",
        help="with --dynamic: one more state per quality bin for runs that ended by themselves"
        " (converged and returned), so a run still running is not averaged with them",
    )
    profile.add_argument(
        "--traces",
        metavar="FILE",
        help="also write every trial's quality at every time to FILE (as NAME.traces.yaml, a"
        " profile directory does not read it as a profile)",
    )
    profile.add_argument("--json", action="store_true", help="print a JSON summary")
    upstream = profile.add_argument_group("measuring a module where a program puts it")
    upstream.add_argument(
        "--upstream",
        metavar="SCHEMA_FILE",
        help="measure the module on the inputs a schema's upstream modules feed it under its"
        " compiled allocations (problems from the schema's program problem set), compiling"
        " again with the new profile and measuring again until the compiled table stops"
        " changing",
    )
    upstream.add_argument(
        "--schema", metavar="NAME", help="the schema of --upstream's file (default: its only one)"
    )
    upstream.add_argument(
        "--rounds",
        type=int_in_range(1, MAX_ROUNDS),
        default=3,
        metavar="N",
        help=f"at most N rounds of measuring and compiling (3; at most {MAX_ROUNDS}); it stops"
        f" when the compiled expectations move by at most {UPSTREAM_TOLERANCE}",
    )
    upstream.add_argument(
        "--probes",
        type=int_in_range(1, MAX_PROBES),
        metavar="N",
        help=f"program runs drawn first in each round, whose inputs, pooled by input cell, the"
        f" trials take theirs from ({PROBES:,}; at most {MAX_PROBES:,}): a cell the program"
        " rarely reaches is measured on the few inputs they find there, which more --probes"
        " add to and more --trials do not",
    )
    isolation_options(profile, "trial")
    library_options(profile)
    profile.set_defaults(run=run_profile, usage_error=profile.error)

    calibrate_ = commands.add_parser(
        "calibrate",
        help="measure a module's ticks per second; convert a profile between ticks and seconds",
        description="Run a module on instances of its registered problem set for a wall-time "
        "budget and report how many ticks it reports per second (the median over runs, with a "
        "95% interval of the median and the range). With --profile, write that profile with "
        "its time axis converted at the measured rate.",
    )
    calibrate_.add_argument("module", metavar="MODULE", help="the module's name")
    calibrate_.add_argument(
        "--seconds",
        type=float_in_range(0, MAX_CALIBRATION_SECONDS),
        default=1.0,
        metavar="S",
        help=f"wall-time budget of the measurement (1; at most {MAX_CALIBRATION_SECONDS})",
    )
    calibrate_.add_argument(
        "--seed", type=random_seed, default=0, metavar="S", help="root seed (0)"
    )
    calibrate_.add_argument("--profile", metavar="FILE", help="a profile file to convert")
    calibrate_.add_argument(
        "--to",
        choices=["seconds", "ticks"],
        default=None,  # None: not given, so that --to without --profile can be refused
        help="the unit to convert --profile's time axis to (seconds; only with --profile)",
    )
    calibrate_.add_argument(
        "-o", "--output", metavar="OUT", help="where to write the converted profile"
    )
    calibrate_.add_argument("--json", action="store_true", help="print JSON")
    calibrate_.add_argument("--quiet", action="store_true", help="no progress bar")
    isolation_options(
        calibrate_,
        "run",
        crash="a run that crashes or hangs is an error, not the command's end",
        bound="; at most the budget + 2",
    )
    library_options(calibrate_)
    calibrate_.set_defaults(run=run_calibrate, usage_error=calibrate_.error)

    check = commands.add_parser(
        "check",
        help="run the catalogue of checks every anytime module must pass",
        description="Run a module through the catalogue on instances of its registered problem "
        "set, under the work clock: it pickles by reference, every answer is a Result of "
        "quality in [0, 1], no run raises, it honours its deadlines, interrupted it keeps its "
        "best registered result, and its measured profile agrees with its declared one within "
        "sampling error. Exit status 1 when a check fails.",
    )
    check.add_argument("module", metavar="MODULE", help="the module's name")
    check.add_argument(
        "--trials",
        type=trial_count,
        default=20,
        metavar="N",
        help=f"instances per cell (20; at most {MAX_CHECK_RUNS:,} runs in all)",
    )
    check.add_argument(
        "--seed",
        type=random_seed,
        default=0,
        metavar="S",
        help="root seed (0); the instances are never those `anytime profile` measured with it",
    )
    check.add_argument(
        "--workers",
        type=worker_count,
        default=1,
        metavar="N",
        help=f"local processes for the profile check (1; at most {MAX_WORKERS})",
    )
    check.add_argument("--json", action="store_true", help="print the report as JSON")
    check.add_argument("--quiet", action="store_true", help="no progress bars")
    isolation_options(check, "run")
    library_options(check)
    check.set_defaults(run=run_check)


def run_profile(args: argparse.Namespace) -> int:
    if args.states is not None and not args.dynamic:
        args.usage_error("--states K goes with --dynamic")
    if args.entered is not None and not args.dynamic:
        args.usage_error("--entered C goes with --dynamic")
    if args.ends and not args.dynamic:
        args.usage_error("--ends goes with --dynamic")
    if args.upstream is None and args.schema is not None:
        args.usage_error("--schema NAME goes with --upstream SCHEMA_FILE")
    if args.upstream is None and args.probes is not None:
        args.usage_error("--probes N goes with --upstream SCHEMA_FILE")
    if args.upstream is not None:
        return _run_upstream(args)
    module, library = _runnable(args)
    output = Path(args.output if args.output is not None else f"{module.name}.yaml")
    refuse_colliding_outputs(
        {
            "the profile's file": output,
            "the dynamic profile's file": dynamic_profile_path(output) if args.dynamic else None,
            "--traces": args.traces,
        }
    )
    grid = library.measurement(module.name).grid
    cells = math.prod(grid.cell_shape)
    tables = 2 if module.reports == "estimate" and (args.dynamic or args.traces) else 1
    size = 8 * tables * args.trials * cells * len(grid.time)  # qualities (and estimates)
    if size > MAX_TABLE_BYTES:
        raise UsageError(
            f"--trials {args.trials}: {cells} cells x {len(grid.time)} times make"
            f" {'tables' if tables > 1 else 'a table'} of {format_size(size)}, more than the"
            f" limit of {format_size(MAX_TABLE_BYTES)}; give fewer --trials"
        )
    request = ProfileRequest(
        trials=args.trials,
        seed=args.seed,
        workers=args.workers,
        scheduler=args.scheduler,
        clock=args.clock,
        quiet=args.quiet,
        traces=args.dynamic or args.traces is not None,
        mode=run_mode(args),
    )
    build = profile_module(module, request, measurement=library.measurement(module.name))
    written = {"file": output}
    _save(output, lambda path: save_profile(build.profile, path))
    traces = build.traces
    if args.dynamic:
        assert traces is not None  # asked for with the dynamic profile
        written["dynamic_file"] = dynamic_profile_path(output)
        dynamic = DynamicProfile.from_traces(
            traces, states=args.states or DEFAULT_STATES, entered=args.entered, ends=args.ends
        )
        _save(written["dynamic_file"], lambda path: save_dynamic_profile(dynamic, path))
    if args.traces is not None:
        assert traces is not None
        written["traces_file"] = Path(args.traces)
        _save(written["traces_file"], lambda path: save_traces(traces, path))
    if args.json:
        files = {key: str(written[key]) if key in written else None for key in FILE_KEYS}
        print(json_text({"module": module.name} | files | build.to_dict()))
    else:
        print(build.summary())
        print(f"wrote {', '.join(str(path) for path in written.values())}")
    return EXIT_OK


def _run_upstream(args: argparse.Namespace) -> int:
    """`anytime profile MODULE --upstream SCHEMA_FILE`: `measure_upstream`, its rounds told."""
    for option, given in (
        ("--dynamic", args.dynamic),
        ("--traces", args.traces),
        ("--scheduler", args.scheduler),
    ):
        if given:
            args.usage_error(f"{option} does not go with --upstream")
    module, library = _runnable(args)
    output = Path(args.output if args.output is not None else f"{module.name}.yaml")
    refuse_overwriting_inputs(output, args.upstream)
    schemas = load_schemas(args.upstream)
    name = one_schema(schemas, args.schema, "feeds the module")

    def told(index: int, done: Round) -> None:
        if not (args.quiet or args.json):
            print(
                f"round {index}: {done.reached} of {done.cells} input cells reached; the"
                f" compiled expectations moved by up to {done.change:.4f} (the measurement's"
                f" noise: {done.noise:.4f})",
                flush=True,
            )

    try:
        measured = measure_upstream(
            module.name,
            schemas,
            name,
            library,
            trials=args.trials,
            seed=args.seed,
            workers=args.workers,
            rounds=args.rounds,
            tolerance=UPSTREAM_TOLERANCE,
            progress=False if args.quiet or args.json else None,
            on_round=told,
            probes=args.probes if args.probes is not None else PROBES,
        )
    except (UpstreamError, CompileError) as error:
        raise InputError(str(error), where=getattr(error, "where", None)) from None
    _save(output, lambda path: save_profile(measured.profile, path))
    if args.json:
        rounds = [
            {"change": r.change, "noise": r.noise, "reached": r.reached, "cells": r.cells}
            for r in measured.rounds
        ]
        summary = {"module": module.name, "file": str(output), "schema": name}
        summary |= {"trials": args.trials, "seed": args.seed}
        print(json_text(summary | {"rounds": rounds, "converged": measured.converged}))
    else:
        last = measured.rounds[-1]
        verdict = "converged"
        if not measured.converged:
            verdict = (
                f"not converged: the last round moved the table by {last.change:.4f}, more"
                f" than {UPSTREAM_TOLERANCE}"
                + (
                    (
                        ", within the measurement's noise, most of it in a cell measured on"
                        " a few inputs of the program, reused: measure with more --probes"
                        if last.pooled
                        else ", within the measurement's noise: measure with more --trials"
                    )
                    if last.change <= last.noise
                    else ": give more --rounds"
                )
            )
        print(f"{module.name} on schema {name}: {len(measured.rounds)} rounds, {verdict}")
        print(f"wrote {output}")
    return EXIT_OK


#: The files `anytime profile --json` names (null: not written).
FILE_KEYS = ("file", "dynamic_file", "traces_file")


def _save(path: Path, write: Callable[[Path], None]) -> None:
    """`write(path)`; a file that cannot be written is an `InputError` naming it."""
    try:
        write(path)
    except OSError as error:
        raise InputError(f"cannot write '{path}': {error.strerror}") from None


def _runnable(args: argparse.Namespace) -> tuple[AnytimeModule, AnytimeLibrary]:
    """The module `args.module` names, which must have code to run, and its library."""
    library = open_library(args)
    entry = library[args.module]
    if entry.module is None:
        raise InputError(
            f"module '{entry.name}' has no code to run: it is only a profile ({entry.origin})"
        )
    return entry.module, library


def run_calibrate(args: argparse.Namespace) -> int:
    if (args.profile is None) != (args.output is None):
        args.usage_error("--profile FILE and -o OUT go together")
    if args.to is not None and args.profile is None:
        args.usage_error(f"--to {args.to}: --to converts a --profile FILE, and none was given")
    args.to = args.to or "seconds"
    refuse_overwriting_inputs(args.output, args.profile)
    module, library = _runnable(args)
    profile = None
    if args.profile is not None:  # checked before the measurement spends its seconds
        profile = load_profile(args.profile)
        if profile.time_unit == args.to:
            other = "ticks" if args.to == "seconds" else "seconds"
            raise InputError(
                f"{args.profile}: time_unit: the profile is already in {args.to}"
                f" (give --to {other} to convert it to {other})"
            )
        if profile.module.lower() != module.name:
            raise InputError(
                f"{args.profile}: module: expected '{module.name}' (the module"
                f" calibrated), got '{profile.module}'"
            )
    bar = False if args.quiet else None  # a progress bar on a terminal, unless --quiet
    plan = library.measurement(module.name)
    with timed_progress(args.seconds, label=f"{module.name} calibration", enabled=bar):
        calibration = calibrate(
            module, args.seconds, measurement=plan, seed=args.seed, mode=run_mode(args)
        )
    if profile is not None:
        converted = convert_profile(profile, calibration.ticks_per_second, to=args.to)
        _save(Path(args.output), lambda path: save_profile(converted, path))
    if args.json:
        print(json_text(calibrate_json(calibration) | {"seed": args.seed, "file": args.output}))
    else:
        print(calibration.summary())
        if profile is not None:
            print(f"wrote {args.output} (time in {args.to})")
    return EXIT_OK


def calibrate_json(calibration: Calibration) -> dict[str, Any]:
    """`Calibration.to_dict` with every rate named as one (`min` and `max` are baselines in
    `compile --json`)."""
    renamed = {
        "interval": "ticks_per_second_interval",
        "min": "min_ticks_per_second",
        "max": "max_ticks_per_second",
    }
    return {renamed.get(key, key): value for key, value in calibration.to_dict().items()}


def run_check(args: argparse.Namespace) -> int:
    module, library = _runnable(args)
    plan = library.measurement(module.name)
    cells = math.prod(plan.grid.cell_shape)
    runs = args.trials * cells * (len(plan.grid.time) + 1)  # deadline and interruption runs
    if runs > MAX_CHECK_RUNS:
        raise UsageError(
            f"--trials {args.trials}: {cells} cells x"
            f" {len(plan.grid.time) + 1} runs each make {runs:,} runs, more than the limit"
            f" of {MAX_CHECK_RUNS:,}; give fewer --trials"
        )
    report = check_module(
        module,
        plan.problems,
        registered=plan.grid,
        trials=args.trials,
        seed=args.seed,
        workers=args.workers,
        progress=False if args.quiet else None,  # bars on a terminal, unless --quiet
        mode=run_mode(args),
    )
    if args.json:
        data = report.to_dict()
        # a check's name is `check`, as a module's is `module` (docs/cli.md, "JSON output")
        data["checks"] = [{"check": c.pop("name")} | c for c in data["checks"]]
        print(json_text(data))
    else:
        print(report.format())
    if report.passed:
        return EXIT_OK
    names = ", ".join(check.name for check in report.failed)
    raise InputError(
        f"module '{report.module}' fails {len(report.failed)} of {len(report.checks)} checks:"
        f" {names}"
    )
