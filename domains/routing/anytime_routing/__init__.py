"""Delivery routing for anytime-compose: estimate the customers' demand from an order log,
place the depots by demand-weighted k-means, and plan a tour per depot (nearest neighbour then
2-opt / Or-opt, or randomised cheapest insertion). A plugin of its own, found by the framework
through its `anytime.plugins` entry point; it imports only `anytime` and `anytime.plugin`."""

__version__ = "0.1.0"
