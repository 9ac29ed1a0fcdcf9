"""Run the benchmarks and write their tables into docs/benchmarks.md (what `make bench` runs).

Each benchmark runs as its own process, with its quick settings where it has them, and what it
prints goes into the page as it is; the page is generated whole, so no table in it is ever
typed by hand. Run it on a quiet machine: other load skews the numbers.

    .venv/bin/python benchmarks/write_page.py [--only NAME ...] [-o docs/benchmarks.md]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from tables import machine

HERE = Path(__file__).resolve().parent
PAGE = HERE.parent / "docs" / "benchmarks.md"

#: (script, quick arguments, title, what it measures): the order of the page.
BENCHMARKS = [
    (
        "bench_profiles.py",
        [],
        "Profile builder and profiles",
        "Trials per second of the profile builder with one and two worker processes (the"
        " same profile every time), and evaluations per second of a profile's interpolation"
        " for a batch of 100,000 points against asking one point at a time.",
    ),
    (
        "bench_loading.py",
        ["--quick", "--repeats", "1"],
        "Loading profile files",
        "Load time and peak memory of `expected:` and `probability:` profiles of 10^4 to 10^6"
        " numbers: the YAML text with PyYAML's pure loader and with libyaml's C loader, and the"
        " YAML header with its binary companion (target: 10^6 numbers in at most 2 s); and the"
        " navigation schema's compilation split into reading its profiles and compiling."
        " `--quick` skips the pure loader at 10^6 numbers (about a minute a table).",
    ),
    (
        "bench_compiler.py",
        ["--quick"],
        "Compiler",
        "Compile time of the papers' 2-module chain with each allocator (target: under one"
        " second); dp against hill-climbing on random 8-module chains and trees; how far"
        " hill-climbing is from the exhaustive optimum on random programs of 2 to 4 modules."
        " The full run (without `--quick`) uses more programs and repeats.",
    ),
    (
        "bench_allocators.py",
        ["--quick"],
        "Compiler: allocators for general programs",
        "The multi-start allocator against hill-climbing, the exhaustive search and dp on"
        " random chains, trees and DAGs with 1-3 shared results, with and without a best-of or"
        " an if, deterministic and stochastic profiles, 2-12 modules, 50 and 100 lattice units:"
        " the gap to the exhaustive optimum where it is computable (targets: mean <= 0.1%,"
        " worst <= 1% for n <= 5), the allocators' times (target: >= 100x faster than"
        " exhaustive at 4-5 modules), and compile time and peak memory of 6- to 12-module DAGs"
        " (target: 12 modules, 3 shared results, 100 units in <= 10 s and <= 1 GB). `--quick`"
        " uses 15 programs per row instead of 30 and one program per size.",
    ),
    (
        "bench_runtime.py",
        ["--runs", "50", "--repeats", "3"],
        "Runtime: interruption and overhead",
        "How late an interrupted module answers on the wall clock (targets: p99 below 2 ms"
        " for a module yielding every 100 us, below 20 ms for a stuck module under hard"
        " interruption), and what the executor adds per registered result (target: below 5%).",
    ),
    (
        "bench_isolation.py",
        ["--quick"],
        "Runtime: what process isolation costs",
        "Soft, hard and process isolation side by side: the wall time of one run of a trivial"
        " module on the work clock (per-run overhead; for process isolation a fork, a pipe and"
        " ending the child's process group), with the bare process's share and what the"
        " caller pays after a fork; how late a run answers after its deadline on the wall"
        " clock (interruption latency) for a module that yields every millisecond, one that"
        " blocks and one that spins in Python (soft mode cannot interrupt the last two); and"
        " how soon a run answers after its module raises, or its process exits or is killed"
        " (process isolation only). Ratios to soft (or hard) mode; no targets. `--quick` uses"
        " 30 runs per latency row and 200 per overhead row instead of 60 and 500.",
    ),
    (
        "bench_runtime_conversion.py",
        ["--quick"],
        "Runtime: contract algorithms made interruptible",
        "Acceleration ratios of the constructed interruptible algorithms (geometric,"
        " round-robin on m processes, randomised) against theory.",
    ),
    (
        "bench_stopping.py",
        ["--quick-synthetic", "--history"],
        "Runtime: when to stop",
        "Stopping policies (fixed, myopic, projected, optimal by backward induction over the"
        " dynamic profile on the state (quality bins x classes of the time a run entered its"
        " bin, or the run's whole history) that cross-validation on the training traces chose"
        " (`fit_optimal`, its claim the cross-validated utility), with a state per bin for runs"
        " that ended by themselves where some do, and for comparison on 10 bins alone; history"
        " learned on the training traces' histories) on held-out"
        " traces of the ATP, 2-opt tours, k-means clustering and"
        " a test plugin's local search that stalls (it registers only when it improves), as a"
        " fraction of the clairvoyant utility of each trace, with the monitor seeing what"
        " the module reports and, for comparison, its true quality (targets: optimal >= 0.98,"
        " never below fixed or myopic by more than the standard error, claim within 2 se);"
        " then with a cost per look, choosing when to look against looking never and every"
        " step (target: it beats both, or ties looking never where no look pays); then the"
        " stopping rule with a guarantee (ConformalStopping): how often a run"
        " could still gain more than epsilon after its stop, against the alpha it promises"
        " (target: at most alpha + 0.01), and the time it used and saved against running each"
        " run to its end. Last, synthetic families (q = 1 - exp(-lambda t), lambda drawn per"
        " run from a known prior; the monitor sees the true quality, a quantised or a biased"
        " quantised estimate) against their exact Bayes optimum, computed in the benchmark,"
        " with and without a monitoring cost: every policy (the fitted optimal one, and, for"
        " comparison, the optimal one on the bin alone; the history policy learned on the"
        " traces' histories), as a fraction of the Bayes optimum"
        " and of the"
        " clairvoyant, and the optimal and history policies' claimed expected utility against"
        " what they realise (targets: >= 0.98 of the Bayes optimum, never below fixed by more"
        " than the se, claim within 2 se). `--quick-synthetic` runs the synthetic section on"
        " one family and two utilities (12 rows; the full run has 48).",
    ),
    (
        "bench_promises.py",
        ["--runs", "200"],
        "Compiler: promised against delivered",
        "The compiled expectation at every budget of the table against the mean quality that"
        " runs on fresh instances deliver, with its standard error, for the navigation"
        " plugin's navigate schema, for the example plugin's side-length schema (a plugin"
        " that is not the framework's) and for the three schemas of the test plugin"
        " tests/plugins/estimation_plugin (a chain, a two-input program, a best-of)."
        " Target: within two standard errors at every budget, including the smallest (at 5%"
        " a budget falls outside by chance: about one in twenty rows), and no run over its"
        " budget on the work clock. The standard error is the realised mean's only; the"
        " compiled expectation has its own, from the profiles' sampling (find-path: 2000"
        " worlds per cell) and their interpolation between measured input qualities.",
    ),
    (
        "bench_adaptive.py",
        ["--quick"],
        "Runtime: adaptive re-allocation against the fixed allocation",
        "Fixed and adaptive runs of the same fresh instances: the test plugin"
        " tests/plugins/estimation_plugin's three schemas (a chain, a two-input program, a"
        " best-of), the navigation plugin's navigate and navigate-two-planners (a DAG: one"
        " sensed map read by two planners), two DAGs over one shared sensed map whose modules"
        " draw their qualities from their profiles, and the routing plugin's deliver-best."
        " Mean quality with standard errors, the paired difference and its standard error"
        " (target: adaptive >= fixed - se), the re-plans asked for and searched, and the time"
        " of the adaptive runs' `run_program` calls over the fixed ones', wall clock and CPU"
        " (target: <= 1.1). `--quick` uses 64 x 64 worlds and fewer instances.",
    ),
    (
        "bench_shapes.py",
        [],
        "Compiler: promises on every program shape",
        "Programs over one uncertain shared result (a sensed map of quality 0.15 or 0.95) read"
        " by two planners: a best-of of the two plans, a diamond with a product-like join, a"
        " join reading the map twice, with deterministic and stochastic planners. At every"
        " other total, 20,000 simulated runs in which each module draws from its own profile"
        " given the qualities its inputs had in that run, against the compiled promise now and"
        " before (the readers' inputs taken as independent: the promise and what its own"
        " allocation delivered). Then a called schema and an if branch reading the map,"
        " compiled with the input grid {1} and the default one, against the brute-force"
        " optimum. Target: within two standard errors at every total (about one row in twenty"
        " outside by chance), never above the optimum.",
    ),
    (
        "bench_routing.py",
        ["--quick"],
        "Routing: promised against delivered, and 2-opt/Or-opt on TSPLIB",
        "The routing plugin's chain (deliver), DAG (deliver-best) and loop over the depots"
        " (deliver-each, a map of plan-tour): the compiled expectation at every budget"
        " against the mean true quality of fixed and adaptive runs on fresh problems"
        " (target: within max(0.01, 2 se), no run over its budget); and"
        " plan-tours on TSPLIB instances against their optimal lengths over its ticks"
        " (target: within 5% at convergence). `--quick` uses 100 problems per budget.",
    ),
    (
        "bench_motion.py",
        ["--quick"],
        "Motion: compiled against MoveIt's even split, on OMPL",
        "The motion plugin's chain (move: sense, BIT*, shorten) and DAG (move-best: a best-of"
        " of RRT* and BIT* on one sensed map) at every budget of the compiled table, on fresh"
        " problems: the compiled expectation against the realised quality of the compiled"
        " split, MoveIt's even split, all of the time to the planners and the best single fixed"
        " split (targets: the compiled split at least 10% above the even split where the split"
        " matters, never below it by more than a standard error; within max(0.01, 2 se) of its"
        " expectation; no run over its budget); RRT*'s and BIT*'s quality over their validity"
        " checks; profile measuring time on 1 and 2 workers and on a local Dask cluster of 2."
        " `--quick` uses 30 problems per budget.",
    ),
    (
        "bench_choices.py",
        [],
        "Choices: splitting the time of a best-of",
        "Expected quality of the best alternative for the same time stock T_d under the"
        " compiled split, Romanenko's proportional split and an equal split (target: the"
        " compiled split never worse).",
    ),
    (
        "bench_loops.py",
        ["--random", "40"],
        "Loops: splitting a map's time among its calls",
        "For K = 1..4 calls of one module on items of different qualities, the mean expected"
        " quality under the run-time split (equal shares, the marginal-value rule or dynamic"
        " programming, by the calls' curves) against the best split by exhaustive search over"
        " the K calls and an equal split, per budget; then random situations: the gap (target:"
        " within 0.5% for K <= 4), the marginal-value rule used alone, and the time of one"
        " split against one exhaustive search.",
    ),
    (
        "bench_overcoming.py",
        ["--situations", "300"],
        "Navigation: overcoming moving obstacles",
        "The same comparison on obstacle situations met in navigation: expected and realised"
        " quality of the best alternative, over all situations and over those where every"
        " alternative applies (the encounters the profiles are measured on, so the only ones"
        " the expected quality is promised for).",
    ),
    (
        "bench_navigation.py",
        ["--quick"],
        "Navigation: the anytime abstract planner against a compiled A*",
        "Every ratio is against the compiled A* (`search.GridAstar`, numba: the project's A* "
        "step for step, the same paths and expansions, checked problem by problem and against"
        " the `.scen` optima; issue 36); the pure-Python A* is a row and a column. Plan "
        "quality after the first plan and at completion, and time and expansions as fractions"
        " of A*'s (the papers report 0.93 at 27% of their A*'s time); the compiled A* against"
        " `pathfinding`'s; and per map kind, the default ATP and, row by row, its options "
        "added one at a time up to those `anytime plan` uses (each configuration with its own"
        " abstraction build) on the longest problems of 15 MovingAI maps: random with 10%, "
        "20% and 30% of cells blocked, rooms of 8 to 64, mazes of corridor widths 1 to 8, two"
        " street maps and two game maps (twelve of them in `benchmarks/data/movingai/`), with"
        " the abstraction's one-off cost, the falls of the anytime curve (every registered "
        "plan executed), 16 random problems per map, the pure-Python and the peers' A*s per "
        "query (`pathfinding`, networkx, tcod) and issue 36's targets (`--maps MAP ...` runs "
        "that table on maps of your own); last, the compiled A* against the `.scen` optima of"
        " the 15 maps. `--quick` solves fewer problems in the first two tables, keeps the "
        "best of 3 runs of each problem of the per-kind table (16 per map, so the one-off "
        "cost is shared by 16 problems, as the issue states) and checks 200 problems per map "
        "against the `.scen` optima. Each timed run follows a garbage collection, with the "
        "collector off while it runs; what is alive once the benchmark is set up (the modules"
        " loaded) is frozen (`gc.freeze`), so that collection does not scan it again (since "
        "186b07b: before, each collection walked some 140,000 objects, a cold start that made"
        " the planner's time on the options' rows up to 1.6 times what it is without, and "
        "took most of the run). What runs just before a timed run matters too: the planner's "
        "runs are short and cache-bound, so each side runs a map's problems as a stream, "
        "one after another as a planner serving queries on one map does, after one "
        "collection and one untimed round, the best of 3 rounds kept per problem (before, "
        "the sides were interleaved per problem with a collection before each run, and the "
        "options by map read up to 11 points of A*'s time higher with the build on the "
        'caves; docs/navigation.md, "Measured again without the cold start"). The ATP plans '
        "over connected free regions of blocks (a block a wall splits is two nodes), first over "
        "blocks of 8 x 8 cells from centre to centre, then goes on "
        "from the route through the doors between them (not registered by itself); its time "
        "is planning only. Plans are made on the map they are followed on, so the robot keeps"
        " to the cells of the plan's nodes (`keep_to_plan`).",
    ),
    (
        "bench_monitor.py",
        ["--sizes", "64,128", "--worlds", "400"],
        "Navigation: the monitor",
        "The navigation task under the monitor against fixed contract times and the papers'"
        " MIN/MAX policies, and under the monitor with each frame's planning stopped by the"
        " optimal stopping policy over the planner's dynamic profile (`stopping`), on 400"
        " held-out worlds of 64 x 64 and 400 of 128 x 128 (seeds 0-399; on 100 the standard"
        " error of a difference, 6-10, was larger than the differences), against a fixed"
        " contract at every contract of the monitor's grid (100 to 1000): mean utility,"
        " prediction error and bias, utility against a clairvoyant bound, and the monitored"
        " policy's utility less each other policy's, world by world, with its standard error"
        " (targets: prediction error under 2%, the monitored policy above every fixed one and"
        " MIN at both sizes). The monitor plans with the frame program's profile measured in"
        " the task on other worlds (`anytime_navigation.task.calibration`, seeds from 1000;"
        " the first frame's contract chosen apart from the later frames').",
    ),
]


def run(script: str, arguments: list[str]) -> tuple[str, float]:
    """What the benchmark prints, and how long it took in seconds."""
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, str(HERE / script), *arguments],
        cwd=HERE.parent,
        stdout=subprocess.PIPE,
        text=True,
        check=True,
    )
    return done.stdout.strip("\n"), time.perf_counter() - started


def _markdown(output: str) -> str:
    """The benchmark's output as Markdown: a blank line after each table, since a line of text
    right below one would be read as another row."""
    lines: list[str] = []
    for line in output.splitlines():
        if lines and lines[-1].startswith("|") and line.strip() and not line.startswith("|"):
            lines.append("")
        lines.append(line.rstrip())
    return "\n".join(lines)


def section(script: str, arguments: list[str], title: str, about: str) -> str:
    print(f"running {script} {' '.join(arguments)}".rstrip(), file=sys.stderr, flush=True)
    output, seconds = run(script, arguments)
    output = _markdown(output)
    command = " ".join([".venv/bin/python", f"benchmarks/{script}", *arguments])
    return (
        f"## {title}\n\n{_wrap(about)}\n\n`{command}` ({seconds:.0f} s):\n\n"
        f"<!-- output of {script} -->\n\n{output}\n"
    )


def _wrap(text: str) -> str:
    return textwrap.fill(text, width=96, break_on_hyphens=False)


def sections_of(text: str) -> dict[str, str]:
    """The sections of a page this script wrote, by the script whose output each holds."""
    found = {}
    for part in re.split(r"(?m)^(?=## )", text)[1:]:
        script = re.search(r"<!-- output of (\S+) -->", part)
        if script:
            found[script.group(1)] = part.rstrip("\n") + "\n"
    return found


def page(sections: list[str], started: float, rerun: list[str] | None = None) -> str:
    minutes = (time.perf_counter() - started) / 60
    intro = _wrap(
        "Side-by-side measurements, not tests: nothing here is asserted, and `make test` does"
        " not run them. Ratios, not absolute times, are the point. This page is written whole"
        " by `make bench`, which runs every benchmark of `benchmarks/` (with its quick"
        " settings where it has them) and copies what each prints; the tables are never typed"
        " by hand. `benchmarks/README.md` says what each script compares and how to run the"
        " full versions."
    )
    return (
        "# Benchmarks\n\n"
        "<!-- Generated by `make bench` (benchmarks/write_page.py): do not edit by hand. -->\n\n"
        f"{intro}\n\nMachine: {machine()}.\n\n"
        + (
            f"The whole run took {minutes:.1f} minutes.\n\n"
            if not rerun
            else f"Re-run since the whole page was written ({minutes:.1f} minutes):"
            f" {', '.join(rerun)}; each section gives its own command and time.\n\n"
        )
        + "\n".join(sections)
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--only", action="append", metavar="NAME", help="just this script")
    parser.add_argument("-o", "--output", type=Path, default=PAGE, help="the page to write")
    args = parser.parse_args()
    started = time.perf_counter()
    if args.only and args.output.exists():  # re-run some sections, keep the others as written
        kept = sections_of(args.output.read_text(encoding="utf-8"))
        fresh = {b[0]: section(*b) for b in BENCHMARKS if b[0] in args.only}
        parts = [fresh.get(b[0]) or kept.get(b[0]) or section(*b) for b in BENCHMARKS]
        text = page(parts, started, rerun=sorted(fresh))
    else:
        chosen = [b for b in BENCHMARKS if not args.only or b[0] in args.only]
        text = page([section(*benchmark) for benchmark in chosen], started)
    args.output.write_text(text, encoding="utf-8")
    print(f"wrote {args.output}", file=sys.stderr)


if __name__ == "__main__":
    main()
