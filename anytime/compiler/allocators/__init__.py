"""Time allocators: how a total time T is split among a program's anytime modules.

All allocators work on one lattice: allocations are whole numbers of time units `dt`, summing
exactly to `T / dt`, so their results are comparable (the exhaustive search is the reference).
Each works on a batch of cells at once: rows of program input qualities `q (C, m)` and totals
`units (C,)`, returning allocations `(C, n)` in units and their expected output qualities. The
compiler runs them through one protocol (`Allocator`, in `protocol`), one allocator a module:

- `hill_climbing`: the papers' algorithm as written (Zilberstein & Russell), from equal shares;
- `exhaustive`: every allocation of the lattice simplex; exact, and exponential in n;
- `proportional`: Romanenko's rule, each module's share in proportion to the least time at
  which its quality rises (a baseline);
- `dynamic_programming`: local compilation, exact for trees of deterministic, input-monotone
  modules (`dp_obstacle` says why it is not exact elsewhere);
- `multi_start`: hill-climbing from many starts, for programs where dp is not exact.

`lattice` and `memory` hold what they share (the lattice's compositions and splits; the memory
a search holds, and evaluation in chunks within a cap); `reallocate` is the search the runtime
runs to re-split time during a run.
"""

from anytime.compiler.allocators.dynamic_programming import DynamicProgramming, dp_obstacle
from anytime.compiler.allocators.exhaustive import Exhaustive
from anytime.compiler.allocators.hill_climbing import HillClimbing
from anytime.compiler.allocators.lattice import compositions, equal_split, proportional_split
from anytime.compiler.allocators.memory import DEFAULT_MEMORY
from anytime.compiler.allocators.multi_start import MultiStart
from anytime.compiler.allocators.proportional import Proportional, least_useful_time
from anytime.compiler.allocators.protocol import Allocator, AllocatorClass, Evaluates
from anytime.compiler.allocators.reallocate import reallocate

#: Allocators by name.
ALLOCATORS: dict[str, AllocatorClass] = {
    "hill-climbing": HillClimbing,
    "exhaustive": Exhaustive,
    "dp": DynamicProgramming,
    "proportional": Proportional,
    "multi-start": MultiStart,
}

__all__ = [
    "ALLOCATORS",
    "DEFAULT_MEMORY",
    "Allocator",
    "AllocatorClass",
    "DynamicProgramming",
    "Evaluates",
    "Exhaustive",
    "HillClimbing",
    "MultiStart",
    "Proportional",
    "compositions",
    "dp_obstacle",
    "equal_split",
    "least_useful_time",
    "proportional_split",
    "reallocate",
]
