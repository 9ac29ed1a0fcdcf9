#!/usr/bin/env bash
# Measure the motion plugin's profiles with the framework's own `anytime profile`, on the work
# clock (ticks: ray casts and OMPL validity checks), and write them into the package. Run with
# the environment's `anytime` on the PATH (or ANYTIME=path/to/anytime) and the plugin
# installed; the same seed gives the same files for any --workers (OMPL's random numbers are
# seeded from each problem's seed, drawn from the framework's seed stream).
#
# The trial counts are small on purpose (minutes, not hours, on one core): 200 problems for
# the sensor, 100 per input cell for the planners, 60 for the shortcutting on its own problem
# set (see README.md).
#
# shorten-path is then measured again where `move` puts it (`--upstream`): on the paths the
# compiled program's BIT* plans on the maps its sensing makes, under the compiled allocations,
# compiling again with the new profile until the table stops moving. A path's quality alone
# does not say whether a shortcut can free it (BIT*'s straight line on the empty map never is;
# a colliding path on a partly sensed map sometimes is), so its own problem set's paths of a
# quality are not the program's. The measurement on the own problem set stays the starting
# point, and it measures the cells the program does not reach.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
anytime="${ANYTIME:-anytime}"
workers="${WORKERS:-1}"
profiles="$here/anytime_motion/profiles"
measure() {  # MODULE TRIALS [OPTION...]
  local module="$1" trials="$2"
  shift 2
  "$anytime" profile "$module" --trials "$trials" --workers "$workers" --seed 0 "$@" \
    -o "$profiles/$module.yaml"
}
measure sense-obstacles "${SENSE_TRIALS:-200}" --quiet
measure rrt-star "${PLANNER_TRIALS:-100}" --quiet
measure bit-star "${PLANNER_TRIALS:-100}" --quiet
measure shorten-path "${SHORTEN_TRIALS:-60}" --quiet
measure shorten-path "${UPSTREAM_TRIALS:-100}" --quiet --rounds 3 \
  --upstream "$here/anytime_motion/schemas/motion.any" --schema move
