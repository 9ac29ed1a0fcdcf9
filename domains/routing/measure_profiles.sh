#!/usr/bin/env bash
# Measure the routing plugin's profiles with the framework's own `anytime profile`, on the work
# clock, and write them into the package. Run with the environment's `anytime` on the PATH (or
# ANYTIME=path/to/anytime) and the plugin installed with its `measure` extra; the same seed
# gives the same files for any --workers.
#
# The tour planners are measured where the programs put them (`--upstream`): `plan-tours` on
# the clusterings `deliver` hands it under its compiled allocations, then `insert-tours` on
# those `deliver-best` hands it (compiled with the new `plan-tours`), each compiled and
# measured again until the compiled table moves by at most 0.005 (at most ROUNDS rounds); the
# input cells a program never reaches are measured on the module's own problem set. Each round
# is told as it ends (its reached cells and how far the compiled table moved).
# `plan-tour`, called in `deliver-each`'s loop (`map`), which `--upstream` does not reach, is
# measured on its own problem set, made with `deliver-each`'s compiled allocations: measure it
# after the other four.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
anytime="${ANYTIME:-anytime}"
workers="${WORKERS:-2}"
schemas="$here/anytime_routing/schemas/routing.any"
measure() {  # MODULE TRIALS [OPTION...]
  local module="$1" trials="$2"
  shift 2
  "$anytime" profile "$module" --trials "$trials" --workers "$workers" --seed 0 "$@" \
    -o "$here/anytime_routing/profiles/$module.yaml"
}
measure estimate-demand "${DEMAND_TRIALS:-2000}" --quiet
measure cluster-stops "${CLUSTER_TRIALS:-500}" --quiet
measure plan-tours "${TOUR_TRIALS:-300}" \
  --upstream "$schemas" --schema deliver --rounds "${ROUNDS:-3}"
measure insert-tours "${INSERT_TRIALS:-100}" \
  --upstream "$schemas" --schema deliver-best --rounds "${ROUNDS:-3}"
measure plan-tour "${DEPOT_TRIALS:-300}" --quiet
