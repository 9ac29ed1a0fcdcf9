"""The anytime library: lookup, its sources, clashes, lazy profiles and installed plugins."""

import importlib.metadata
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import attrs
import pytest
from conftest import Cli

import anytime.library
from anytime import (
    REGISTRY,
    AnytimeLibrary,
    LibraryError,
    PluginSource,
    ProfileDirectory,
    ProfileError,
    Registry,
    RegistrySource,
    Result,
    SchemaError,
    UnknownModuleError,
    contract,
    elementary,
    interruptible,
    parse_schemas,
)
from anytime.library import PLUGIN_GROUP
from anytime.profiles import Exponential, tabulate
from anytime.profiles.io import save_profile

TOY_PLUGIN = Path(__file__).resolve().parent / "plugins" / "toy_plugin"
HERE = f"python module {__name__}"

FIND_PATH_PROFILE = tabulate(
    lambda t, q: q * t / 400,
    time=[0, 100, 200, 400],
    bins=[0.0, 0.25, 0.5, 0.75, 1.0],
    input_grids=[[0.5, 1.0]],
    inputs=["domain"],
    module="find-path",
)
VISION_PROFILE = tabulate(Exponential(0.05), time=[0, 10, 20], module="get-domain-description")


@pytest.fixture
def registry() -> Registry:
    """A fresh registry with a planner (profile in memory) and an elementary function."""
    fresh = Registry()

    @interruptible("find-path", inputs=["domain"], profile=FIND_PATH_PROFILE, registry=fresh)
    def find_path(ctx: Any, start: Any, goal: Any, domain: Any) -> Iterator[Result]:
        yield Result(None, 0.0)

    @elementary(registry=fresh)
    def make_goal(x: Any, y: Any) -> Any:
        return (x, y)

    return fresh


@pytest.fixture
def profiles(tmp_path: Path) -> Path:
    """A directory of two profile files."""
    directory = tmp_path / "profiles"
    directory.mkdir()
    save_profile(FIND_PATH_PROFILE, directory / "find-path.yaml")
    save_profile(VISION_PROFILE, directory / "vision.yaml")
    (directory / "notes.txt").write_text("not a profile")
    return directory


@pytest.fixture
def clean_registry() -> Iterator[Registry]:
    """The process-wide registry, rid afterwards of what plugins imported by a test added."""
    before = {module.name for module in REGISTRY}
    yield REGISTRY
    for module in list(REGISTRY):
        if module.name not in before:
            REGISTRY.remove(module.name)
    for name in list(sys.modules):
        if name.partition(".")[0] in ("toy_anytime_plugin", "nested_plugin"):
            del sys.modules[name]


class FakeEntryPoint:
    """What the library reads of an entry point: name, value, and load() giving `plugin`."""

    group = PLUGIN_GROUP

    def __init__(self, name: str, value: str, plugin: Any = None, error: Exception | None = None):
        self.name, self.value, self.plugin, self.error = name, value, plugin, error

    def load(self) -> Any:
        if self.error is not None:
            raise self.error
        return self.plugin


def _raise(error: Exception) -> Callable[..., Any]:
    def fail(*args: Any) -> Any:
        raise error

    return fail


# --- lookup ------------------------------------------------------------------------------------


def test_lookup_gives_the_module_its_profile_and_where_it_came_from(registry: Registry) -> None:
    library = AnytimeLibrary([RegistrySource(registry)])
    entry = library["find-path"]
    assert entry.module is registry.get("find-path")
    assert entry.profile is FIND_PATH_PROFILE
    assert (entry.name, entry.kind, entry.inputs) == ("find-path", "interruptible", ("domain",))
    assert (entry.parameters, entry.arity) == (("start", "goal", "domain"), 3)
    assert entry.origin == HERE
    assert library.profile("find-path") is FIND_PATH_PROFILE
    goal = library["make-goal"]
    assert (goal.kind, goal.inputs, goal.arity, goal.profile) == ("elementary", ("x", "y"), 2, None)


