"""Map figures: plans drawn as squares of their level on the map (row 0 at the top), routes,
and the refinement stages of an ATP run with their qualities."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from anytime_navigation import world
from anytime_navigation.figures import draw_plan, plot_plan, plot_refinement
from anytime_navigation.planning import abstraction, planner
from anytime_navigation.task import execution, vision

from anytime.modules import Context, Result
from anytime.plot import new_figure

pytest.importorskip("matplotlib")

SIZE = 32


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


@pytest.fixture(scope="module")
def run() -> tuple[world.World, list[Result]]:
    w = world.random_world(SIZE, seed=3, density=0.3, movement=8)
    pyramid = abstraction.Pyramid.build(w.blocked)
    return w, list(planner.atp(Context(), w.start, w.goal, pyramid, movement=8, top=3))


def test_plot_plan_writes_the_map_with_plan_and_route(
    tmp_path: Path, run: tuple[world.World, list[Result]]
) -> None:
    w, results = run
    plan = results[0].value
    route = execution.execute(plan, w.blocked, movement=8).route
    out = tmp_path / "plan.png"
    plot_plan(w.blocked, plan, out, route=route, title="first plan")
    assert png_size(out) == (650, 730)


def test_plan_squares_are_the_cells_of_their_level_and_row_0_is_at_the_top(
    run: tuple[world.World, list[Result]],
) -> None:
    w, results = run
    plan = results[len(results) // 2].value
    ax = new_figure(5, 5).add_subplot()
    handles = draw_plan(ax, w.blocked, plan, route=[w.start, w.goal])
    assert ax.get_ylim() == (SIZE, 0) and ax.get_xlim() == (0, SIZE)
    drawn = set()
    for collection in ax.collections:
        for path in collection.get_paths():
            corners = collection.get_transforms()  # identity: patches are in data coordinates
            assert len(corners) == 0
            (x0, y0), (x1, y1) = path.vertices.min(axis=0), path.vertices.max(axis=0)
            drawn.add((round(x0), round(y0), round(x1), round(y1)))
    wanted = {abstraction.cell_bounds(cell, s.level) for s in plan.segments for cell in s.cells}
    assert drawn == wanted
    labels = [h.get_label() for h in handles]
    levels = sorted({s.level for s in plan.segments}, reverse=True)
    assert labels[: len(levels)] == [f"plan at level {k} ({1 << k}x{1 << k} cells)" for k in levels]
    assert labels[-4:] == ["abstract plan", "executed route", "start", "goal"]


def test_plot_plan_draws_into_given_axes(
    tmp_path: Path, run: tuple[world.World, list[Result]]
) -> None:
    w, results = run
    figure = new_figure(8, 4)
    left, right = figure.subplots(1, 2)
    plot_plan(w.blocked, results[0].value, ax=left, title="first")
    plot_plan(w.blocked, results[-1].value, tmp_path / "two.png", ax=right, title="last")
    assert left.get_title() == "first"
    assert png_size(tmp_path / "two.png") == (800, 400)
    with pytest.raises(ValueError, match="needs a path to write or axes"):
        plot_plan(w.blocked, results[0].value)


def test_plot_refinement_shows_first_to_last_with_qualities(
    tmp_path: Path, run: tuple[world.World, list[Result]]
) -> None:
    w, results = run
    out = tmp_path / "refinement.png"
    stages = plot_refinement(w.blocked, results, out, movement=8)
    assert png_size(out) == (900, 1030)
    assert [s[0] for s in stages][0] == 0 and stages[-1][0] == len(results) - 1
    assert len(stages) == min(4, len(results))
    optimal = execution.optimal_length(w.blocked, w.start, w.goal, movement=8)
    assert optimal is not None
    for step, quality, estimate in stages:
        followed = execution.execute(results[step].value, w.blocked, movement=8)
        assert quality == execution.plan_quality(followed.length, optimal)
        assert estimate == results[step].quality


def test_plot_refinement_marks_what_vision_misread(
    tmp_path: Path, run: tuple[world.World, list[Result]]
) -> None:
    w, results = run
    seen = np.array(vision.sensed_map(w.blocked, vision.error_draws(w.blocked.shape, 1), 0.9))
    seen[w.start[1], w.start[0]] = seen[w.goal[1], w.goal[0]] = False
    pyramid = abstraction.Pyramid.build(seen)
    noisy = list(planner.atp(Context(), w.start, w.goal, pyramid, movement=8, top=3))
    stages = plot_refinement(
        w.blocked, noisy, tmp_path / "noisy.png", stages=2, movement=8, seen=seen
    )
    assert [s[0] for s in stages] == [0, len(noisy) - 1]
    assert png_size(tmp_path / "noisy.png") == (900, 560)
    ax = new_figure(5, 5).add_subplot()
    labels = [h.get_label() for h in draw_plan(ax, w.blocked, None, seen=seen)]
    assert labels == [f"misread by vision ({int(np.sum(seen != w.blocked))} cells)"]


def test_plot_refinement_needs_results(tmp_path: Path) -> None:
    blocked = np.zeros((4, 4), dtype=bool)
    with pytest.raises(ValueError, match="at least one result"):
        plot_refinement(blocked, [], tmp_path / "x.png")
    with pytest.raises(ValueError, match="stages must be >= 1, got 0"):
        plot_refinement(blocked, [Result(None, 0.0)], tmp_path / "x.png", stages=0)
    with pytest.raises(ValueError, match="result 0 is not a plan"):
        plot_refinement(blocked, [Result(None, 0.0)], tmp_path / "x.png")


def test_a_frame_picture_has_one_key_for_what_both_views_draw(tmp_path: Path) -> None:
    """Every encoding of a frame's picture is in its key (plan levels, the abstract plan, the
    route, start, goal, sensor window, robot, moving obstacles), and the frame is numbered the
    same way everywhere (its title says 'frame 2 of N', no view says 'frame 1')."""
    from anytime_navigation.obstacles.moving import random_obstacles
    from anytime_navigation.task.frame_figures import write_frames
    from anytime_navigation.task.frame_program import navigation_program
    from anytime_navigation.task.frames import run_task
    from anytime_navigation.task.model import NavigationTask
    from anytime_navigation.world import random_world
    from matplotlib.figure import Figure

    from anytime.runtime.monitor import DeadlineValue

    task = NavigationTask(random_world(32, seed=0), radius=8, value=DeadlineValue(1000, 1500, 1))
    compiled, trace = navigation_program()
    obstacles = random_obstacles(task.world, 2, seed=0)
    report = run_task(task, compiled, trace, obstacles=obstacles)
    seen: list[tuple[str, list[str], list[str]]] = []
    original = Figure.savefig

    def keep(figure: Figure, *args: object, **kwargs: object) -> None:
        labels = [t.get_text() for legend in figure.legends for t in legend.get_texts()]
        titles = [ax.get_title() for ax in figure.axes]
        seen.append((figure.get_suptitle(), labels, titles))
        original(figure, *args, **kwargs)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(Figure, "savefig", keep)
        write_frames(report, task, tmp_path)
    title, labels, titles = seen[1]
    assert title.startswith(f"monitored policy: frame 2 of {report.frames} (")
    assert not any("frame 1" in t for t in titles)
    assert {
        "abstract plan",
        "executed route",
        "start",
        "goal",
        "sensor window",
        "robot now",
    } <= set(labels)
    assert any(label.startswith("plan at level 0") for label in labels)
    assert any(label.startswith("moving obstacle") for label in labels)
