"""Opens penumbra's outputs in Blender (3.4, headless) and checks what a user would see there.

Run by run.sh:  blender -b --factory-startup --python check_outputs.py -- EXR GLB SCALE [VDB]
  EXR    a camera bake with two lights and two depth layers: one multilayer image, R,G,B,A as
         its Combined pass and visibility, depth and normal as passes of those names, and the
         layers light0, light1 and layer1 with their own passes (README, "Outputs")
  GLB    a vertex bake of examples/vertices-floor.glb placed at x SCALE: a colour attribute, and
         the floor's world size is 6 x SCALE (the scene transform is kept)
  VDB    optional, a volume bake: a Volume object with a grid named visibility
Exits 1 with one line per failed check.
"""
import sys

import bpy
import numpy as np

# Blender 3.4's glTF importer still uses np.bool, which NumPy 1.24 removed.
np.bool = bool

failures = []


def check(ok, message):
    print(("ok:   " if ok else "FAIL: ") + message)
    if not ok:
        failures.append(message)


def exr_passes(path):
    """The image and Blender's compositor Image node showing it: its outputs are the passes."""
    image = bpy.data.images.load(path)
    image.colorspace_settings.name = "Linear"
    scene = bpy.context.scene
    scene.use_nodes = True
    node = scene.node_tree.nodes.new("CompositorNodeImage")
    node.image = image
    return image, node, {o.name: o.type for o in node.outputs if o.enabled}


def check_exr(path):
    # A multilayer image has no pixel buffer of its own before something renders it, so the
    # checks are on what Blender parsed from the header: the passes and their kinds.
    image, node, outputs = exr_passes(path)
    check(image.type == "MULTILAYER", f"{path} opens as a multilayer image (type {image.type})")
    # R, G, B, A without a prefix are the Combined pass (and its Alpha), as a render's are; each
    # named layer is one pass with its channels grouped: visibility.V and depth.Z one value
    # each, normal.X/Y/Z one three-channel pass (Blender 3.4 gives it a colour socket).
    expect = {"Combined": ("RGBA",), "Alpha": ("VALUE",), "visibility": ("VALUE",), "depth": ("VALUE",),
              "normal": ("VECTOR", "RGBA")}
    for name, kinds in expect.items():
        check(outputs.get(name) in kinds, f"{path}: compositor Image node offers '{name}' as {' or '.join(kinds)} (outputs {outputs})")
    stray = sorted(set(outputs) - set(expect))
    check(not stray, f"{path}: no stray passes ({stray})")
    # Per-light passes and deeper surfaces are layers of their own, each with its passes grouped
    # (the node lists a layer's passes once the layer is chosen; an unknown name raises).
    layers = {"light0": {"irradiance", "visibility"}, "light1": {"irradiance", "visibility"},
              "layer1": {"Combined", "Alpha", "visibility", "depth", "normal"}}
    for layer, passes in layers.items():
        try:
            node.layer = layer
            seen = {o.name for o in node.outputs if o.enabled}
        except TypeError as error:
            seen = {f"no such layer: {error}"}
        check(seen == passes, f"{path}: layer '{layer}' has the passes {sorted(passes)} ({sorted(seen)})")


def world_box(objects):
    from mathutils import Vector
    corners = [o.matrix_world @ Vector(c) for o in objects for c in o.bound_box]
    lo = [min(c[i] for c in corners) for i in range(3)]
    hi = [max(c[i] for c in corners) for i in range(3)]
    return lo, hi


def check_glb(path, scale):
    bpy.ops.import_scene.gltf(filepath=path)
    meshes = {o.name: o for o in bpy.context.scene.objects if o.type == "MESH"}
    check("floor" in meshes, f"{path}: the floor mesh is imported (objects {sorted(meshes)})")
    if "floor" not in meshes:
        return
    floor = meshes["floor"]
    colours = [a.name for a in floor.data.color_attributes]
    check(len(colours) >= 1, f"{path}: the floor has a colour attribute ({colours})")
    if colours:
        attribute = floor.data.color_attributes[0]
        values = np.empty(len(attribute.data) * 4, dtype=np.float32)
        attribute.data.foreach_get("color", values)
        grey = values.reshape(-1, 4)[:, 0]
        check(grey.min() < 0.5 < grey.max(), f"{path}: the colours hold a shadow (min {grey.min():.3f}, max {grey.max():.3f})")
    lo, hi = world_box([floor])
    size = [h - l for l, h in zip(lo, hi)]
    # glTF is +Y up, Blender +Z up: the 6 x 6 floor in x and z lies in Blender's x and y.
    expect = 6.0 * scale
    check(abs(size[0] - expect) < 1e-3 * expect and abs(size[1] - expect) < 1e-3 * expect and size[2] < 1e-3,
          f"{path}: floor world size {size[0]:.4f} x {size[1]:.4f} x {size[2]:.4f}, expected {expect} x {expect} x 0")


def check_vdb(path):
    bpy.ops.object.volume_import(filepath=path)
    volumes = [o for o in bpy.context.scene.objects if o.type == "VOLUME"]
    check(len(volumes) == 1, f"{path}: one Volume object ({len(volumes)})")
    if volumes:
        grids = volumes[0].data.grids
        grids.load()
        names = [g.name for g in grids]
        check("visibility" in names, f"{path}: grid 'visibility' ({names})")
        # Lit voxels are active too, so the volume's bounds are the whole baked box (6 x 1.1 x 6
        # in run.sh's scene, voxels of 0.2), not just the shadowed part.
        bpy.context.view_layer.update()
        lo, hi = world_box(volumes)
        size = sorted(h - l for l, h in zip(lo, hi))
        check(abs(size[0] - 1.1) < 0.45 and abs(size[1] - 6) < 0.45 and abs(size[2] - 6) < 0.45,
              f"{path}: the volume's bounds are the baked box ({size[0]:.2f} x {size[1]:.2f} x {size[2]:.2f}, expected 1.1 x 6 x 6)")


def main():
    args = sys.argv[sys.argv.index("--") + 1:]
    check_exr(args[0])
    check_glb(args[1], float(args[2]))
    if len(args) > 3:
        check_vdb(args[3])
    if failures:
        print(f"{len(failures)} Blender check(s) failed")
        sys.exit(1)
    print("all Blender checks passed")


try:
    main()
except SystemExit:
    raise
except BaseException as error:  # a Blender-side exception must fail the test, not hang or pass
    print(f"FAIL: {type(error).__name__}: {error}")
    sys.exit(1)
