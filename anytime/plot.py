"""Figures of performance profiles and compiled programs, as the papers draw them.

- `plot_profile`: a performance profile, expected quality against time with its spread
  (Zilberstein & Russell, Figures 4 and 5: the profile of the abstract planner), or a
  conditional one, one curve per input quality (Figures 7 and 9: the planner's CPP).
- `plot_compiled` / `plot_allocation`: a compiled program's expected quality against the total
  time, beside the baselines equal split, MIN and MAX (Figures 8 and 10: compilation of vision and
  planning), over the allocation of that time among the modules.

matplotlib is an optional dependency (the `plot` extra). It is imported only when a figure is
made, and never through pyplot: each figure is a `matplotlib.figure.Figure` on its own Agg
canvas, so drawing switches no backend and touches no global state (safe in threads and next
to a user's interactive session). Plugins draw their own figures with `new_figure` and
`save_figure`; the `draw_*` functions draw into any matplotlib axes.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from anytime.errors import AnytimeError
from anytime.files import atomic_path
from anytime.profiles.profile import Array, ConditionalPerformanceProfile, point_mass

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from anytime.compiler.compile import CompiledProgram

__all__ = [
    "DPI",
    "MISSING_MATPLOTLIB",
    "MissingMatplotlibError",
    "PlotError",
    "draw_allocation",
    "draw_compiled",
    "draw_profile",
    "new_figure",
    "plot_allocation",
    "plot_compiled",
    "plot_profile",
    "require_matplotlib",
    "save_figure",
]

#: Pixels per inch of every figure: a figure of w x h inches is a PNG of 100 w x 100 h pixels.
DPI = 100

#: At most this many curves in a conditional profile's figure (input qualities are thinned).
MAX_CURVES = 6

MISSING_MATPLOTLIB = "matplotlib is needed for figures: pip install 'anytime-compose[plot]'"

_BASELINE_STYLE = {
    "equal": ("tab:gray", "--"),
    "min": ("tab:red", ":"),
    "max": ("tab:purple", "-."),
}


class MissingMatplotlibError(AnytimeError, ImportError):
    """matplotlib, which every figure needs, is not installed."""


class PlotError(AnytimeError, ValueError):
    """A figure cannot be made from what was given (an unknown image format, mismatched
    tables); the message says what was expected and what was given."""


# --- figures and files -----------------------------------------------------------------------


def require_matplotlib() -> None:
    """Check that figures can be made (before any long work whose end is a figure).

    Raises:
        MissingMatplotlibError: matplotlib is not installed.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise MissingMatplotlibError(MISSING_MATPLOTLIB) from None


def new_figure(width: float, height: float) -> Figure:
    """A figure of `width` x `height` inches (at `DPI`) with constrained layout, on an Agg canvas.

    Raises:
        MissingMatplotlibError: matplotlib is not installed.
    """
    require_matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def save_figure(figure: Figure, path: str | os.PathLike[str]) -> None:
    """Write `figure` to `path` in the format its suffix names (PNG when it has none),
    atomically (a temporary file renamed over `path`).

    Raises:
        PlotError: a suffix that is no image format matplotlib writes.
        OSError: the file cannot be written.
    """
    suffix = Path(path).suffix.lower().removeprefix(".")
    formats = figure.canvas.get_supported_filetypes()
    if suffix and suffix not in formats:
        raise PlotError(
            f"{os.fspath(path)}: unknown image format '.{suffix}' "
            f"(expected one of {', '.join('.' + f for f in sorted(formats))})"
        )
    with atomic_path(path) as temp:
        figure.savefig(os.fspath(temp), dpi=DPI, format=suffix or "png")


# --- performance profiles (Figures 4, 5, 7, 9) -----------------------------------------------


def plot_profile(
    profile: ConditionalPerformanceProfile,
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
) -> None:
    """Draw `profile` (see `draw_profile`) into a 7 x 4.5 inch figure saved at `path`."""
    figure = new_figure(7, 4.5)
    draw_profile(figure.add_subplot(), profile, title=title)
    save_figure(figure, path)


