#!/usr/bin/env bash
# Opens a camera bake's EXR, a vertex bake's glTF and a volume bake's VDB in Blender 3.4 headless
# (Debian's `blender`) and checks what Blender sees (check_outputs.py). Skips with 77 when Blender
# is not installed, which ./setup.sh test does.
# Usage: run.sh PENUMBRA SOURCE_DIR
set -euo pipefail
penumbra=$1
source_dir=$2
if ! command -v blender >/dev/null 2>&1; then
  echo "blender_import: notice: blender not found (Debian package 'blender', installed by ./setup.sh test); skipped"
  exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp "$source_dir/examples/vertices-floor.glb" "$work/"
light='{"type": "rect", "center": [0.8, 4, 0.4], "u": [1.5, 0, 0], "v": [0, 0, 1.5], "radiance": [10, 10, 10], "samples": 64}'
# Two lights and two depth layers: light<i>.* and layer1.* must be layers of their own in Blender.
cat >"$work/camera.json" <<JSON
{"geometry": [{"type": "glb", "path": "vertices-floor.glb"}],
 "lights": [$light, {"type": "rect", "center": [-0.8, 4, 0.4], "u": [1.5, 0, 0], "v": [0, 0, 1.5], "radiance": [5, 5, 5], "samples": 16}],
 "receivers": {"type": "camera", "eye": [0, 5, 6], "target": [0, 0, 0], "width": 96, "height": 64, "layers": 2},
 "output": "camera.exr"}
JSON
cat >"$work/vertices.json" <<JSON
{"geometry": [{"type": "glb", "path": "vertices-floor.glb", "transform": {"scale": 2}}],
 "lights": [{"type": "rect", "center": [1.6, 8, 0.8], "u": [3, 0, 0], "v": [0, 0, 3], "radiance": [10, 10, 10], "samples": 64}],
 "receivers": {"type": "vertices", "meshes": [0]}, "output": "vertices.glb"}
JSON
cat >"$work/volume.json" <<JSON
{"geometry": [{"type": "glb", "path": "vertices-floor.glb"}], "lights": [$light],
 "receivers": {"type": "volume", "box": [[-3, 0.05, -3], [3, 1.15, 3]], "voxel_size": 0.2},
 "output": "volume.vdb"}
JSON
for scene in camera vertices volume; do
  "$penumbra" bake "$work/$scene.json" --quiet
done
# --python-exit-code: an uncaught Python error fails the test instead of exiting 0.
code=0
blender -b --factory-startup --python-exit-code 1 --python "$source_dir/tests/tools/blender/check_outputs.py" \
  -- "$work/camera.exr" "$work/vertices.glb" 2 "$work/volume.vdb" >"$work/blender.log" 2>&1 || code=$?
# Blender's own chatter (add-on registration, "Blender quit") is left out unless it failed.
if [ "$code" -ne 0 ]; then cat "$work/blender.log"; else grep -E '^(ok|info|all)' "$work/blender.log"; fi
exit "$code"
