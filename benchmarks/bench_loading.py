"""Loading profile files, printed as side-by-side tables (not a test: nothing here is asserted).

1. Load time and peak memory of `expected:` and `probability:` profiles of 10^4, 10^5 and 10^6
   numbers (a probability table of 10^6 numbers is 10^5 cells x 10 bins), read three ways: the
   YAML text with PyYAML's pure loader, the same text with libyaml's C loader, and the YAML
   header with its binary companion (`NAME.npz`). Each load runs in a fresh process; peak
   memory is the growth of its maximum resident set over what it held before the load.
2. The navigation schema's compilation from a cold start (`navigate`, totals 0:3000:250, as
   `make demo`), split into reading the modules' profile files, the library's set-up (plugin
   discovery and imports) and compiling, with each loader.

Run: .venv/bin/python benchmarks/bench_loading.py [--quick] [--repeats N]
(`--quick` reads text of 10^6 numbers with the C loader only: the pure loader takes minutes.)
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from tables import machine, table  # benchmarks/tables.py: a script's own folder is on sys.path

from anytime.profiles import ConditionalPerformanceProfile, point_mass
from anytime.profiles import io as profile_io
from anytime.profiles.io import document, profile_file

SIZES = (10_000, 100_000, 1_000_000)
KINDS = ("expected", "probability")
BINS = np.linspace(0, 1, 11)
INPUT_QUALITIES = 10  # the tables are (input quality, time[, bin])
LOADERS = ("pure", "C", "companion")


def profile(kind: str, numbers: int) -> ConditionalPerformanceProfile:
    """A random profile whose table holds `numbers` numbers."""
    rng = np.random.default_rng(0)
    cells = numbers if kind == "expected" else numbers // (len(BINS) - 1)
    shape = (INPUT_QUALITIES, cells // INPUT_QUALITIES)
    grids = [np.linspace(0, 1, INPUT_QUALITIES)]
    time_grid = np.arange(shape[1], dtype=np.float64)
    if kind == "expected":
        mean = rng.random(shape).round(6)
        return ConditionalPerformanceProfile(
            input_grids=grids, time=time_grid, bins=BINS, probability=point_mass(mean, BINS),
            mean=mean, inputs=["x"], module="m",
        )  # fmt: skip
    probability = rng.dirichlet(np.ones(len(BINS) - 1), size=shape).round(6)
    probability /= probability.sum(axis=-1, keepdims=True)
    return ConditionalPerformanceProfile(
        input_grids=grids, time=time_grid, bins=BINS, probability=probability, inputs=["x"],
        module="m",
    )  # fmt: skip


def rss_kib() -> int:
    """This process's peak resident set, in KiB: the kernel's own (VmHWM) where there is one,
    since `ru_maxrss` keeps the parent's peak across the exec that started this process."""
    status = Path("/proc/self/status")
    if status.exists():
        for line in status.read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def use_loader(loader: str) -> None:
    if loader == "pure":
        document.FAST_LOADER = yaml.SafeLoader  # where the loader is read


def child_load(path: str, loader: str) -> dict[str, float]:
    """In the child process: one load, its seconds and its peak memory growth in MiB."""
    use_loader(loader)
    before = rss_kib()
    start = time.perf_counter()
    profile_io.load_profile(path)
    return {"seconds": time.perf_counter() - start, "mib": (rss_kib() - before) / 1024}


def child_navigation(loader: str) -> dict[str, float]:
    """In the child process: the navigation schema's compilation from a cold start, split into
    the library's set-up (plugin discovery, imports), reading its profile files and compiling."""
    from anytime_navigation.resources import data_file

    from anytime.compiler import compile_file
    from anytime.dsl import load_schemas
    from anytime.library import AnytimeLibrary

    use_loader(loader)
    reading = [0.0]
    read_file = profile_file.read_profile_file

    def timed(path: Any) -> Any:
        start = time.perf_counter()
        try:
            return read_file(path)
        finally:
            reading[0] += time.perf_counter() - start

    profile_file.read_profile_file = timed  # what load_profile calls
    start = time.perf_counter()
    library = AnytimeLibrary.default()
    schemas = load_schemas(str(data_file("schemas", "navigation.any")))
    set_up, read_before = time.perf_counter() - start, reading[0]
    compile_file(schemas, library, range(0, 3001, 250), schema="navigate")
    total = time.perf_counter() - start
    return {
        "read": reading[0],
        "set-up": set_up - read_before,
        "compile": total - set_up - (reading[0] - read_before),
        "total": total,
    }


