#include "stream/GltfDraco.h"

#include "stream/util/Memory.h"
#include "stream/util/Error.h"

#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>

#include <cmath>
#include <memory>

namespace penumbra {

DracoPrimitive decodeDracoPrimitive(const GltfDocument& doc, GltfBytes& bytes, const GltfPrimitiveLayout& layout,
                                    bool allAttributes) {
    const std::string where = layout.where(doc);
    const GltfPrimitiveDesc& desc = doc.meshes[size_t(layout.mesh)].primitives[size_t(layout.primitive)];
    const GltfBufferView& view = doc.views[size_t(desc.draco->bufferView)];
    if (view.meshopt) fail(where, "KHR_draco_mesh_compression data in a meshopt-compressed bufferView is not supported");
    std::vector<uint8_t> input(size_t(view.byteLength));
    bytes.copy(view.buffer, view.byteOffset, view.byteLength, input.data());

    std::unique_ptr<draco::Mesh> mesh;
    try {
        draco::DecoderBuffer buffer;
        buffer.Init(reinterpret_cast<const char*>(input.data()), input.size());
        draco::Decoder decoder;
        auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
        if (!decoded.ok())
            fail(where, "KHR_draco_mesh_compression data does not decode: {}", decoded.status().error_msg_string());
        mesh = std::move(decoded).value();
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {  // allocation failures inside the decoder
        fail(where, "KHR_draco_mesh_compression data does not decode: {}", e.what());
    }
    releaseStorage(input);
    if (!mesh) fail(where, "KHR_draco_mesh_compression data holds no mesh");

    const uint64_t points = mesh->num_points(), faces = mesh->num_faces();
    if (points != layout.vertices)
        fail(where, "Draco data decodes to {} vertices, but POSITION accessor {} has {}", points, layout.positions, layout.vertices);
    if (desc.indices >= 0 && doc.accessors[size_t(desc.indices)].count != 3 * faces)
        fail(where, "Draco data decodes to {} triangles, but indices accessor {} has {} elements", faces, desc.indices,
             doc.accessors[size_t(desc.indices)].count);

    auto values = [&](const std::string& name, int id, int components, auto&& store) {
        const draco::PointAttribute* a = mesh->GetAttributeByUniqueId(uint32_t(id));
        if (!a) fail(where, "Draco data has no attribute {} (for {})", id, name);
        float v[4] = {0, 0, 0, 0};
        for (uint32_t i = 0; i < points; ++i) {
            v[0] = v[1] = v[2] = v[3] = 0;
            if (!a->ConvertValue<float>(a->mapped_index(draco::PointIndex(i)), int8_t(std::min<int>(components, a->num_components())), v))
                fail(where, "Draco attribute {} (for {}) cannot be read as floats", id, name);
            store(i, v);
        }
    };
    DracoPrimitive out;
    for (const auto& [name, id] : desc.draco->attributes) {
        if (name == "POSITION") {
            out.positions.resize(size_t(points));
            values(name, id, 3, [&](uint32_t i, const float* v) { out.positions[i] = glm::vec3(v[0], v[1], v[2]); });
        } else if (allAttributes) {
            std::vector<glm::vec4> a(static_cast<size_t>(points));
            values(name, id, 4, [&](uint32_t i, const float* v) { a[i] = glm::vec4(v[0], v[1], v[2], v[3]); });
            out.attributes.emplace_back(name, std::move(a));
        }
    }
    if (out.positions.size() != points) fail(where, "KHR_draco_mesh_compression lists no POSITION attribute");
    out.indices.resize(size_t(3 * faces));
    for (uint32_t f = 0; f < faces; ++f) {
        const draco::Mesh::Face& face = mesh->face(draco::FaceIndex(f));
        for (int c = 0; c < 3; ++c) {
            const uint32_t index = face[c].value();
            if (index >= points) fail(where, "Draco face {} refers to point {} of {}", f, index, points);
            out.indices[3 * size_t(f) + size_t(c)] = index;
        }
    }
    return out;
}

}  // namespace penumbra
