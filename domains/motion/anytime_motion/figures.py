"""The figures of `anytime motion --out DIR` (matplotlib, the `plot` extra): the obstacles, the
sensed map and the paths of the three splits; and the quality over the budget, realised
against the compiled expectation."""

from __future__ import annotations

from pathlib import Path as FilePath

import numpy as np

from anytime import CompiledProgram
from anytime.plugin.figures import new_figure, save_figure

from .program import SPLITS, Motion, Problem, move

__all__ = ["write_figures"]

NAMES = {"compiled": "compiled", "even": "even (MoveIt)", "planner": "all to the planner"}


def write_figures(
    out: FilePath,
    program: CompiledProgram,
    problem: Problem,
    runs: dict[str, Motion],
    budget: float,
) -> list[str]:
    """Write `paths.png` and `quality.png` into `out`; returns their paths."""
    from matplotlib.patches import Circle, Rectangle

    world = problem.world
    figure = new_figure(6.5, 6.5)
    ax = figure.add_subplot()
    sensed = runs["compiled"].map
    if sensed is not None and world.dimension == 2:
        ax.imshow(
            sensed.occupied.T,
            origin="lower",
            extent=(0, 1, 0, 1),
            cmap="Greys",
            alpha=0.35,
            vmin=0,
            vmax=1.5,
        )
    for centre, size, box in zip(world.centres, world.sizes, world.boxes, strict=True):
        x, y = float(centre[0]), float(centre[1])
        patch: Circle | Rectangle
        if box:
            patch = Rectangle(
                (x - size[0], y - size[1]), 2 * size[0], 2 * size[1], fill=False, color="black"
            )
        else:
            patch = Circle((x, y), float(size[0]), fill=False, color="black")
        ax.add_patch(patch)
    ref = problem.reference.path
    if ref is not None:
        ax.plot(ref.points[:, 0], ref.points[:, 1], ":", color="grey", label="reference")
    for k, split in enumerate(SPLITS):
        run = runs[split]
        if run.path is not None:
            label = f"{NAMES[split]}: quality {run.quality:.3f}"
            ax.plot(run.path.points[:, 0], run.path.points[:, 1], color=f"C{k}", label=label)
    ax.scatter([world.start[0]], [world.start[1]], marker="o", s=80, c="green", label="start")
    ax.scatter([world.goal[0]], [world.goal[1]], marker="*", s=160, c="red", label="goal")
    projection = "" if world.dimension == 2 else f" (the first two of {world.dimension} axes)"
    ax.set_title(
        f"{program.name}, {budget:g} ticks: obstacles, the sensed map (grey), paths{projection}",
        fontsize="small",
    )
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_aspect("equal")
    ax.legend(loc="upper left", fontsize="x-small", framealpha=0.8)
    paths_png = out / "paths.png"
    save_figure(figure, paths_png)

    figure = new_figure(7.0, 4.0)
    ax = figure.add_subplot()
    time = np.asarray(program.profile.time, dtype=float)
    ax.plot(time, program.expected, marker="o", label="compiled expectation")
    for k, split in enumerate(SPLITS):
        realised = [move(program, problem, float(t), split).quality for t in time]
        ax.plot(
            time, realised, marker="s", linestyle="--", color=f"C{k + 1}",
            label=f"{NAMES[split]}, this problem",
        )  # fmt: skip
    here = runs["compiled"].quality
    ax.scatter([budget], [here], s=120, c="red", zorder=3, label=f"this run ({budget:g})")
    ax.set_xlabel("budget (ticks: ray casts and validity checks)")
    ax.set_ylabel("quality (reference cost / cost)")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize="small")
    ax.set_title(f"{program.name}: quality over the budget")
    quality_png = out / "quality.png"
    save_figure(figure, quality_png)
    return [str(paths_png), str(quality_png)]
