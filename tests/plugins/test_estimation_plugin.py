"""A third party's plugin, end to end: tests/plugins/estimation_plugin (`anytime-estimation`),
installed with pip as a user would install it, found through its entry point, its schemas
compiled against its measured profiles and run on the work clock.

The promise checks compare the compiled expectation at every total of the compiled time grid
with the mean quality that `run_program` delivers on fresh instances (seeds apart from the
profile builder's), scored against the hidden truth as the plugin's problem sets score.
"""

from __future__ import annotations

import importlib.metadata
import math
import os
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from anytime import AnytimeLibrary, CompiledProgram, Context, WorkClock, compile_file, load_schemas
from anytime.library import PluginSource
from anytime.runtime import Budget, ProgramRecord, Status, run_program

SOURCE = Path(__file__).resolve().parent / "estimation_plugin"
SCHEMAS = ("tank-side", "two-tank-side", "labelled-tank-side")
TOTALS = range(0, 41, 4)  # the compiled time grid (ticks), on a lattice of 2 ticks
#: The least error of a compiled expectation itself (see the promise test).
PROFILE_ERROR = 0.001
RUNS = 300  # fresh instances per total
#: The totals the fast test compares adaptive with fixed runs at (the slow one: every total).
ADAPTIVE_TOTALS = (20, 32)
SEED = 20_240_601  # root of the instances' seeds: SeedSequence([SEED, schema, total, run])


class Installed:
    """The plugin as installed: its package (imported from the install), its library and its
    compiled schemas."""

    def __init__(self, package: ModuleType, library: AnytimeLibrary, site: Path) -> None:
        self.package = package
        self.library = library
        self.site = site
        self.names = library.names()  # before compiling: compile_file adds the schemas to it
        schemas = load_schemas(package.SCHEMA_FILE, library.known_functions())
        compiled = compile_file(schemas, library, TOTALS, resolution=2)
        self.programs = {program.name: program for program in compiled}


def _pip_install(source: Path, target: Path) -> subprocess.CompletedProcess[str]:
    """Install a plugin package into `target` with pip, without its dependencies (as
    tests/test_library.py installs the toy plugin)."""
    command = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index"]
    try:  # without build isolation when this environment's setuptools can build wheels
        version = importlib.metadata.version("setuptools")
        if tuple(map(int, version.split(".")[:2])) >= (70, 1):
            command.append("--no-build-isolation")
        else:
            command.remove("--no-index")  # pip fetches a build backend from the index
    except importlib.metadata.PackageNotFoundError:
        command.remove("--no-index")
    command += ["--target", str(target), str(source)]
    env = os.environ | {"PIP_DISABLE_PIP_VERSION_CHECK": "1"}
    return subprocess.run(command, capture_output=True, text=True, env=env, check=False)


