"""Figures, opt-in: `from anytime.plugin.figures import new_figure, save_figure`.

`require_matplotlib()` raises a one-line `AnytimeError` naming the extra to install when
matplotlib is missing (call it before doing the work a figure is for); `new_figure(width,
height)` makes a figure without touching pyplot's global state; `save_figure(figure, path)`
writes it whole or not at all. matplotlib itself is imported only when a figure is made.
"""

from __future__ import annotations

from anytime.plot import new_figure, require_matplotlib, save_figure

__all__ = ["new_figure", "require_matplotlib", "save_figure"]