def draw_profile(
    ax: Axes, profile: ConditionalPerformanceProfile, *, title: str | None = None
) -> None:
    """Expected output quality against time.

    Without inputs: the curve with its spread, the measured mean +- one standard deviation when
    the profile has `std`, otherwise the 10-90% quantiles of its histogram (none for a
    deterministic profile). With inputs: one curve per value of the first input's grid (at most
    `MAX_CURVES`, the highest always among them), the other inputs at their highest grid value
    (the default title says so).
    """
    time = profile.time
    table = _expected_table(profile)
    name = profile.module or "the module"
    if profile.n_inputs == 0:
        ax.plot(time, table, color="tab:blue", lw=2, marker=_marker(time), label="expected quality")
        band = _spread(profile)
        if band is not None:
            low, high, label = band
            ax.fill_between(time, low, high, color="tab:blue", alpha=0.2, lw=0, label=label)
        default = f"Performance profile of {name}"
        legend_title = None
    else:
        grid = profile.input_grids[0]
        chosen = _thin(len(grid), MAX_CURVES)
        colours = _colours(len(chosen))
        rest = (-1,) * (profile.n_inputs - 1)
        for colour, i in zip(colours, chosen[::-1], strict=True):  # the best input first
            ax.plot(
                time,
                table[(i, *rest)],
                color=colour,
                lw=2,
                marker=_marker(time),
                label=f"input quality {grid[i]:g}",
            )
        names = _input_names(profile)
        default = f"Conditional performance profile of {name}"
        if profile.n_inputs > 1:
            others = ", ".join(names[1:])
            best = ", ".join(f"{g[-1]:g}" for g in profile.input_grids[1:])
            default += f"\n(curves over {names[0]}; {others} at quality {best})"
        legend_title = f"input: {names[0]}"
    ax.set_title(title if title is not None else default)
    ax.set_xlabel(f"{_time_axis(profile)} ({profile.time_unit})")
    ax.set_ylabel("expected output quality")
    _quality_axes(ax, time)
    if legend_title is None:
        ax.legend(loc="lower right", fontsize="small")
    else:  # beside the axes: the curves fill the lower right
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1), title=legend_title, fontsize="small")


# --- compiled programs (Figures 8, 10) -------------------------------------------------------


def plot_compiled(
    compiled: CompiledProgram, path: str | os.PathLike[str], *, title: str | None = None
) -> None:
    """A compiled program against its baselines, over its allocation (see `plot_allocation`)."""
    plot_allocation(
        compiled.profile,
        compiled.modules,
        compiled.allocation,
        path,
        baselines=compiled.baselines,
        title=title,
        dependence=compiled.dependence,
    )


def plot_allocation(
    profile: ConditionalPerformanceProfile,
    modules: Sequence[str],
    allocation: Array,
    path: str | os.PathLike[str],
    *,
    baselines: Mapping[str, Array] | None = None,
    title: str | None = None,
    dependence: Array | None = None,
) -> None:
    """Two panels saved at `path` (7 x 7 inches): the compiled expected quality against the
    total time with the `baselines` and the `dependence` bounds (`draw_compiled`), and the
    time each module gets
    (`draw_allocation`). The tables are those of a `CompiledProgram` or of the file it saves
    (`allocation` shaped (*input grids, time, len(modules))); a program with quality-carrying
    inputs is drawn at their highest grid quality, as the compile report does."""
    _check_allocation(profile, modules, allocation)
    figure = new_figure(7, 7)
    top, bottom = figure.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    draw_compiled(top, profile, baselines, modules=modules, title=title, dependence=dependence)
    draw_allocation(bottom, profile, modules, allocation)
    top.set_xlabel("")
    save_figure(figure, path)


def draw_compiled(
    ax: Axes,
    profile: ConditionalPerformanceProfile,
    baselines: Mapping[str, Array] | None = None,
    *,
    modules: Sequence[str] = (),
    title: str | None = None,
    dependence: Array | None = None,
) -> None:
    """The compiled profile's expected quality against total time, with the baselines (tables
    shaped like the profile's mean: equal split, MIN and MAX, the first module given its least
    or most useful time) and, for a program with a best-of, the band its expected quality
    spans if the alternatives depend on each other (`CompiledProgram.dependence`), at the
    highest grid quality of every input."""
    best = (-1,) * profile.n_inputs
    time = profile.time
    if dependence is not None:
        low, high = (np.asarray(bound)[best] for bound in dependence)
        ax.fill_between(
            time,
            low,
            high,
            color="tab:blue",
            alpha=0.15,
            lw=0,
            label="compiled, if the best-of's alternatives depend on each other",
        )
    ax.plot(
        time, _expected_table(profile)[best], color="tab:blue", lw=2.5, label="compiled (optimal)"
    )
    first = modules[0] if modules else "the first module"
    labels = {
        "equal": "equal split",
        "min": f"MIN ({first} gets its least useful time)",
        "max": f"MAX ({first} gets its most useful time)",
    }
    for name, table in (baselines or {}).items():
        colour, style = _BASELINE_STYLE.get(name, ("black", "--"))
        ax.plot(
            time,
            np.asarray(table)[best],
            color=colour,
            ls=style,
            lw=2,
            label=labels.get(name, name),
        )
    default = f"Compiled {profile.module or 'program'}"
    if baselines:
        default += ": optimal allocation vs. " + ", ".join(
            labels.get(name, name).split(" (")[0] for name in baselines
        )
    else:
        default += ": expected quality of the optimal allocation"
    if profile.n_inputs:
        qualities = ", ".join(f"{g[-1]:g}" for g in profile.input_grids)
        default += f"\n(at input quality {qualities} of {', '.join(_input_names(profile))})"
    ax.set_title(title if title is not None else default)
    ax.set_xlabel(f"total time T ({profile.time_unit})")
    ax.set_ylabel("expected output quality")
    _quality_axes(ax, time)
    ax.legend(loc="lower right", fontsize="small")


