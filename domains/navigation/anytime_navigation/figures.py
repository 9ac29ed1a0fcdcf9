"""Map figures: abstract plans and executed routes (Zilberstein & Russell, Figures 1-3 and 5-7
of the first paper, Figures 4 and 6 of the second: "the large squares drawn in broken line" of
an abstract plan, and the route the robot follows when guided by it, with the plan's quality).

The map is drawn as the MovingAI files and `world` store it: `blocked[y, x]`, row 0 at the top,
x to the right; base cell (x, y) is the unit square [x, x + 1] x [y, y + 1], so a level-k cell is
the 2^k x 2^k square `abstraction.cell_bounds` gives, and a route is a line through cell
centres. Each level has its own colour in every figure.

`draw_plan` draws into any matplotlib axes (for frame-by-frame views); `plot_plan` and
`plot_refinement` write files. matplotlib comes with the `plot` extra and is imported only here,
lazily, through `anytime.plot` (Agg canvases, no pyplot).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from anytime.plugin import Result
from anytime.plugin.figures import new_figure, save_figure

from .planning.abstraction import cell_bounds
from .planning.planner import MultiPath
from .task.execution import execute, optimal_length, plan_quality
from .world import BoolGrid, Position

if TYPE_CHECKING:
    from matplotlib.artist import Artist
    from matplotlib.axes import Axes

__all__ = ["LEVEL_COLOURS", "Stage", "draw_plan", "plot_plan", "plot_refinement"]

#: The colour of each abstraction level's squares (level 0 first; cycled beyond).
LEVEL_COLOURS = (
    "tab:green",
    "tab:blue",
    "tab:orange",
    "tab:purple",
    "tab:red",
    "tab:brown",
    "tab:pink",
    "tab:olive",
)
ROUTE_COLOUR = "crimson"
BLOCKED_COLOUR = "0.3"
MISREAD_COLOUR = "darkorange"

#: (refinement step, plan quality, quality estimate) of one panel of `plot_refinement`.
Stage = tuple[int, float, float]


def level_colour(level: int) -> str:
    return LEVEL_COLOURS[level % len(LEVEL_COLOURS)]


def draw_plan(
    ax: Axes,
    blocked: BoolGrid,
    plan: MultiPath | None,
    *,
    route: Sequence[Position] | None = None,
    title: str | None = None,
    legend: bool = True,
    seen: BoolGrid | None = None,
    goal: Position | None = None,
) -> list[Artist]:
    """The map (blocked cells dark), the plan's route segments as squares of their level
    (translucent fill, broken outline, a dotted line through their centres: the abstract
    plan), the executed `route` as a line through cell centres, the start and the goal.

    `seen` is the map the planner was given (a sensed map, `vision.sensed_map`): the cells it
    got wrong are marked. `plan` may be None (the map and a route only). The start and goal
    markers are the plan's, else the route's ends; `goal` puts the goal marker elsewhere (a
    route that has not arrived yet).

    Returns the legend handles (one per level drawn, the route, the start and the goal) so that
    a figure of several panels can show one legend; with `legend=True` they are also shown
    below the axes.
    """
    from matplotlib.collections import PatchCollection
    from matplotlib.colors import ListedColormap, to_rgba
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Rectangle

    grid = np.asarray(blocked, dtype=bool)
    height, width = grid.shape
    ax.imshow(
        grid,
        cmap=ListedColormap(["white", BLOCKED_COLOUR]),
        vmin=0,
        vmax=1,
        origin="upper",
        extent=(0, width, height, 0),
        interpolation="nearest",
    )
    handles: list[Artist] = []
    if seen is not None:
        wrong = np.asarray(seen, dtype=bool) != grid
        overlay = np.zeros((height, width, 4))
        overlay[wrong] = to_rgba(MISREAD_COLOUR, 0.8)
        ax.imshow(overlay, origin="upper", extent=(0, width, height, 0), interpolation="nearest")
        handles.append(
            Patch(
                facecolor=MISREAD_COLOUR,
                alpha=0.8,
                label=f"misread by vision ({int(wrong.sum())} cells)",
            )
        )
    if plan is not None:
        for level in sorted({s.level for s in plan.segments}, reverse=True):
            colour = level_colour(level)
            cells = {
                c for s in plan.segments if s.level == level for c in s.cells
            }  # junctions once
            squares = [
                Rectangle((x0, y0), x1 - x0, y1 - y0)
                for x0, y0, x1, y1 in (cell_bounds(cell, level) for cell in sorted(cells))
            ]
            ax.add_collection(
                PatchCollection(
                    squares,
                    facecolor=colour,
                    edgecolor=colour,
                    alpha=0.25 if level else 0.45,
                    linewidth=1.2 if level else 0,
                    linestyle="--",
                )
            )
            side = 1 << level
            handles.append(
                Patch(
                    facecolor=colour,
                    edgecolor=colour,
                    alpha=0.4,
                    linestyle="--",
                    label=f"plan at level {level} ({side}x{side} cells)",
                )
            )
        centres = [
            ((x + 0.5) * (1 << s.level), (y + 0.5) * (1 << s.level))
            for s in plan.segments
            for x, y in s.cells
        ]
        xs, ys = zip(*centres, strict=True)
        (line,) = ax.plot(xs, ys, color="black", lw=1, ls=":", label="abstract plan")
        handles.append(line)
    if route is not None and len(route) > 0:
        centred = np.asarray(route, dtype=np.float64) + 0.5
        (line,) = ax.plot(
            centred[:, 0], centred[:, 1], color=ROUTE_COLOUR, lw=2, label="executed route"
        )
        handles.append(line)
    start, end = _ends(plan, route)
    goal = goal if goal is not None else end
    for position, marker, colour, name in (
        (start, "o", "tab:green", "start"),
        (goal, "*", "gold", "goal"),
    ):
        if position is not None:
            ax.plot(
                position[0] + 0.5,
                position[1] + 0.5,
                marker=marker,
                markersize=12 if marker == "*" else 9,
                color=colour,
                markeredgecolor="black",
                ls="none",
                zorder=5,
                clip_on=False,  # start and goal are often corner cells
            )
            handles.append(
                Line2D(
                    [],
                    [],
                    marker=marker,
                    color=colour,
                    markeredgecolor="black",
                    ls="none",
                    markersize=9,
                    label=name,
                )
            )
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)  # row 0 at the top, as in the map files
    ax.set_aspect("equal")
    ax.set_xlabel("x (cells)")
    ax.set_ylabel("y (cells; row 0 at the top)")
    if title is not None:
        ax.set_title(title)
    if legend and handles:
        ax.legend(
            handles=handles,
            loc="upper center",
            bbox_to_anchor=(0.5, -0.1),
            ncols=min(3, len(handles)),
            fontsize="small",
        )
    return handles


def plot_plan(
    blocked: BoolGrid,
    plan: MultiPath | None,
    path: str | os.PathLike[str] | None = None,
    *,
    route: Sequence[Position] | None = None,
    title: str | None = None,
    ax: Axes | None = None,
    seen: BoolGrid | None = None,
) -> None:
    """`draw_plan` in a 6.5 x 7.3 inch figure written to `path`; or, given `ax`, into those axes
    (and their figure written to `path` when one is given too).

    Raises:
        ValueError: neither `path` nor `ax`.
        anytime.plot.MissingMatplotlibError: matplotlib is not installed.
    """
    if ax is None:
        if path is None:
            raise ValueError("plot_plan needs a path to write or axes to draw into")
        figure = new_figure(6.5, 7.3)
        ax = figure.add_subplot()
    draw_plan(ax, blocked, plan, route=route, title=title, seen=seen)
    if path is not None:
        save_figure(ax.get_figure(root=True), path)  # type: ignore[arg-type]


def plot_refinement(
    blocked: BoolGrid,
    results: Sequence[Result],
    path: str | os.PathLike[str],
    *,
    stages: int = 4,
    movement: int = 4,
    title: str | None = None,
    optimal: float | None = None,
    seen: BoolGrid | None = None,
) -> list[Stage]:
    """Snapshots of an ATP run (`planner.atp`'s results, in order): `stages` panels from the
    first plan to the last, evenly spaced over the refinements, each plan drawn with the route
    the robot follows on the true map `blocked` and, in its title, its quality
    (optimal length / executed length) beside the planner's own estimate.

    Args:
        optimal: the optimal route length (computed with A* on `blocked` when not given).
        seen: the map the planner was given, when it is not `blocked` (imperfect vision, the
            papers' Figures 5-7): its wrong cells are marked in every panel.

    Returns:
        (refinement step, quality, estimate) of each panel.

    Raises:
        ValueError: no results, stages < 1, or a result that is not a `MultiPath`.
    """
    if not results:
        raise ValueError("plot_refinement needs at least one result of the planner")
    if stages < 1:
        raise ValueError(f"stages must be >= 1, got {stages}")
    plans = [r.value for r in results]
    for i, plan in enumerate(plans):
        if not isinstance(plan, MultiPath):
            raise ValueError(f"result {i} is not a plan (a MultiPath): {type(plan).__name__}")
    first: MultiPath = plans[0]
    if optimal is None:
        optimal = optimal_length(blocked, first.start, first.goal, movement=movement)
    chosen = _spread(len(plans), stages)
    ncols = math.ceil(math.sqrt(len(chosen)))
    nrows = math.ceil(len(chosen) / ncols)
    figure = new_figure(4.5 * ncols, 4.7 * nrows + 0.9)
    axes = figure.subplots(nrows, ncols, squeeze=False).ravel()
    handles: dict[str, Any] = {}
    summary: list[Stage] = []
    for ax, step in zip(axes, chosen, strict=False):
        plan = plans[step]
        execution = execute(plan, blocked, movement=movement)
        if optimal is None or not execution.reached:
            quality = 0.0
        else:
            quality = plan_quality(execution.length, optimal)
        estimate = float(results[step].quality)
        summary.append((step, quality, estimate))
        levels = sorted({s.level for s in plan.segments}, reverse=True)
        names = " & ".join(str(level) for level in levels)
        heading = (
            f"step {step} of {len(plans) - 1}: plan at level{'s' if len(levels) > 1 else ''} "
            f"{names}\nquality {quality:.3f} (estimate {estimate:.3f})"
        )
        for handle in draw_plan(
            ax, blocked, plan, route=execution.route, title=heading, legend=False, seen=seen
        ):
            handles.setdefault(str(handle.get_label()), handle)
    for ax in axes[len(chosen) :]:
        ax.set_axis_off()
    order = sorted(handles, key=_legend_order)
    figure.legend(
        [handles[k] for k in order],
        order,
        loc="outside lower center",
        ncols=min(4, len(order)),
        fontsize="small",
    )
    size = np.asarray(blocked).shape
    figure.suptitle(
        title
        if title is not None
        else f"Anytime abstract planning on a {size[1]}x{size[0]} map ({movement}-connected moves)"
    )
    save_figure(figure, path)
    return summary


def _ends(
    plan: MultiPath | None, route: Sequence[Position] | None
) -> tuple[Position | None, Position | None]:
    if plan is not None:
        return plan.start, plan.goal
    if route:
        return tuple(route[0]), tuple(route[-1])  # type: ignore[return-value]
    return None, None


def _spread(n: int, k: int) -> list[int]:
    """At most k of 0..n-1, evenly spread, first and last included."""
    if n <= k:
        return list(range(n))
    return sorted({int(i) for i in np.round(np.linspace(0, n - 1, k))})


def _legend_order(label: str) -> tuple[int, int]:
    """Levels from the top down, then the plan line, the route, start and goal."""
    if label.startswith("plan at level "):
        return (0, -int(label.split()[3]))
    if label.startswith("misread"):
        return (2, 0)
    rest = ("abstract plan", "executed route", "start", "goal")
    return (1, rest.index(label) if label in rest else len(rest))
