#!/usr/bin/env bash
# Measure the plugin's profiles with the framework's own `anytime profile`, on the work clock,
# and write them into the package. Run from anywhere, with the environment's `anytime` on the
# PATH (or ANYTIME=path/to/anytime); the same seed gives the same files for any --workers.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
anytime="${ANYTIME:-anytime}"
python="$(dirname "$(command -v "$anytime")")/python"
site="$(mktemp -d)"
trap 'rm -rf "$site"' EXIT
# Installed as a user would install it: the entry point is what `anytime` finds.
# (From a copy: pip builds in place, and the source tree stays clean.)
mkdir "$site/source"
cp -r "$here/pyproject.toml" "$here/anytime_estimation" "$site/source/"
"$python" -m pip install --quiet --no-deps --target "$site/lib" "$site/source"
for module in estimate-volume read-label cube-side joint-side; do
  PYTHONPATH="$site/lib" "$anytime" profile "$module" --trials "${TRIALS:-2000}" \
    --workers "${WORKERS:-4}" --seed 0 --quiet -o "$here/anytime_estimation/profiles/$module.yaml"
done
