"""Anytime motion planning for anytime-compose: noisy range scans integrated into an occupancy
map, OMPL's RRT* and BIT* on it, and shortcutting, on a work clock of ray casts and validity
checks. A plugin of its own, found by the framework through its `anytime.plugins` entry point;
it imports only `anytime` and `anytime.plugin`."""

__version__ = "0.1.0"
