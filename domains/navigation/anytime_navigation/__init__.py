"""The robot-navigation domain of Zilberstein & Russell, the reference plugin.

It is found through the `anytime.plugins` entry point (see pyproject.toml), exactly as a
third-party plugin would be: the entry point names `anytime_navigation.plugin:PLUGIN`, the
object that lists the plugin's modules, problem sets, critical events and subcommands
(`anytime plan`, `anytime navigate`); the framework (`anytime`) never imports the domain.

What is where. At the top, the plugin's face and what the whole domain shares: the plugin
object (`plugin`), the anytime modules with their problem sets (`modules`) and measured
profiles (`profiles/`), the problems the schemas are promised for (`program_problems`), the
world (`world`: the grid, positions and moves, random rectangle worlds with a connectivity
guarantee), the MovingAI benchmark loader (`movingai`), the packaged data (`resources`:
`schemas/`, `maps/`, `profiles/`), map figures (`figures`) and the subcommands (`cli`). Then,
by what they do: `planning` (the abstraction pyramid, components and doors, A*, the ATP),
`task` (vision, plan execution, the task and the monitor's model, the frame loop and its
figures) and `obstacles` (moving obstacles, overcoming them, crossing the map among them).
"""

__version__ = "0.1.0"
