#include "stream/GltfInstancing.h"

#include "stream/GltfPrimitive.h"
#include "stream/util/Error.h"

#include <fmt/format.h>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include <cmath>
#include <string>

namespace penumbra {

GltfInstancing gltfInstancingOf(const GltfDocument& doc, int index) {
    const GltfNodeDesc& node = doc.nodes[size_t(index)];
    GltfInstancing out;
    out.translation = node.instanceTranslation, out.rotation = node.instanceRotation, out.scale = node.instanceScale;
    if (!out.any()) return out;
    const std::string where = fmt::format("{}: node {} EXT_mesh_gpu_instancing", doc.path, index);
    int first = -1;
    auto check = [&](int accessor, const char* name, int components) {
        if (accessor < 0) return;
        const GltfAccessor& a = doc.accessors[size_t(accessor)];
        if (a.components != components) fail(where, "{} accessor {} is not VEC{}", name, accessor, components);
        if (a.sparse || (a.bufferView < 0 && a.count > 0))
            fail(where, "{} accessor {} must be dense, with a bufferView", name, accessor);
        if (a.componentType == kGltfUnsignedInt)
            fail(where, "{} accessor {} has componentType {}, which glTF does not allow", name, accessor, a.componentType);
        if (first >= 0 && a.count != out.instances)
            fail(where, "{} accessor {} has {} elements, accessor {} has {}", name, accessor, a.count, first, out.instances);
        if (first < 0) first = accessor, out.instances = a.count;
    };
    check(out.translation, "TRANSLATION", 3);
    check(out.rotation, "ROTATION", 4);
    check(out.scale, "SCALE", 3);
    return out;
}

glm::dmat4 gltfInstanceLocal(const GltfDocument& doc, GltfBytes& bytes, const GltfInstancing& instancing, int node, uint64_t i) {
    glm::dmat4 local(1.0);  // T * R * S, as for node TRS
    if (!instancing.any()) return local;
    auto element = [&](int accessor) {
        const GltfAccessor& a = doc.accessors[size_t(accessor)];
        return decodeGltfElement(bytes.at(a.bufferView, a.byteOffset + i * a.stride, a.elementBytes), a);
    };
    if (instancing.translation >= 0) local = glm::translate(local, glm::dvec3(glm::vec3(element(instancing.translation))));
    if (instancing.rotation >= 0) {
        const glm::dvec4 q(element(instancing.rotation));
        if (glm::length(q) > 0) local *= glm::mat4_cast(glm::normalize(glm::dquat(q.w, q.x, q.y, q.z)));
    }
    if (instancing.scale >= 0) local = glm::scale(local, glm::dvec3(glm::vec3(element(instancing.scale))));
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            if (!std::isfinite(local[c][r]))
                fail(doc.path, "node {} EXT_mesh_gpu_instancing: instance {} has a non-finite transform", node, i);
    return local;
}

}  // namespace penumbra