@pytest.fixture(scope="module")  # gone before the other tests: it is on sys.path
def installed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Installed]:
    root = tmp_path_factory.mktemp("estimation")
    source = root / "source"  # pip builds in place: keep the work tree clean
    shutil.copytree(SOURCE, source, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    site = root / "site"
    done = _pip_install(source, site)
    if done.returncode != 0 and "No matching distribution found for setuptools" in done.stderr:
        pytest.skip("pip cannot get a build backend for the plugin: no package index")
    assert done.returncode == 0, done.stderr
    entry_points = [
        ep
        for dist in importlib.metadata.distributions(path=[str(site)])
        for ep in dist.entry_points
        if ep.group == "anytime.plugins"
    ]
    sys.path.insert(0, str(site))
    try:
        library = AnytimeLibrary([PluginSource(entry_points=entry_points)])
        import anytime_estimation

        yield Installed(anytime_estimation, library, site)
    finally:
        sys.path.remove(str(site))
        for name in [n for n in sys.modules if n.split(".")[0] == "anytime_estimation"]:
            del sys.modules[name]


# --- the package --------------------------------------------------------------------------


def test_the_plugin_is_found_through_its_entry_point(installed: Installed) -> None:
    library = installed.library
    assert library.problems == ()
    assert [p.name for p in library.plugins] == ["estimation"]
    assert Path(str(installed.package.__file__)).is_relative_to(installed.site)
    timed = ["cube-side", "estimate-volume", "joint-side", "read-label"]
    assert installed.names == (
        *("cube-side", "estimate-volume", "has-label?", "has-sensor?", "joint-side"),
        "read-label",
    )
    for name in installed.names:
        assert library[name].origin == "plugin 'estimation' (anytime_estimation:PLUGIN)"
    for name in timed:
        profile = library.profile(name)
        assert profile is not None and profile.module == name and profile.time_unit == "ticks"
        assert library.measurement(name) is library.plugins[0].problem_sets[name]
    assert {library[n].module.reports for n in timed} == {"estimate", "true"}  # type: ignore[union-attr]


@pytest.mark.slow
@pytest.mark.parametrize("module", ["estimate-volume", "read-label", "cube-side", "joint-side"])
def test_every_shipped_profile_is_what_anytime_profile_measures(
    installed: Installed, tmp_path: Path, module: str
) -> None:
    """As the plugin's README regenerates them, byte for byte."""
    _measure_and_compare(installed, module, tmp_path)


def _measure_and_compare(installed: Installed, module: str, tmp_path: Path) -> None:
    out = tmp_path / f"{module}.yaml"
    env = os.environ | {"PYTHONPATH": str(installed.site)}
    command = [sys.executable, "-m", "anytime", "profile", module, "--trials", "2000"]
    command += ["--workers", "2", "--seed", "0", "--quiet", "-o", str(out)]
    done = subprocess.run(command, capture_output=True, text=True, env=env, check=False)
    assert done.returncode == 0, done.stderr
    shipped = SOURCE / "anytime_estimation" / "profiles" / f"{module}.yaml"
    assert out.read_bytes() == shipped.read_bytes()


# --- the problem sets ---------------------------------------------------------------------


@pytest.mark.parametrize("q", [0.0, 0.25, 0.5, 0.75, 0.9, 1.0])
def test_an_input_of_quality_q_is_an_estimate_that_far_off(installed: Installed, q: float) -> None:
    est = installed.package
    rng = np.random.default_rng([SEED, 99])
    for _ in range(50):
        instance = est.VolumeEstimates().instance(rng, (q,))
        (volume,) = instance.args
        assert volume.quality == q
        truth = instance.reference**3
        if q == 0:  # the estimator's quality is 0 only when it has no result
            assert volume.value is None
        else:
            assert est.quality(volume.value, truth) == pytest.approx(q, abs=1e-9)


def test_the_estimator_is_what_the_problem_sets_assume(installed: Installed) -> None:
    """Its quality is 0 only without a result (its readings lie in [0, 2 V], so its relative
    error is below 1), and its error is as often above as below: so an input of quality q is
    the volume off by 1 - q either way, as `estimate_of` makes it."""
    est = installed.package
    rng = np.random.default_rng([SEED, 98])
    signs = []
    for allocation in (0.0, 1.0, 2.0, 8.0):
        for _ in range(200):
            tank = est.Tank(float(rng.uniform(*est.VOLUMES)), int(rng.integers(2**32)))
            result = est.estimate_volume(Context(allocation), tank)
            if allocation < est.BATCH_TICKS:
                assert result is None
                continue
            assert 0 < est.quality(result.value, tank.volume) <= 1
            signs.append(np.sign(result.value - tank.volume))
    assert abs(np.mean(signs)) < 3 / math.sqrt(len(signs))


@pytest.mark.parametrize("module", ["cube-side", "joint-side"])
def test_the_self_estimates_are_lower_bounds_of_the_true_quality(
    installed: Installed, module: str
) -> None:
    measurement = installed.library.measurement(module)
    rng = np.random.default_rng([SEED, 97])
    checked = 0
    for q in (0.25, 0.5, 0.9, 1.0):
        for _ in range(40):
            instance = measurement.problems.instance(rng, (q,) * len(measurement.grid.input_grids))
            function = installed.library[module].module
            assert function is not None
            ctx = Context(40.0)
            for result in function(ctx, *instance.args):
                true = measurement.problems.score(instance, result.value)
                assert result.quality <= true + 1e-12
                checked += 1
                if ctx.expired:
                    break
    assert checked > 1000


# --- promises, end to end -----------------------------------------------------------------


def _instance(est: ModuleType, schema: str, rng: np.random.Generator) -> tuple[list[Any], float]:
    """A fresh problem for `schema`: its inputs and the true side."""
    if schema == "two-tank-side":
        a, b = est.Tank(*_draw(est, rng)), est.Tank(*_draw(est, rng))
        return [a, b], (a.volume + b.volume) ** (1 / 3)
    volume, seed = _draw(est, rng)
    if schema == "labelled-tank-side":  # both preconditions hold, as the compiler assumes
        readable = bool(rng.random() < est.READABLE)
        tank = est.Tank(volume, seed, label=volume, label_readable=readable)
    else:
        tank = est.Tank(volume, seed)
    return [tank], volume ** (1 / 3)


def _draw(est: ModuleType, rng: np.random.Generator) -> tuple[float, int]:
    return float(rng.uniform(*est.VOLUMES)), int(rng.integers(2**32))


class Runs:
    """`RUNS` runs of a program at one total: the delivered qualities and the records."""

    def __init__(self, qualities: list[float], records: list[ProgramRecord]) -> None:
        self.qualities = np.array(qualities)
        self.records = records

    @property
    def mean(self) -> float:
        return float(self.qualities.mean())

    @property
    def se(self) -> float:
        return float(self.qualities.std(ddof=1) / math.sqrt(len(self.qualities)))


_CACHE: dict[tuple[str, int, bool], Runs] = {}


def _runs(installed: Installed, schema: str, j: int, adaptive: bool = False) -> Runs:
    key = (schema, j, adaptive)
    if key not in _CACHE:
        est = installed.package
        compiled = installed.programs[schema]
        total = float(compiled.profile.time[j])
        qualities, records = [], []
        for i in range(RUNS):
            rng = np.random.default_rng([SEED, SCHEMAS.index(schema), j, i])
            inputs, truth = _instance(est, schema, rng)
            record = run_program(
                compiled, inputs, Budget(total, clock=WorkClock()), adaptive=adaptive
            )
            value = record.result.value if record.result is not None else None
            qualities.append(est.quality(value, truth))
            records.append(record)
        _CACHE[key] = Runs(qualities, records)
    return _CACHE[key]


def _totals(compiled: CompiledProgram) -> list[int]:
    return list(range(len(compiled.profile.time)))


@pytest.mark.parametrize("schema", SCHEMAS)
def test_the_compiled_schemas_cover_the_grid(installed: Installed, schema: str) -> None:
    compiled = installed.programs[schema]
    assert compiled.profile.time.tolist() == list(TOTALS)
    assert compiled.expected.shape == (len(TOTALS),)  # no quality-carrying program input
    assert compiled.allocator == "exhaustive" and compiled.warnings == ()


@pytest.mark.parametrize("schema", SCHEMAS)
def test_each_total_delivers_what_the_compiler_expects(installed: Installed, schema: str) -> None:
    """At every total, the realised mean against the compiled expectation, in standard errors
    of the mean (|diff| / (1 / RUNS) where every run scored the same): within 2 at every total
    but at most 2 of them (at 5% each, 2 of the 9 or so totals where quality varies may fall
    outside 2 by chance alone), and within 3 at all. The compiled expectation has an error of
    its own, which the realised standard error does not see: the profiles' sampling error and
    their interpolation between measured input qualities (measured at up to 0.003 on the
    two-input profile); it is taken as at least `PROFILE_ERROR`. At T = 0 both are exactly 0."""
    compiled = installed.programs[schema]
    assert compiled.expected[0] == 0.0
    assert _runs(installed, schema, 0).qualities.tolist() == [0.0] * RUNS
    report = []
    for j in _totals(compiled):
        runs = _runs(installed, schema, j)
        promised = float(compiled.expected[j])
        se = math.hypot(runs.se if runs.se > 0 else 1 / RUNS, PROFILE_ERROR)
        z = abs(runs.mean - promised) / se
        report.append(
            (z, f"T={compiled.profile.time[j]:g}: compiled {promised:.4f}, realised"
                f" {runs.mean:.4f} (se {runs.se:.4f}, {z:.2f} se)")
        )  # fmt: skip
    outside = [line for z, line in report if z > 2]
    assert len(outside) <= 2, outside
    assert [line for z, line in report if z > 3] == []


@pytest.mark.parametrize("schema", SCHEMAS)
def test_anytime_verify_passes_on_the_plugins_own_program_problems(
    installed: Installed, schema: str
) -> None:
    """The plugin declares, per schema, the problems its promise is for (`program_problems`):
    `anytime.verify` on them passes at every total, T = 0 included, and no run is over."""
    from anytime import verify

    declared = installed.library.program_problems(schema)
    assert declared.time_grid == tuple(float(t) for t in TOTALS) and declared.resolution == 2
    checked = verify(installed.programs[schema], declared, runs=200)
    assert checked.passed, [
        (c.total, round(c.promised, 4), round(c.realised, 4), round(c.z, 2)) for c in checked.failed
    ]
    assert [c.total for c in checked.budgets] == [float(t) for t in TOTALS]


@pytest.mark.parametrize("schema", SCHEMAS)
def test_no_run_ends_over_its_total(installed: Installed, schema: str) -> None:
    compiled = installed.programs[schema]
    over = []
    for j in _totals(compiled):
        total = float(compiled.profile.time[j])
        used = [r.time_used for r in _runs(installed, schema, j).records]
        late = [u for u in used if u > total]
        if late:
            over.append(f"T={total:g}: {len(late)} of {RUNS} runs, up to {max(late):g}")
    assert over == []


@pytest.mark.parametrize("schema", SCHEMAS)
def test_adaptive_runs_are_never_worse_than_fixed(installed: Installed, schema: str) -> None:
    _compare_adaptive(installed, schema, ADAPTIVE_TOTALS)


@pytest.mark.slow
@pytest.mark.parametrize("schema", SCHEMAS)
def test_adaptive_runs_are_never_worse_than_fixed_at_any_total(
    installed: Installed, schema: str
) -> None:
    _compare_adaptive(installed, schema, TOTALS)


def _compare_adaptive(installed: Installed, schema: str, totals: Iterable[int]) -> None:
    """On the same instances, adaptive re-allocation's mean is never below the fixed
    allocation's by more than 2 standard errors of the paired difference (1 / RUNS where the
    difference is the same in every run)."""
    compiled = installed.programs[schema]
    worse = []
    for total in totals:
        j = list(TOTALS).index(total)
        fixed, adaptive = _runs(installed, schema, j), _runs(installed, schema, j, adaptive=True)
        difference = adaptive.qualities - fixed.qualities
        se = float(difference.std(ddof=1) / math.sqrt(RUNS))
        if difference.mean() < -(2 * se if se > 0 else 1 / RUNS):
            worse.append(f"T={total}: {fixed.mean:.4f} -> {adaptive.mean:.4f} (se {se:.4f})")
    assert compiled.profile.time.tolist() == list(TOTALS)
    assert worse == []


# --- no results ---------------------------------------------------------------------------


def _statuses(record: ProgramRecord) -> list[tuple[str, str, str | None]]:
    return [(r.module, r.status.value, r.error) for r in record.records]


@pytest.mark.parametrize("adaptive", [False, True])
def test_a_module_whose_input_has_no_result_is_not_called(
    installed: Installed, adaptive: bool
) -> None:
    est = installed.package
    broken = est.Tank(100.0, 1, has_sensor=False)  # the estimator has nothing to read
    record = run_program(
        installed.programs["tank-side"],
        [broken],
        Budget(40.0, clock=WorkClock()),
        adaptive=adaptive,
    )
    assert record.result is None and record.status == Status.NO_RESULT
    assert _statuses(record) == [
        ("estimate-volume", "no-result", None),
        ("cube-side", "no-result", "not run: its input from 'estimate-volume' has no result"),
    ]
    assert [r.time_used for r in record.records] == [0.0, 0.0]
    assert record.time_used == 0.0


def test_a_two_input_module_with_one_input_missing_is_not_called(installed: Installed) -> None:
    est = installed.package
    tanks = [est.Tank(100.0, 1), est.Tank(50.0, 2, has_sensor=False)]
    record = run_program(
        installed.programs["two-tank-side"], tanks, Budget(40.0, clock=WorkClock())
    )
    assert record.result is None and record.status == Status.NO_RESULT
    assert _statuses(record)[1:] == [
        ("estimate-volume", "no-result", None),
        ("joint-side", "no-result", "not run: its input from 'estimate-volume' has no result"),
    ]
    assert record.records[0].status == Status.COMPLETED


@pytest.mark.parametrize("adaptive", [False, True])
def test_a_best_of_whose_preconditions_are_all_false_is_a_no_result(
    installed: Installed, adaptive: bool
) -> None:
    est = installed.package
    bare = est.Tank(100.0, 1, has_sensor=False)  # no sensor and no label
    record = run_program(
        installed.programs["labelled-tank-side"],
        [bare],
        Budget(40.0, clock=WorkClock()),
        adaptive=adaptive,
    )
    assert record.result is None and record.status == Status.NO_RESULT
    assert _statuses(record) == [
        ("has-sensor?", "completed", None),
        ("has-label?", "completed", None),
        (
            "best-of",
            "no-result",
            "schema 'labelled-tank-side': no alternative of best-of 'volume' is applicable"
            " (all 2 preconditions are false)",
        ),
        ("cube-side", "no-result", "not run: its input from 'best-of' has no result"),
    ]
    assert record.time_used == 0.0


@pytest.mark.parametrize(
    ("tank", "source"),
    [
        (lambda est: est.Tank(100.0, 1, has_sensor=False, label=100.0), "read-label"),
        (lambda est: est.Tank(100.0, 1), "estimate-volume"),
    ],
)
def test_a_best_of_runs_the_applicable_alternative_with_all_its_time(
    installed: Installed, tank: Callable[[ModuleType], Any], source: str
) -> None:
    compiled = installed.programs["labelled-tank-side"]
    record = run_program(compiled, [tank(installed.package)], Budget(40.0, clock=WorkClock()))
    assert record.result is not None and record.status in (
        Status.COMPLETED,
        Status.CONTRACT_EXPIRED,
    )
    ran = [r.module for r in record.records if r.module in ("estimate-volume", "read-label")]
    assert ran == [source]
    planned = compiled.allocation_at([], 40.0)
    given = dict(zip(compiled.modules, record.allocations, strict=True))
    shares = dict(zip(compiled.modules, planned, strict=True))
    assert given[source] == shares["estimate-volume"] + shares["read-label"]
