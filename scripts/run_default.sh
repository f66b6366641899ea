#!/usr/bin/env bash
# Set everything up and run the main job on the built-in default synthetic scene:
# render the scene (datasets_synthetic/default.toml), then run the pipeline on it.
# Outputs go to out/ (override with OUT=...).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
OUT="${OUT:-out}"
PY=.venv/bin/python
$PY recipes/make_scene.py datasets_synthetic/default.toml --out "$OUT/default_scene" --overwrite
$PY recipes/free_viewpoint.py "$OUT/default_scene" --out "$OUT/default_fvv" --replace-stale
echo
echo "Done. Open the recordings with:"
echo "  .venv/bin/rerun $OUT/default_scene/scene.rrd     (the scene and its ground truth)"
echo "  .venv/bin/rerun $OUT/default_fvv/recording.rrd   (every stage of the pipeline)"
