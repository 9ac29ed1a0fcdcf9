#!/usr/bin/env bash
# Measure the routing plugin's profiles with the framework's own `anytime profile`, on the work
# clock, and write them into the package. Run with the environment's `anytime` on the PATH (or
# ANYTIME=path/to/anytime) and the plugin installed with its `measure` extra; the same seed
# gives the same files for any --workers.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
anytime="${ANYTIME:-anytime}"
workers="${WORKERS:-2}"
measure() {  # MODULE TRIALS
  "$anytime" profile "$1" --trials "$2" --workers "$workers" --seed 0 --quiet \
    -o "$here/anytime_routing/profiles/$1.yaml"
}
measure estimate-demand "${DEMAND_TRIALS:-2000}"
measure cluster-stops "${CLUSTER_TRIALS:-500}"
measure plan-tours "${TOUR_TRIALS:-300}"
measure insert-tours "${INSERT_TRIALS:-100}"
measure plan-tour "${DEPOT_TRIALS:-300}"
