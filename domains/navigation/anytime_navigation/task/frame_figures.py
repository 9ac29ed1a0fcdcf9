"""Frame-by-frame pictures of a navigation task (the papers' Figures 13 and 14): per frame, a
planning view (the robot's map, the sensor window, the best plan; contract time, frame time,
expected and actual plan quality, sensing time and quality) beside an execution view (the true
map, the route so far; current time, energy, expected completion time and value), one PNG per
frame, and an animated GIF of the run. Needs matplotlib (the `plot` extra), imported lazily."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .model import NavigationTask, TaskReport

__all__ = ["write_frames"]

#: Colours of the chosen alternatives of obstacle overcoming, and of the moving obstacles.
CHOICE_COLOURS = {"detour-left": "tab:purple", "detour-right": "tab:cyan", "wait": "gold"}
OBSTACLE_COLOUR = "tab:brown"


def _draw_obstacles(axes: Any, frame: Any) -> None:
    """The moving obstacles at the frame's end (squares, velocity as arrows scaled to 60
    ticks of motion) and each alternative chosen in the frame: its route in its own colour,
    labelled with its name at the branch cell."""
    from matplotlib.patches import Rectangle

    for obstacle in frame.obstacles:
        (x, y), (vx, vy), size = obstacle.position, obstacle.velocity, obstacle.size
        axes.add_patch(
            Rectangle(
                (x + 0.5 - size / 2, y + 0.5 - size / 2),
                size,
                size,
                color=OBSTACLE_COLOUR,
                zorder=7,
            )
        )
        axes.arrow(x + 0.5, y + 0.5, 60 * vx, 60 * vy, width=0.15, color=OBSTACLE_COLOUR, zorder=7)
    for name, cells in frame.choices:
        colour = CHOICE_COLOURS.get(name, "magenta")
        xs = [c[0] + 0.5 for c in cells]
        ys = [c[1] + 0.5 for c in cells]
        axes.plot(xs, ys, "-", color=colour, lw=2.5, zorder=8)
        axes.plot(xs[:1], ys[:1], "s", color=colour, mec="black", zorder=8)
        axes.annotate(
            name,
            (xs[0], ys[0]),
            color=colour,
            fontsize=8,
            zorder=9,
            xytext=(4, 4),
            textcoords="offset points",
            fontweight="bold",
        )


def _key(planned: list[Any], walked: list[Any], frame: Any) -> list[Any]:
    """One key for both views: what `draw_plan` drew in each (once per label), the sensor
    window, the robot, and, where there are any, the moving obstacles and the alternatives
    chosen to overcome them."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: dict[str, Any] = {}
    for handle in [*planned, *walked]:
        handles.setdefault(handle.get_label(), handle)
    window = Patch(fill=False, edgecolor="tab:orange", lw=2, label="sensor window")
    handles["sensor window"] = window
    handles["robot"] = Line2D(
        [], [], marker="o", color="tab:red", mec="black", ls="none", label="robot now"
    )
    if frame.obstacles:
        handles["obstacle"] = Line2D(
            [], [], marker="s", color=OBSTACLE_COLOUR, ls="none",
            label="moving obstacle (arrow: 60 ticks of its motion)",
        )  # fmt: skip
    for name, _ in frame.choices:
        colour = CHOICE_COLOURS.get(name, "magenta")
        handles[name] = Line2D([], [], color=colour, lw=2.5, label=name)
    return list(handles.values())


def write_frames(
    report: TaskReport,
    task: NavigationTask,
    out: str | Path,
    on_frame: Callable[[int], object] | None = None,
) -> list[str]:
    """Write `frame-NNN.png` for every frame and `run.gif` into `out`; return the paths.
    Each file is written atomically; `on_frame(n)`, if given, is called after each picture.

    Left, the planning view: the robot's map at planning time (what it had sensed and bumped
    into), the sensor window, and the plan as squares of its abstraction levels
    (`figures.draw_plan`). Right, the execution view: the true map and the route so far."""
    from matplotlib.patches import Rectangle
    from PIL import Image

    from anytime.plugin.cli import atomic_path
    from anytime.plugin.figures import new_figure, save_figure

    from ..figures import draw_plan

    out = Path(out)
    truth = np.asarray(task.world.blocked, dtype=bool)
    written: list[str] = []
    for frame in report.records:
        figure = new_figure(11, 6.6)
        left, right = figure.subplots(1, 2)
        planned = draw_plan(left, frame.known, frame.plan, legend=False)
        x0, y0, x1, y1 = frame.window
        left.add_patch(
            Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="tab:orange", lw=2, zorder=5)
        )
        left.set_title(
            f"planning: contract {frame.contract:.0f}, "
            f"frame {frame.frame_time:.0f} ticks\n"
            f"plan quality {frame.plan_quality:.2f} (expected {frame.expected_quality:.2f}); "
            f"sensing {frame.sensing_time:.0f} ticks, quality {frame.sensing_quality:.3f}",
            fontsize=9,
        )
        upto = [c for f in report.records[: frame.index + 1] for c in f.route]
        walked = draw_plan(right, truth, None, route=upto, goal=task.world.goal, legend=False)
        here = frame.route[-1]
        right.plot(here[0] + 0.5, here[1] + 0.5, "o", color="tab:red", mec="black", zorder=6)
        _draw_obstacles(right, frame)
        right.set_title(
            f"execution: time {frame.exec_end:.0f} ticks, speed {frame.speed:g} cells/tick, "
            f"energy {frame.energy:.0f}\n"
            f"expected completion {frame.expected_completion:.0f}, "
            f"expected value {frame.expected_value:.0f}"
            + (
                f"; {frame.decisions} decisions, {frame.collisions} collisions"
                if frame.obstacles
                else ""
            ),
            fontsize=9,
        )
        figure.suptitle(
            f"{report.policy} policy: frame {frame.index + 1} of {report.frames} (left: the"
            " robot's map as it plans; right: the true map as it executes)",
            fontsize=10,
        )
        figure.legend(
            handles=_key(planned, walked, frame),
            loc="outside lower center",
            ncol=4,
            fontsize=8,
            frameon=False,
        )
        path = out / f"frame-{frame.index:03d}.png"
        save_figure(figure, path)
        written.append(str(path))
        if on_frame is not None:
            on_frame(len(written))
    if written:
        images = [Image.open(p).convert("P") for p in written]
        gif = out / "run.gif"
        with atomic_path(gif) as temp:
            images[0].save(
                temp, format="GIF", save_all=True, append_images=images[1:], duration=700, loop=0
            )
        written.append(str(gif))
    return written
