#!/usr/bin/env bash
# Measure the motion plugin's profiles with the framework's own `anytime profile`, on the work
# clock (ticks: ray casts and OMPL validity checks), and write them into the package. Run with
# the environment's `anytime` on the PATH (or ANYTIME=path/to/anytime) and the plugin
# installed; the same seed gives the same files for any --workers (OMPL's random numbers are
# seeded from each problem's seed, drawn from the framework's seed stream).
#
# The trial counts are small on purpose (minutes, not hours, on one core): 200 problems for
# the sensor, 100 per input cell for the planners, 60 for the shortcutting (see README.md).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
anytime="${ANYTIME:-anytime}"
workers="${WORKERS:-1}"
measure() {  # MODULE TRIALS [OPTION...]
  local module="$1" trials="$2"
  shift 2
  "$anytime" profile "$module" --trials "$trials" --workers "$workers" --seed 0 "$@" \
    -o "$here/anytime_motion/profiles/$module.yaml"
}
measure sense-obstacles "${SENSE_TRIALS:-200}" --quiet
measure rrt-star "${PLANNER_TRIALS:-100}" --quiet
measure bit-star "${PLANNER_TRIALS:-100}" --quiet
measure shorten-path "${SHORTEN_TRIALS:-60}" --quiet
