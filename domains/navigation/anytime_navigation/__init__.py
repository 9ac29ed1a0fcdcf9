"""The robot-navigation domain of Zilberstein & Russell, the reference plugin.

It registers through the `anytime.plugins` entry point (see pyproject.toml), exactly as a
third-party plugin would: the entry point names `anytime_navigation.modules`, whose import
registers the anytime modules; the framework (`anytime`) never imports the domain. The
domain's subcommands (`anytime plan`, `anytime navigate`) come through the `anytime.commands`
entry point (`anytime_navigation.cli`), which does not register modules by being imported.

What is where: the world (`world`: random rectangle worlds with a connectivity guarantee, 4-
and 8-connected movement) and the MovingAI benchmark loader (`movingai`); the abstraction
pyramid (`abstraction`); the general path finder (`search`: A*, the papers' baseline); the
anytime abstract planner (`planner`: the papers' ATP); plan execution and plan quality
(`execution`); anytime vision (`vision`); the anytime modules with their problem sets
(`modules`) and measured profiles (`profiles/`); the frame-by-frame task under the monitor
(`task`); figures (`figures`, `frame_figures`) and the subcommands (`cli`).
"""

__version__ = "0.1.0"
