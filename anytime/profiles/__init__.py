"""Performance profiles: the data model, analytic families, file format and profile builder."""

from anytime.profiles.families import (
    Constant,
    DiscreteVariants,
    Exponential,
    Step,
    VisionHyperbola,
    tabulate,
)
from anytime.profiles.profile import (
    ConditionalPerformanceProfile,
    PerformanceProfile,
    default_bins,
    new_profile,
    point_mass,
)

__all__ = [
    "ConditionalPerformanceProfile",
    "Constant",
    "Exponential",
    "PerformanceProfile",
    "DiscreteVariants",
    "Step",
    "VisionHyperbola",
    "default_bins",
    "new_profile",
    "point_mass",
    "tabulate",
]