def test_names_are_case_insensitive(registry: Registry) -> None:
    library = AnytimeLibrary([RegistrySource(registry)])
    assert library["Find-PATH"] is library["find-path"]
    assert "FIND-path" in library
    assert "find_path" not in library
    assert 3 not in library
    assert library.get("MAKE-GOAL") is library["make-goal"]
    assert library.get("fly") is None


def test_names_iteration_and_known_functions(registry: Registry, tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    library = AnytimeLibrary([RegistrySource(registry), ProfileDirectory(tmp_path / "empty")])
    assert library.names() == ("find-path", "make-goal")
    assert [entry.name for entry in library] == ["find-path", "make-goal"]
    assert len(library) == 2
    assert library.known_functions() == {"find-path": 3, "make-goal": 2}
    assert library.problems == ()
    assert repr(library) == "<AnytimeLibrary of 2 modules from 2 sources>"


def test_a_parameter_with_a_default_leaves_the_arity_unchecked() -> None:
    fresh = Registry()

    @contract(registry=fresh)
    def search(ctx: Any, start: Any, goal: Any, level: int = 0) -> Result:
        return Result(None, 1.0)

    assert AnytimeLibrary([RegistrySource(fresh)]).known_functions() == {"search": None}


def test_an_unknown_name_suggests_the_closest(registry: Registry) -> None:
    library = AnytimeLibrary([RegistrySource(registry)])
    with pytest.raises(UnknownModuleError) as caught:
        library["find-pth"]
    assert str(caught.value) == "no module named 'find-pth'; did you mean 'find-path'?"
    assert isinstance(caught.value, KeyError)
    assert isinstance(caught.value, LibraryError)
    with pytest.raises(
        UnknownModuleError, match="^no module named 'FIND-PTH'; did you mean 'find-path'"
    ):
        library["FIND-PTH"]
    with pytest.raises(UnknownModuleError, match=r"^no module named 'zz' \(known: find-path, "):
        library["zz"]


# --- profile directories ---------------------------------------------------------------------


def test_a_profile_directory_gives_profile_only_entries(profiles: Path) -> None:
    library = AnytimeLibrary([ProfileDirectory(profiles)])
    assert library.names() == ("find-path", "get-domain-description")
    entry = library["find-path"]
    assert entry.module is None
    assert entry.origin == f"profile file {profiles / 'find-path.yaml'}"
    assert entry.profile_file == profiles / "find-path.yaml"
    assert (entry.kind, entry.inputs, entry.parameters, entry.arity) == (
        "interruptible",
        ("domain",),
        (),
        None,
    )
    assert entry.profile == FIND_PATH_PROFILE
    assert library["get-domain-description"].origin == f"profile file {profiles / 'vision.yaml'}"
    assert library.known_functions() == {"find-path": None, "get-domain-description": None}


def test_a_missing_or_non_directory_profile_directory_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(LibraryError) as caught:
        AnytimeLibrary([ProfileDirectory(tmp_path / "nope")])
    assert str(caught.value) == f"profile directory '{tmp_path / 'nope'}' does not exist"
    (tmp_path / "file.yaml").write_text("", encoding="utf-8")
    with pytest.raises(LibraryError) as caught:
        AnytimeLibrary([ProfileDirectory(tmp_path / "file.yaml")])
    assert str(caught.value) == f"profile directory '{tmp_path / 'file.yaml'}' is not a directory"


def test_a_malformed_file_in_a_profile_directory_names_the_file(profiles: Path) -> None:
    (profiles / "bad.yaml").write_text("format: anytime-profile/9\n")
    with pytest.raises(ProfileError) as caught:
        AnytimeLibrary([ProfileDirectory(profiles)])
    assert str(caught.value) == (
        f"{profiles / 'bad.yaml'}: format: unknown format version "
        "(expected 'anytime-profile/1', got 'anytime-profile/9')"
    )


# --- clashes -----------------------------------------------------------------------------------


def test_a_name_defined_by_two_sources_names_both_origins(
    registry: Registry, profiles: Path
) -> None:
    with pytest.raises(LibraryError) as caught:
        AnytimeLibrary([RegistrySource(registry), ProfileDirectory(profiles)])
    assert str(caught.value) == (
        f"module 'find-path' is defined twice: in {HERE} and in "
        f"profile file {profiles / 'find-path.yaml'}"
    )


def test_two_different_modules_of_one_name_clash(registry: Registry) -> None:
    other = Registry()

    @interruptible("Find-Path", inputs=[], registry=other)
    def planner(ctx: Any) -> Iterator[Result]:
        yield Result(None, 1.0)

    plugin = FakeEntryPoint("nav", "nav.plan:modules", lambda: [planner])
    with pytest.raises(LibraryError) as caught:
        AnytimeLibrary([RegistrySource(registry), PluginSource([plugin], registry=other)])
    assert str(caught.value) == (
        f"module 'find-path' is defined twice: in {HERE} and in plugin 'nav' (nav.plan:modules)"
    )


@pytest.mark.parametrize("plugin_first", [True, False], ids=["plugin-first", "registry-first"])
def test_one_module_reached_through_two_sources_is_one_entry_of_the_plugin(
    registry: Registry, plugin_first: bool
) -> None:
    find_path = registry.get("find-path")
    plugin = PluginSource([FakeEntryPoint("nav", "nav:modules", lambda: [find_path])], registry)
    sources = [plugin, RegistrySource(registry)]
    library = AnytimeLibrary(sources if plugin_first else sources[::-1])
    assert library.names() == ("find-path", "make-goal")
    assert library["find-path"].module is find_path
    assert library["find-path"].origin == "plugin 'nav' (nav:modules)"
    assert library["make-goal"].origin == HERE
    twice = AnytimeLibrary([RegistrySource(registry), RegistrySource(registry)])
    assert twice.names() == ("find-path", "make-goal")


# --- profiles read on first use ----------------------------------------------------------------


def test_a_profile_file_is_read_when_first_needed_then_cached(tmp_path: Path) -> None:
    path = tmp_path / "find-path.yaml"
    fresh = Registry()

    @interruptible("find-path", inputs=["domain"], profile=path, registry=fresh)
    def find_path(ctx: Any, domain: Any) -> Iterator[Result]:
        yield Result(None, 1.0)

    library = AnytimeLibrary([RegistrySource(fresh)])  # the file does not exist yet
    entry = library["find-path"]
    assert entry.profile_file == path
    save_profile(FIND_PATH_PROFILE, path)
    first = entry.profile
    assert first == FIND_PATH_PROFILE
    path.unlink()
    assert entry.profile is first


def _module_with_profile(path: Path, inputs: tuple[str, ...] = ("domain",)) -> AnytimeLibrary:
    fresh = Registry()

    @interruptible("find-path", inputs=list(inputs), profile=path, registry=fresh)
    def find_path(ctx: Any, domain: Any, other: Any) -> Iterator[Result]:
        yield Result(None, 1.0)

    return AnytimeLibrary([RegistrySource(fresh)])


def test_a_missing_profile_file_is_reported_when_needed(tmp_path: Path) -> None:
    library = _module_with_profile(tmp_path / "nope.yaml")
    with pytest.raises(ProfileError) as caught:
        library.profile("find-path")
    assert str(caught.value) == (
        f"{tmp_path / 'nope.yaml'}: no such profile file (the profile of module 'find-path',"
        f" from {HERE})"
    )


def test_a_malformed_profile_file_is_reported_when_needed(tmp_path: Path) -> None:
    path = tmp_path / "find-path.yaml"
    path.write_text("format: anytime-profile/1\ntime: [0, 1]\n")
    library = _module_with_profile(path)
    entry = library["find-path"]
    with pytest.raises(ProfileError) as caught:
        _ = entry.profile
    assert str(caught.value) == (
        f"{path}: quality_bins: missing field (expected a list of bin edges, got nothing)"
    )


@pytest.mark.parametrize(
    ("profile", "inputs", "message"),
    [
        (
            tabulate(Exponential(0.1), time=[0, 1], module="vision"),
            ("domain",),
            "module: expected 'find-path' (the module it is the profile of), got 'vision'",
        ),
        (
            tabulate(Exponential(0.1), time=[0, 1], module="find-path", kind="contract"),
            (),
            "kind: expected 'interruptible' (module 'find-path' is interruptible), got 'contract'",
        ),
        (
            tabulate(Exponential(0.1), time=[0, 1], module="find-path"),
            ("domain",),
            "inputs: expected [domain] (the inputs of module 'find-path'), got no input axis",
        ),
        (FIND_PATH_PROFILE, ("other",), "inputs: expected [other] (the inputs of module "),
        (
            tabulate(lambda t, q: q, time=[0, 1], input_grids=[[0, 1]], module="find-path"),
            ("domain", "other"),
            "inputs: expected [domain, other] (the inputs of module 'find-path'),"
            " got 1 unnamed input axis",
        ),
    ],
    ids=["other-module", "other-kind", "fewer-axes", "other-input-name", "unnamed-axes"],
)
def test_a_profile_file_must_describe_its_module(
    tmp_path: Path, profile: Any, inputs: tuple[str, ...], message: str
) -> None:
    path = tmp_path / "find-path.yaml"
    save_profile(profile, path)
    library = _module_with_profile(path, inputs)
    with pytest.raises(ProfileError) as caught:
        library.profile("find-path")
    assert str(caught.value).startswith(f"{path}: {message}")


def test_an_in_memory_profile_must_have_one_axis_per_input() -> None:
    fresh = Registry()

    @interruptible("plan", profile=FIND_PATH_PROFILE, registry=fresh)
    def plan(ctx: Any, a: Any, b: Any) -> Iterator[Result]:
        yield Result(None, 1.0)

    with pytest.raises(ProfileError) as caught:
        AnytimeLibrary([RegistrySource(fresh)]).profile("plan")
    assert str(caught.value) == (
        f"module 'plan' ({HERE}): profile: inputs: expected [a, b] (the inputs of module 'plan'),"
        " got [domain]"
    )


# --- the DSL checks calls against the library ----------------------------------------------


def test_known_functions_report_unknown_functions_at_the_call(
    registry: Registry, profiles: Path
) -> None:
    library = AnytimeLibrary([ProfileDirectory(profiles), RegistrySource(Registry())])
    text = (
        "(defschema navigate (start goal sensor)\n"
        "  (setf domain (get-domain-descripton sensor))\n"
        "  (find-path start goal domain))\n"
    )
    with pytest.raises(SchemaError) as caught:
        parse_schemas(text, "nav.any", library.known_functions())
    assert str(caught.value) == (
        "nav.any:2:17: error: unknown function 'get-domain-descripton';"
        " did you mean 'get-domain-description'?\n"
        "    (setf domain (get-domain-descripton sensor))\n"
        "                  ^~~~~~~~~~~~~~~~~~~~~"
    )
    modules = AnytimeLibrary([RegistrySource(registry)])
    with pytest.raises(SchemaError) as caught:
        parse_schemas("(defschema p (a)\n  (Find-Path a))\n", "p.any", modules.known_functions())
    assert str(caught.value).splitlines()[0] == (
        "p.any:2:4: error: function 'find-path' takes 3 arguments, got 1"
    )


# --- plugins -----------------------------------------------------------------------------------


def test_plugins_load_from_entry_points_and_broken_ones_are_reported(
    monkeypatch: pytest.MonkeyPatch, clean_registry: Registry
) -> None:
    monkeypatch.syspath_prepend(str(TOY_PLUGIN))
    installed = [
        importlib.metadata.EntryPoint("toy", "toy_anytime_plugin", PLUGIN_GROUP),
        importlib.metadata.EntryPoint(
            "toy-extra", "toy_anytime_plugin.extra:modules", PLUGIN_GROUP
        ),
        importlib.metadata.EntryPoint("broken", "toy_anytime_plugin.broken", PLUGIN_GROUP),
        importlib.metadata.EntryPoint("missing", "no_such_plugin:modules", PLUGIN_GROUP),
    ]

    def entry_points(**selection: Any) -> list[importlib.metadata.EntryPoint]:
        assert selection == {"group": PLUGIN_GROUP}
        return installed

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)
    before = set(clean_registry)
    library = AnytimeLibrary.default()
    assert library.problems == (
        "plugin 'broken' (toy_anytime_plugin.broken): ModuleNotFoundError: "
        "No module named 'nope_not_installed'",
        "plugin 'missing' (no_such_plugin:modules): ModuleNotFoundError: "
        "No module named 'no_such_plugin'",
    )
    assert set(library.names()) == {m.name for m in before} | {"toy-count", "toy-halve"}
    toy = library["toy-count"]
    assert toy.origin == "plugin 'toy' (toy_anytime_plugin)"
    assert toy.module is clean_registry.get("toy-count")  # its import registered it too
    assert toy.module is not None and toy.module.origin == "python module toy_anytime_plugin"
    assert (toy.kind, toy.inputs, toy.arity) == ("interruptible", ("data",), 2)
    # Counting to a limit drawn from 50..149: at 50 ticks, the mean of min(1, 50 / limit).
    expected = sum(min(1.0, 50 / limit) for limit in range(50, 150)) / 100
    assert toy.profile is not None
    assert toy.profile.expected([[1.0]], [50])[0] == pytest.approx(expected)
    halve = library["toy-halve"]
    assert halve.origin == "plugin 'toy-extra' (toy_anytime_plugin.extra:modules)"
    assert "toy-halve" not in clean_registry
    assert AnytimeLibrary.default(plugins=False).get("toy-halve") is None


