"""Performance profiles: the data model, analytic families and file formats; dynamic profiles
and the quality traces they are derived from."""

from anytime.profiles.dynamic import DynamicProfile, QualityTraces, quantile_bins
from anytime.profiles.dynamic_io import (
    load_dynamic_profile,
    load_traces,
    save_dynamic_profile,
    save_traces,
)
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
    "DynamicProfile",
    "QualityTraces",
    "Step",
    "VisionHyperbola",
    "default_bins",
    "load_dynamic_profile",
    "load_traces",
    "new_profile",
    "point_mass",
    "quantile_bins",
    "save_dynamic_profile",
    "save_traces",
    "tabulate",
]
