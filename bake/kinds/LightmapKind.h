#pragma once
/// @file LightmapKind.h
/// @brief The "lightmap" receiver kind: a receiver per covered texel of the named meshes' UV
/// layouts, written as one EXR texture (plus a PNG preview) per mesh, and one shared atlas for
/// the meshes whose UVs are generated.
///
/// Scene: `{"type": "lightmap", "meshes": [0, 2], "resolution": 512, "padding": 4}`, where each
/// number indexes the scene's "geometry" list and must name an obj/gltf/glb file (its transform
/// applies; the mesh still casts shadows through the geometry stream). `resolution` is an int or
/// [w, h]; `texels_per_unit` (instead of `resolution`) picks a square size from the mesh's world
/// and UV areas, or the atlas's density. `uv` ("auto", "mesh", "generate") says which meshes get
/// generated UVs (receivers/LightmapAtlas.h); meshes without normals get crease-angle normals
/// (`crease_angle_deg`). Output: for the scene output `out/lightmap.exr`, `out/lightmap-NAME.exr`
/// with channels R, G, B (irradiance), A (UV coverage) and visibility.V, dilated `padding` texels beyond the
/// coverage, and `out/lightmap-NAME.png`, the tone-mapped irradiance; NAME is "atlas" for the
/// atlas, whose meshes go to `out/lightmap-uv1.glb` with the atlas as TEXCOORD_1. See
/// docs/scene-format.md.

namespace penumbra {


}  // namespace penumbra