def test_every_way_a_plugin_can_fail_is_one_line_naming_it(registry: Registry) -> None:
    find_path = registry.get("find-path")
    plugins = [
        FakeEntryPoint("good", "good:modules", lambda: iter([find_path, find_path])),
        FakeEntryPoint("raises", "bad:make", _raise(RuntimeError("no licence\nsorry"))),
        FakeEntryPoint("junk", "bad:junk", lambda: [find_path, 42]),
        FakeEntryPoint("number", "bad:NUMBER", 42),
        FakeEntryPoint("import", "bad", error=ImportError("cannot import name 'x' from 'y'")),
        FakeEntryPoint("single", "one:module", registry.get("make-goal")),
    ]
    library = AnytimeLibrary([PluginSource(plugins, registry=Registry())])
    assert library.problems == (
        "plugin 'raises' (bad:make): RuntimeError: no licence sorry",
        "plugin 'junk' (bad:junk): TypeError: expected anytime modules, got 42 (int)",
        "plugin 'number' (bad:NUMBER): TypeError: expected a Plugin, a function returning one, a"
        " Python module or anytime modules, got int",
        "plugin 'import' (bad): ImportError: cannot import name 'x' from 'y'",
    )
    assert {entry.name: entry.origin for entry in library} == {
        "find-path": "plugin 'good' (good:modules)",
        "make-goal": "plugin 'single' (one:module)",
    }


