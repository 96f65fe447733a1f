#include "stream/GltfMeshWriter.h"

#include "stream/GltfBuffers.h"
#include "stream/util/Error.h"

#include <tiny_gltf.h>

#include <glm/common.hpp>

#include <cstdint>

#include <cstring>
#include <limits>
#include <unordered_map>

namespace penumbra {
namespace {

/// A vertex's bits: position, normal and UVs as written, so that welding never merges two
/// vertices that differ in any bit (and -0 stays apart from +0, as a reader would see it).
std::string vertexKey(const IndexedMesh& m, size_t v) {
    std::string key(reinterpret_cast<const char*>(&m.position[v]), sizeof(glm::vec3));
    if (!m.normal.empty()) key.append(reinterpret_cast<const char*>(&m.normal[v]), sizeof(glm::vec3));
    if (!m.uv0.empty()) key.append(reinterpret_cast<const char*>(&m.uv0[v]), sizeof(glm::vec2));
    if (!m.uv1.empty()) key.append(reinterpret_cast<const char*>(&m.uv1[v]), sizeof(glm::vec2));
    return key;
}

/// A position's bits, for welding by exact equality (-0 and +0 stay apart, as a reader sees them).
struct PositionBits {
    uint32_t x, y, z;
    static PositionBits of(const glm::vec3& p) {
        PositionBits b;
        std::memcpy(&b, &p, sizeof b);
        return b;
    }
    bool operator==(const PositionBits&) const = default;
};
struct PositionBitsHash {
    size_t operator()(const PositionBits& b) const {
        uint64_t h = (uint64_t(b.x) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(b.y) * 0xC2B2AE3D27D4EB4Full) ^ (uint64_t(b.z) * 0x165667B19E3779F9ull);
        return size_t(h ^ (h >> 29));
    }
};

/// One mesh of the model: its accessors, a mesh and a node in the scene.
void appendMesh(tinygltf::Model& model, const IndexedMesh& m) {
    tinygltf::Primitive primitive;
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
    const size_t n = m.position.size();
    primitive.attributes["POSITION"] =
        appendGltfAccessor(model, m.position.data(), n * sizeof(glm::vec3), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n,
                       TINYGLTF_TARGET_ARRAY_BUFFER);
    glm::vec3 lo = n ? m.position[0] : glm::vec3(0.f), hi = lo;
    for (const glm::vec3& p : m.position) lo = glm::min(lo, p), hi = glm::max(hi, p);
    model.accessors.back().minValues = {lo.x, lo.y, lo.z};  // required for POSITION by the spec
    model.accessors.back().maxValues = {hi.x, hi.y, hi.z};
    if (!m.normal.empty())
        primitive.attributes["NORMAL"] = appendGltfAccessor(model, m.normal.data(), n * sizeof(glm::vec3), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                        TINYGLTF_TYPE_VEC3, n, TINYGLTF_TARGET_ARRAY_BUFFER);
    auto uvs = [&](const std::vector<glm::vec2>& uv, const char* name) {
        if (uv.empty()) return;
        primitive.attributes[name] = appendGltfAccessor(model, uv.data(), n * sizeof(glm::vec2), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                    TINYGLTF_TYPE_VEC2, n, TINYGLTF_TARGET_ARRAY_BUFFER);
    };
    uvs(m.uv0, "TEXCOORD_0");  // IndexedMesh holds glTF's convention (an OBJ's v is flipped on load)
    uvs(m.uv1, "TEXCOORD_1");
    primitive.indices = appendGltfAccessor(model, m.indices.data(), m.indices.size() * sizeof(uint32_t),
                                       TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, m.indices.size(),
                                       TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    model.scenes[0].nodes.push_back(appendGltfMeshNode(model, m.name, std::move(primitive)));
}

}  // namespace

IndexedMesh weldVertices(const IndexedMesh& m) {
    IndexedMesh out;
    out.name = m.name;
    std::unordered_map<std::string, uint32_t> index;
    std::vector<uint32_t> remap(m.position.size());
    for (size_t v = 0; v < m.position.size(); ++v) {
        auto [it, added] = index.emplace(vertexKey(m, v), uint32_t(out.position.size()));
        if (added) {
            out.position.push_back(m.position[v]);
            if (!m.normal.empty()) out.normal.push_back(m.normal[v]);
            if (!m.uv0.empty()) out.uv0.push_back(m.uv0[v]);
            if (!m.uv1.empty()) out.uv1.push_back(m.uv1[v]);
        }
        remap[v] = it->second;
    }
    out.indices.reserve(m.indices.size());
    for (uint32_t i : m.indices) out.indices.push_back(remap[i]);
    return out;
}

IndexedMesh meshOfTriangles(TriangleSource& source, std::string name) {
    IndexedMesh mesh;
    mesh.name = std::move(name);
    std::unordered_map<PositionBits, uint32_t, PositionBitsHash> index;
    source.rewind();
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t n = source.read(chunk))
        for (size_t t = 0; t < n; ++t)
            for (const glm::vec3& p : chunk[t].v) {
                if (mesh.position.size() >= std::numeric_limits<uint32_t>::max())
                    fail(source.name(), "more than 2^32 distinct vertices do not fit in one glTF mesh");
                auto [it, added] = index.emplace(PositionBits::of(p), uint32_t(mesh.position.size()));
                if (added) mesh.position.push_back(p);
                mesh.indices.push_back(it->second);
            }
    source.rewind();
    return mesh;
}

void writeIndexedGltf(const std::vector<IndexedMesh>& meshes, const std::string& path, bool binary) {
    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = "penumbra";
    uint64_t bytes = 0;
    for (const IndexedMesh& m : meshes)
        bytes += m.position.size() * (12 + (m.normal.empty() ? 0 : 12) + (m.uv0.empty() ? 0 : 8) + (m.uv1.empty() ? 0 : 8)) +
                 m.indices.size() * 4 + 16;
    // A GLB's length fields are 32-bit; stay well inside them (headers and JSON need room too).
    if (bytes > std::numeric_limits<uint32_t>::max() - (1u << 20))
        fail(path, "{} bytes of vertices and indices do not fit in one glTF buffer (at most 4 GiB)", bytes);
    bool any = false;
    for (const IndexedMesh& m : meshes) any = any || !m.indices.empty();
    if (any) {  // an empty model has no scene: tinygltf would write it as null, which it then rejects
        model.buffers.emplace_back();
        model.scenes.emplace_back();
        model.defaultScene = 0;
        for (const IndexedMesh& m : meshes)
            if (!m.indices.empty()) appendMesh(model, m);
    }
    writeGltfModel(model, path, binary);
}

}  // namespace penumbra
