#pragma once
/// @file VertexColorKind.h
/// @brief The "vertices" receiver kind: one receiver per vertex of glTF meshes, written back as a
/// copy of the glTF with the result in vertex attributes.
///
/// Scene: `{"type": "vertices", "meshes": [0]}`, where each number indexes the scene's "geometry"
/// list and must name a glTF/glb file (its scene transform applies). Every vertex of every drawn
/// triangle primitive of that file becomes a receiver, placed by its node and scene transforms,
/// with the NORMAL attribute as its normal (else the area-weighted normals of its faces).
///
/// Output, per primitive: `_VISIBILITY` (float SCALAR, the visible fraction V) and `_IRRADIANCE`
/// (float VEC3, W/m^2), plus `COLOR_0` (float VEC3, V in every channel, i.e. a grey shadow term
/// that viewers multiply with the base colour) unless the primitive already has a `COLOR_0`,
/// which is then left alone. The copy goes to the scene output (`.glb` or `.gltf`, by extension;
/// a `.gltf` embeds its buffers); with several "meshes" entries, entry i is written to
/// `NAME-i.EXT`.

namespace penumbra {


}  // namespace penumbra