def test_a_plugin_module_owns_what_its_import_registered(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, clean_registry: Registry
) -> None:
    package = tmp_path / "nested_plugin"
    package.mkdir()
    (package / "__init__.py").write_text("from nested_plugin import planners  # noqa: F401\n")
    (package / "planners.py").write_text(
        "from anytime import REGISTRY, Result, interruptible\n\n"
        "@interruptible('nested-plan', inputs=[], registry=REGISTRY)\n"
        "def plan(ctx, goal):\n"
        "    yield Result(goal, 1.0)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    plugin = importlib.metadata.EntryPoint("nested", "nested_plugin", PLUGIN_GROUP)
    library = AnytimeLibrary([PluginSource([plugin]), RegistrySource()])
    assert library.problems == ()
    assert library["nested-plan"].origin == "plugin 'nested' (nested_plugin)"
    assert "nested-plan" in clean_registry


def _pip_install(source: Path, target: Path) -> subprocess.CompletedProcess[str]:
    """Install a plugin package into `target` with pip, as a user would (without its deps)."""
    command = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index"]
    try:  # without build isolation when this environment's setuptools can build wheels
        import setuptools

        if tuple(map(int, setuptools.__version__.split(".")[:2])) >= (70, 1):
            command.append("--no-build-isolation")
        else:
            command.remove("--no-index")  # pip fetches a build backend from the index
    except ImportError:
        command.remove("--no-index")
    command += ["--target", str(target), str(source)]
    env = os.environ | {"PIP_DISABLE_PIP_VERSION_CHECK": "1"}
    return subprocess.run(command, capture_output=True, text=True, env=env, check=False)


def test_an_installed_plugin_package_is_discovered(tmp_path: Path) -> None:
    source = tmp_path / "toy_plugin"  # pip builds in place: keep the work tree clean
    shutil.copytree(TOY_PLUGIN, source, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    target = tmp_path / "site"
    installed = _pip_install(source, target)
    if installed.returncode != 0 and "No matching distribution found for setuptools" in (
        installed.stderr
    ):
        pytest.skip("pip cannot get a build backend for the toy plugin: no package index")
    assert installed.returncode == 0, installed.stderr
    assert (target / "toy_anytime_plugin" / "__init__.py").is_file()
    pythonpath = os.pathsep.join([str(target), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    done = subprocess.run(
        [sys.executable, "-m", "anytime", "library", "list", "--json"],
        capture_output=True,
        text=True,
        env=os.environ | {"PYTHONPATH": pythonpath},
        cwd=tmp_path,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr == (
        "anytime: warning: plugin 'broken' (toy_anytime_plugin.broken): ModuleNotFoundError: "
        "No module named 'nope_not_installed'\n"
    )
    rows = {row["module"]: row for row in json.loads(done.stdout)}
    assert rows["toy-count"] == {
        "module": "toy-count",
        "kind": "interruptible",
        "inputs": ["data"],
        "arity": 2,
        "origin": "plugin 'toy' (toy_anytime_plugin)",
        "profile": {
            "description": "2 input grid pts x 4 times x 4 bins, ticks",
            "file": None,
            "input_grid_points": [2],
            "time_points": 4,
            "bins": 4,
            "time_unit": "ticks",
            "measured": False,
        },
        "profile_error": None,
    }
    assert rows["toy-halve"]["origin"] == "plugin 'toy-extra' (toy_anytime_plugin.extra:modules)"
    assert rows["toy-halve"]["kind"] == "contract"


# --- a module's step ----------------------------------------------------------------------------

STEPPED = attrs.evolve(FIND_PATH_PROFILE, step=7)


def _stepped_registry(declared: float | None, profile: Any) -> Registry:
    fresh = Registry()

    @interruptible("find-path", inputs=["domain"], profile=profile, registry=fresh, step=declared)
    def find_path(ctx: Any, start: Any, goal: Any, domain: Any) -> Iterator[Result]:
        yield Result(None, 0.0)

    return fresh


@pytest.mark.parametrize(
    ("declared", "profile", "step"),
    [
        (None, None, None),  # nothing known
        (None, FIND_PATH_PROFILE, None),  # a profile without a step (every old file)
        (None, STEPPED, 7.0),  # measured
        (3, STEPPED, 3.0),  # declared, though smaller: the module's word
        (9, FIND_PATH_PROFILE, 9.0),
        (0, None, 0.0),
    ],
)
def test_an_entry_s_step_is_the_declared_one_else_the_measured_one(
    declared: float | None, profile: Any, step: float | None
) -> None:
    entry = AnytimeLibrary([RegistrySource(_stepped_registry(declared, profile))])["find-path"]
    assert entry.step == step
    assert entry.declared_step == (None if declared is None else float(declared))
    assert entry.measured_step == (None if profile is None else profile.step)


def test_a_profile_only_entry_has_its_file_s_step(tmp_path: Path) -> None:
    directory = tmp_path / "profiles"
    directory.mkdir()
    save_profile(STEPPED, directory / "find-path.yaml")
    save_profile(VISION_PROFILE, directory / "vision.yaml")
    library = AnytimeLibrary([ProfileDirectory(directory)])
    assert (library["find-path"].step, library["get-domain-description"].step) == (7.0, None)


def test_an_unreadable_profile_makes_the_step_raise_unless_one_is_declared(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere.yaml"
    entry = AnytimeLibrary([RegistrySource(_stepped_registry(None, missing))])["find-path"]
    with pytest.raises(ProfileError, match="no such profile file"):
        _ = entry.step
    declared = AnytimeLibrary([RegistrySource(_stepped_registry(4, missing))])["find-path"]
    assert declared.step == 4.0  # the profile is not read for it


@pytest.mark.parametrize(
    ("declared", "profile", "line"),
    [
        (None, STEPPED, "step:        7 ticks (measured)"),
        (7, STEPPED, "step:        7 ticks (declared; measured 7)"),
        (
            3,
            STEPPED,
            "step:        3 ticks (declared; measured 7: its results came further"
            " apart than declared, which is right only if it stops at ctx.expired in between, as"
            " `anytime check` tests)",
        ),
        (
            1,
            STEPPED,
            "step:        1 tick (declared; measured 7: its results came further"
            " apart than declared, which is right only if it stops at ctx.expired in between, as"
            " `anytime check` tests)",
        ),
        (9, STEPPED, "step:        9 ticks (declared; measured 7)"),
        (2.5, FIND_PATH_PROFILE, "step:        2.5 ticks (declared)"),
        (2, None, "step:        2 (declared)"),
    ],
)
def test_library_show_prints_the_step_when_known(
    cli: Cli, monkeypatch: pytest.MonkeyPatch, declared: Any, profile: Any, line: str
) -> None:
    registry = _stepped_registry(declared, profile)
    monkeypatch.setattr(anytime.library, "REGISTRY", registry)
    code, out, err = cli("library", "show", "find-path", "--no-plugins")
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[5] == line, out
    assert lines[4] == "inputs:      domain"
    code, out, _ = cli("library", "show", "find-path", "--no-plugins", "--json")
    data = json.loads(out)
    measured = None if profile is None else profile.step
    mine = None if declared is None else float(declared)
    want = (mine if mine is not None else measured, mine, measured)
    assert (data["step"], data["declared_step"], data["measured_step"]) == want


def test_library_show_says_nothing_of_an_unknown_step(
    cli: Cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(anytime.library, "REGISTRY", _stepped_registry(None, FIND_PATH_PROFILE))
    code, out, _ = cli("library", "show", "find-path", "--no-plugins")
    assert code == 0 and "step" not in out
    code, out, _ = cli("library", "show", "find-path", "--no-plugins", "--json")
    data = json.loads(out)
    assert (data["step"], data["declared_step"], data["measured_step"]) == (None, None, None)


def test_library_show_says_when_its_tables_leave_times_out(cli: Cli) -> None:
    """Six times spread over the grid by default, said in the title; --times 0 shows all."""
    code, out, _ = cli("library", "show", "find-path")
    assert code == 0
    title = next(line for line in out.splitlines() if line.startswith("expected quality"))
    assert title.endswith("time in ticks; 6 of 21 times, --times 0 shows every one):")
    code, out, _ = cli("library", "show", "find-path", "--times", "0")
    title = next(line for line in out.splitlines() if line.startswith("expected quality"))
    assert title.endswith("columns: time in ticks):")
    header = next(line for line in out.splitlines() if line.startswith("  domain \\ time"))
    assert header.split()[3:] == [f"{t}" for t in range(0, 2001, 100)]
    assert cli("library", "show", "find-path", "--times", "x")[0] == 2
