"""The robot-navigation domain of Zilberstein & Russell, the reference plugin.

It registers through the `anytime.plugins` entry point (see pyproject.toml), exactly as a
third-party plugin would; the framework (`anytime`) never imports it.

Built so far: the world (`world`: random rectangle worlds with a connectivity guarantee, 4- and
8-connected movement), the MovingAI benchmark loader (`movingai`), the abstraction pyramid
(`abstraction`), the general path finder (`search`: A*, the papers' baseline), anytime vision
(`vision`) and the anytime abstract planner (`planner`: the papers' ATP). Still to come: plan
execution, registering vision and the planner as anytime modules with measured profiles, and
the figures.
"""

from .modules import find_path, get_domain_description

__all__ = ["find_path", "get_domain_description"]