def in_child(*arguments: str) -> dict[str, float]:
    done = subprocess.run(
        [sys.executable, __file__, "--child", *arguments],
        stdout=subprocess.PIPE,
        text=True,
        check=True,
    )
    result: dict[str, float] = json.loads(done.stdout)
    return result


def best(repeats: int, *arguments: str) -> dict[str, float]:
    """The fastest of `repeats` fresh-process runs (its memory the least of theirs)."""
    runs = [in_child(*arguments) for _ in range(repeats)]
    return {key: min(run[key] for run in runs) for key in runs[0]}


def bench_files(quick: bool, repeats: int) -> str:
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for kind in KINDS:
            for numbers in SIZES:
                made = profile(kind, numbers)
                text, pair = Path(folder, "text.yaml"), Path(folder, "pair.yaml")
                profile_io.save_profile(made, pair, companion=True)
                loaders = ["C", "companion"] if quick and numbers >= 1_000_000 else LOADERS
                profile_io.save_profile(made, text, companion=False)
                runs = {}
                for loader in loaders:
                    path = pair if loader == "companion" else text
                    runs[loader] = best(1 if loader == "pure" else repeats, str(path), loader)
                rows.append(row(kind, numbers, text, pair, runs))
    header = ["table", "numbers", "text MiB", "pure s", "C s", "companion s", "pure/C",
              "C/companion", "pure/companion", "peak MiB pure", "C", "companion"]  # fmt: skip
    return table(header, rows)


def row(
    kind: str, numbers: int, text: Path, pair: Path, runs: dict[str, dict[str, float]]
) -> list[str]:
    def seconds(loader: str) -> str:
        return f"{runs[loader]['seconds']:.3f}" if loader in runs else "-"

    def ratio(slow: str, fast: str) -> str:
        if slow not in runs or fast not in runs:
            return "-"
        return f"{runs[slow]['seconds'] / runs[fast]['seconds']:.1f}x"

    def mib(loader: str) -> str:
        return f"{runs[loader]['mib']:.0f}" if loader in runs else "-"

    return [
        f"{kind}:",
        f"{numbers:,}",
        f"{text.stat().st_size / 2**20:.1f}",
        *(seconds(loader) for loader in LOADERS),
        ratio("pure", "C"),
        ratio("C", "companion"),
        ratio("pure", "companion"),
        *(mib(loader) for loader in LOADERS),
    ]


def bench_navigation(repeats: int) -> str:
    rows = []
    results = {loader: best(repeats, "navigation", loader) for loader in ("pure", "C")}
    keys = ("read", "set-up", "compile", "total")
    for loader, result in results.items():
        share = f"{result['read'] / result['total']:.0%}"
        rows.append([f"{loader} loader", *(f"{result[key]:.3f}" for key in keys), share])
    pure, fast = results["pure"], results["C"]
    rows.append(["pure / C", *(f"{pure[key] / fast[key]:.1f}x" for key in keys), ""])
    header = ["navigate, 0:3000:250", "reading profiles s", "library set-up s", "compiling s",
              "total s", "reading"]  # fmt: skip
    return table(header, rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="no pure-loader run at 10^6")
    parser.add_argument("--repeats", type=int, default=3, help="fresh processes per timing")
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        if args.child[0] == "navigation":
            print(json.dumps(child_navigation(args.child[1])))
        else:
            print(json.dumps(child_load(args.child[0], args.child[1])))
        return
    print(f"Machine: {machine()}; PyYAML {yaml.__version__}, libyaml: {yaml.__with_libyaml__}.")
    print(f"Companions are written above {profile_io.COMPANION_THRESHOLD:,} numbers.\n")
    print(bench_files(args.quick, args.repeats))
    print()
    print(bench_navigation(args.repeats))


if __name__ == "__main__":
    main()
