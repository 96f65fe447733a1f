#include "bake/output/LightmapGltf.h"
#include "stream/util/PathText.h"

#include "stream/GltfBuffers.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"

#include <tiny_gltf.h>

#include <glm/geometric.hpp>

#include <filesystem>
#include <sstream>

namespace penumbra {
namespace {

template <typename V>
int addVectors(tinygltf::Model& model, const std::vector<V>& values, int type) {
    return appendGltfAccessor(model, values.data(), values.size() * sizeof(V), TINYGLTF_COMPONENT_TYPE_FLOAT, type, values.size(),
                       TINYGLTF_TARGET_ARRAY_BUFFER);
}

void addMesh(tinygltf::Model& model, const IndexedMesh& mesh) {
    tinygltf::Primitive primitive;
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
    const int position = addVectors(model, mesh.position, TINYGLTF_TYPE_VEC3);
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (const glm::vec3& p : mesh.position) lo = glm::min(lo, p), hi = glm::max(hi, p);
    model.accessors[size_t(position)].minValues = {lo.x, lo.y, lo.z};
    model.accessors[size_t(position)].maxValues = {hi.x, hi.y, hi.z};
    primitive.attributes["POSITION"] = position;
    if (!mesh.normal.empty()) {
        // glTF requires unit normals; a vertex only degenerate triangles use has none, and any
        // unit vector serves it (it shades nothing).
        std::vector<glm::vec3> normal = mesh.normal;
        for (glm::vec3& n : normal)
            if (!(std::abs(glm::length(n) - 1.0f) < 1e-3f)) n = glm::vec3(0, 0, 1);
        primitive.attributes["NORMAL"] = addVectors(model, normal, TINYGLTF_TYPE_VEC3);
    }
    // glTF numbers texture coordinate sets from 0 without gaps: a mesh without its own
    // TEXCOORD_0 gets the lightmap coordinates there too.
    const int uv1 = addVectors(model, mesh.uv1, TINYGLTF_TYPE_VEC2);
    primitive.attributes["TEXCOORD_0"] = mesh.uv0.empty() ? uv1 : addVectors(model, mesh.uv0, TINYGLTF_TYPE_VEC2);
    primitive.attributes["TEXCOORD_1"] = uv1;
    primitive.indices = appendGltfAccessor(model, mesh.indices.data(), mesh.indices.size() * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                    TINYGLTF_TYPE_SCALAR, mesh.indices.size(), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    appendGltfMeshNode(model, mesh.name, std::move(primitive));
}

}  // namespace

void writeLightmapGltf(const std::string& path, std::span<const IndexedMesh> meshes, const std::string& lightmap) {
    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = "penumbra";
    model.asset.extras = tinygltf::Value(tinygltf::Value::Object{
        {"penumbra", tinygltf::Value(tinygltf::Value::Object{{"lightmap", tinygltf::Value(lightmap)}})}});
    model.buffers.emplace_back();
    tinygltf::Scene scene;
    for (const IndexedMesh& mesh : meshes) {
        if (mesh.indices.empty()) continue;  // glTF meshes need a primitive with data
        addMesh(model, mesh);
        scene.nodes.push_back(int(model.nodes.size() - 1));
    }
    model.scenes.push_back(scene);
    model.defaultScene = 0;
    std::string ext = lowercaseExtension(path);
    const bool binary = ext == ".glb";
    ensureParentDirectory(path);
    writeGltfModel(model, path, binary);
}

}  // namespace penumbra
