"""The figures of `anytime deliver --out DIR` (matplotlib, the `plot` extra): the problem and
its tours, and the quality over the budget, realised against the compiled profile."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from anytime import CompiledProgram
from anytime.plugin.figures import new_figure, save_figure

from .domain import World
from .program import Delivery, deliver, reference_for

__all__ = ["write_figures"]


def write_figures(
    out: Path,
    program: CompiledProgram,
    world: World,
    run: Delivery,
    budget: float,
    adaptive: bool = False,
) -> list[str]:
    """Write `tours.png` and `quality.png` into `out`; returns their paths."""
    figure = new_figure(6.0, 6.0)
    ax = figure.add_subplot()
    colours = [f"C{k % 10}" for k in range(world.depots)]
    size = 20 + 600 * world.shares / world.shares.max()
    tours = run.tours
    labels = tours.clustering.labels if tours is not None else None
    ax.scatter(
        world.points[:, 0],
        world.points[:, 1],
        s=size,
        c=[colours[k] for k in labels] if labels is not None else "grey",
        alpha=0.6,
        edgecolors="black",
        linewidths=0.5,
        label="customers (area: demand share)",
    )
    if tours is not None:
        for k in range(len(tours.orders)):
            route = tours.route(k)
            ax.plot(route[:, 0], route[:, 1], color=colours[k], linewidth=1.5)
        centres = tours.clustering.centres
        ax.scatter(
            centres[:, 0], centres[:, 1], marker="*", s=300, c=colours, edgecolors="black",
            label="depots",
        )  # fmt: skip
    ref = run.reference.centres
    ax.scatter(ref[:, 0], ref[:, 1], marker="x", s=80, c="black", label="reference depots")
    quality = "no reference" if run.quality is None else f"quality {run.quality:.3f}"
    length = f"length {tours.length:.3f}" if tours is not None else "no tours"
    ax.set_title(f"{program.name}, {budget:g} ticks: {length}, {quality}")
    ax.set_xlim(-0.05, 1.05)
    ax.set_ylim(-0.05, 1.05)
    ax.set_aspect("equal")
    ax.legend(loc="best", fontsize="small", framealpha=0.8)
    tours_png = out / "tours.png"
    save_figure(figure, tours_png)

    figure = new_figure(7.0, 4.0)
    ax = figure.add_subplot()
    time = np.asarray(program.profile.time, dtype=float)
    ax.plot(time, program.expected, marker="o", label="compiled expectation")
    reference = reference_for(world)
    realised = [deliver(program, world, float(t), adaptive, reference).quality for t in time]
    shown = [(t, q) for t, q in zip(time, realised, strict=True) if q is not None]
    if shown:
        xs, ys = zip(*shown, strict=True)
        ax.plot(xs, ys, marker="s", linestyle="--", label="realised on this problem")
    if run.quality is not None:
        ax.scatter(
            [budget], [run.quality], s=120, c="red", zorder=3, label=f"this run ({budget:g})"
        )
    ax.set_xlabel("budget (ticks)")
    ax.set_ylabel("quality (reference length / length)")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    ax.set_title(f"{program.name}: quality over the budget")
    quality_png = out / "quality.png"
    save_figure(figure, quality_png)
    return [str(tours_png), str(quality_png)]