def draw_allocation(
    ax: Axes, profile: ConditionalPerformanceProfile, modules: Sequence[str], allocation: Array
) -> None:
    """Stacked areas: the time each module gets against the total time (they add up to it),
    at the highest grid quality of every input."""
    best = (-1,) * profile.n_inputs
    time = profile.time
    shares = np.asarray(allocation, dtype=np.float64)[best]  # (time, module)
    from matplotlib import colormaps

    palette = colormaps["Set2"]
    colours = [palette(i % palette.N) for i in range(len(modules))]
    ax.stackplot(time, shares.T, labels=list(modules), colors=colours)
    ax.plot(time, time, color="black", lw=1, ls="--", label="total T")
    ax.set_xlabel(f"total time T ({profile.time_unit})")
    ax.set_ylabel(f"time allocated ({profile.time_unit})")
    _time_limits(ax, time)
    ax.set_ylim(0, max(float(time[-1]), 1.0) * 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize="small", title="allocation")


# --- helpers ---------------------------------------------------------------------------------


def _expected_table(profile: ConditionalPerformanceProfile) -> Array:
    if profile.mean is not None:
        return profile.mean
    return np.asarray(profile.probability @ profile.values)


def _spread(profile: ConditionalPerformanceProfile) -> tuple[Array, Array, str] | None:
    """The band around the curve of a profile without inputs, and its legend label."""
    mean = _expected_table(profile)
    if profile.std is not None:
        if not np.any(profile.std > 0):
            return None
        label = "±1 std (measured)"
        if profile.samples is not None:
            low_n, high_n = int(profile.samples.min()), int(profile.samples.max())
            trials = f"{low_n}" if low_n == high_n else f"{low_n}-{high_n}"
            label = f"±1 std ({trials} trials per time)"
        return np.clip(mean - profile.std, 0, 1), np.clip(mean + profile.std, 0, 1), label
    if profile.mean is not None and np.array_equal(
        profile.probability, point_mass(profile.mean, profile.bins)
    ):
        return None  # deterministic: a histogram band would only show the bin width
    low, high = _quantiles(profile, (0.1, 0.9))
    return low, high, "10-90% quantiles"


def _quantiles(profile: ConditionalPerformanceProfile, levels: Sequence[float]) -> list[Array]:
    """Quantiles of every cell's histogram, quality spread uniformly inside each bin."""
    p = profile.probability
    cdf = np.cumsum(p, axis=-1)
    edges = profile.bins
    out = []
    for level in levels:
        k = np.argmax(cdf >= level - 1e-12, axis=-1)[..., None]
        mass = np.take_along_axis(p, k, axis=-1)[..., 0]
        before = np.take_along_axis(cdf, k, axis=-1)[..., 0] - mass
        fraction = np.clip(
            np.divide(level - before, mass, where=mass > 0, out=np.zeros_like(mass)), 0, 1
        )
        k = k[..., 0]
        out.append(edges[k] + fraction * (edges[k + 1] - edges[k]))
    return out


def _thin(n: int, most: int) -> list[int]:
    """At most `most` indices of 0..n-1, evenly spread, the last always included."""
    if n <= most:
        return list(range(n))
    return sorted({int(i) for i in np.round(np.linspace(0, n - 1, most))})


def _colours(n: int) -> list[tuple[float, float, float, float]]:
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    return [cmap(x) for x in np.linspace(0.0, 0.85, n)]


def _marker(time: Array) -> str | None:
    return "o" if len(time) <= 25 else None


def _input_names(profile: ConditionalPerformanceProfile) -> list[str]:
    if len(profile.inputs) == profile.n_inputs:
        return list(profile.inputs)
    return [f"input {i + 1}" for i in range(profile.n_inputs)]


def _time_axis(profile: ConditionalPerformanceProfile) -> str:
    return "contract time" if profile.kind == "contract" else "run time"


def _quality_axes(ax: Axes, time: Array) -> None:
    _time_limits(ax, time)
    ax.set_ylim(-0.02, 1.03)  # room for markers at 0 and 1
    ax.grid(alpha=0.3)


def _time_limits(ax: Axes, time: Array) -> None:
    span = float(time[-1] - time[0]) or 1.0
    ax.set_xlim(time[0] - 0.02 * span, time[-1] + 0.02 * span)


def _check_allocation(
    profile: ConditionalPerformanceProfile, modules: Sequence[str], allocation: Array
) -> None:
    expected = (*profile.cell_shape, len(modules))
    shape = np.shape(allocation)
    if shape != expected:
        raise PlotError(
            f"{profile.module or 'profile'}: allocation: expected shape {list(expected)} "
            f"(input grids, time, one per module), got {list(shape)}"
        )
