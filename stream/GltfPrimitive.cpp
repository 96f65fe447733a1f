#include "stream/GltfPrimitive.h"

#include "stream/util/Error.h"
#include "stream/GltfDraco.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

namespace penumbra {
namespace {

const char* modeName(int mode) {
    switch (mode) {
    case 0: return "POINTS";
    case 1: return "LINES";
    case 2: return "LINE_LOOP";
    case 3: return "LINE_STRIP";
    default: return "unknown-mode";
    }
}

bool isUnsignedIndexType(int type) {
    return type == kGltfUnsignedByte || type == kGltfUnsignedShort || type == kGltfUnsignedInt;
}

}  // namespace

std::string GltfPrimitiveLayout::where(const GltfDocument& doc) const {
    return fmt::format("{}: mesh {} primitive {}", doc.path, mesh, primitive);
}

void GltfSkipped::warn(const std::string& path) const {
    for (const auto& [mode, count] : modes)
        fmt::print(stderr, "penumbra: warning: {}: skipped {} {} primitive{} (only triangles cast shadows)\n", path, count,
                   modeName(mode), count == 1 ? "" : "s");
    if (withoutPositions > 0)
        fmt::print(stderr, "penumbra: warning: {}: skipped {} primitive{} without POSITION\n", path, withoutPositions,
                   withoutPositions == 1 ? "" : "s");
}

uint64_t dracoDecodeBytes(uint64_t vertices, uint64_t indices, uint64_t compressedBytes) {
    // The decoded arrays (12 bytes per position, 4 per index), the decoder's mesh (its attribute
    // values and faces, about as much again), its corner table (about 40 bytes per corner) and
    // the compressed input.
    return vertices * (12 + 24) + indices * (4 + 4 + 40) + compressedBytes + (1u << 20);
}

std::optional<GltfPrimitiveLayout> gltfTrianglePrimitive(const GltfDocument& doc, int m, int p, GltfSkipped* skipped) {
    const GltfPrimitiveDesc& prim = doc.meshes[size_t(m)].primitives[size_t(p)];
    GltfPrimitiveLayout g;
    g.mesh = m, g.primitive = p, g.mode = prim.mode;
    const std::string where = g.where(doc);
    if (prim.mode != kGltfTriangles && prim.mode != kGltfTriangleStrip && prim.mode != kGltfTriangleFan) {
        if (skipped) ++skipped->modes[prim.mode];
        return std::nullopt;
    }
    g.positions = prim.attribute("POSITION");
    if (g.positions < 0) {
        if (skipped) ++skipped->withoutPositions;  // the spec says such primitives are not rendered
        return std::nullopt;
    }
    const GltfAccessor& positions = doc.accessors[size_t(g.positions)];
    if (positions.components != 3) fail(where, "POSITION accessor {} is not VEC3", g.positions);
    if (positions.componentType == kGltfUnsignedInt)
        fail(where, "POSITION accessor {} has componentType {}, which glTF does not allow", g.positions, positions.componentType);
    g.draco = prim.draco.has_value();
    if (g.draco && positions.sparse) fail(where, "POSITION accessor {} of a Draco-compressed primitive is sparse", g.positions);
    // Without a bufferView every position is zero but for sparse substitutions: a count bounded
    // by nothing but the JSON (a tiny file could ask for 2^60 of them) of degenerate triangles.
    // With substitutions it is still bounded by the 32-bit indices that reach them.
    if (!g.draco && positions.bufferView < 0 && positions.count > 0 &&
        (!positions.sparse || positions.count > std::numeric_limits<uint32_t>::max()))
        fail(where, "POSITION accessor {} has no bufferView", g.positions);
    g.vertices = positions.count;

    uint64_t sequence = positions.count;  // vertices in drawing order
    g.indices = prim.indices;
    if (g.indices >= 0) {
        const GltfAccessor& indices = doc.accessors[size_t(g.indices)];
        if (indices.components != 1) fail(where, "indices accessor {} is not SCALAR", g.indices);
        if (!isUnsignedIndexType(indices.componentType))
            fail(where, "indices accessor {} has componentType {} (must be an unsigned integer type)", g.indices,
                 indices.componentType);
        if (g.draco && indices.sparse) fail(where, "indices accessor {} of a Draco-compressed primitive is sparse", g.indices);
        if (!g.draco && indices.bufferView < 0 && indices.count > 0 && !indices.sparse)
            fail(where, "indices accessor {} has no bufferView", g.indices);
        sequence = indices.count;
    }
    if (g.draco) {
        if (prim.mode != kGltfTriangles) fail(where, "KHR_draco_mesh_compression needs mode TRIANGLES, not {}", prim.mode);
        if (g.indices < 0) fail(where, "KHR_draco_mesh_compression primitive has no indices accessor");
        g.decodeBytes = dracoDecodeBytes(g.vertices, sequence, doc.views[size_t(prim.draco->bufferView)].byteLength);
    } else {
        g.decodeBytes = gltfDecodedViewBytes(doc, positions.bufferView) +
                        (g.indices >= 0 ? gltfDecodedViewBytes(doc, doc.accessors[size_t(g.indices)].bufferView) : 0);
        for (const auto& [name, accessor] : prim.attributes) g.sparseBytes += gltfSparseBytes(doc, accessor);
        g.sparseBytes += gltfSparseBytes(doc, g.indices);
        g.decodeBytes += g.sparseBytes;
    }
    if (prim.mode == kGltfTriangles) {
        if (sequence % 3 != 0) fail(where, "TRIANGLES primitive has {} vertices, not a multiple of 3", sequence);
        g.triangles = sequence / 3;
    } else {
        g.triangles = sequence >= 3 ? sequence - 2 : 0;
    }
    return g;
}

std::array<uint64_t, 3> gltfTriangleCorners(int mode, uint64_t t) {
    switch (mode) {
    case kGltfTriangleStrip: return {t, t + 1 + t % 2, t + 2 - t % 2};  // every other one flipped
    case kGltfTriangleFan: return {t + 1, t + 2, 0};
    default: return {3 * t, 3 * t + 1, 3 * t + 2};
    }
}

glm::vec4 decodeGltfElement(const uint8_t* at, const GltfAccessor& a) {
    glm::vec4 p(0.0f);
    if (!at) return p;
    for (int c = 0; c < std::min(a.components, 4); ++c) {
        switch (a.componentType) {
        case kGltfFloat: std::memcpy(&p[c], at + 4 * c, 4); break;
        case kGltfByte: {
            auto x = static_cast<int8_t>(at[c]);
            p[c] = a.normalized ? std::max(float(x) / 127.0f, -1.0f) : float(x);
            break;
        }
        case kGltfUnsignedByte: p[c] = a.normalized ? float(at[c]) / 255.0f : float(at[c]); break;
        case kGltfShort: {
            int16_t x;
            std::memcpy(&x, at + 2 * c, 2);
            p[c] = a.normalized ? std::max(float(x) / 32767.0f, -1.0f) : float(x);
            break;
        }
        case kGltfUnsignedShort: {
            uint16_t x;
            std::memcpy(&x, at + 2 * c, 2);
            p[c] = a.normalized ? float(x) / 65535.0f : float(x);
            break;
        }
        case kGltfUnsignedInt: {
            uint32_t x;
            std::memcpy(&x, at + 4 * c, 4);
            p[c] = float(x);
            break;
        }
        }
    }
    return p;
}

GltfPrimitiveReader::GltfPrimitiveReader(const GltfDocument& doc, GltfBytes& bytes, const GltfPrimitiveLayout& layout,
                                         bool attributes)
    : doc_(doc), bytes_(bytes), layout_(layout), desc_(doc.meshes[size_t(layout.mesh)].primitives[size_t(layout.primitive)]) {
    if (layout.draco) {
        draco_ = std::make_unique<DracoPrimitive>(decodeDracoPrimitive(doc, bytes, layout, attributes));
        return;
    }
    positions_.emplace(doc, bytes, layout.positions, layout.where(doc));
    if (layout.indices >= 0) indices_.emplace(doc, bytes, layout.indices, layout.where(doc));
}

GltfPrimitiveReader::~GltfPrimitiveReader() = default;

uint32_t GltfPrimitiveReader::sequence(uint64_t i) {
    if (draco_) return draco_->indices[size_t(i)];
    if (layout_.indices < 0) return uint32_t(i);
    const GltfAccessor& a = indices_->accessor();
    uint32_t index = 0;
    if (const uint8_t* p = indices_->at(i)) {
        if (a.componentType == kGltfUnsignedByte) index = *p;
        else if (a.componentType == kGltfUnsignedShort) {
            uint16_t x;
            std::memcpy(&x, p, 2);
            index = x;
        } else {
            std::memcpy(&index, p, 4);
        }
    }
    if (index >= layout_.vertices)
        fail(doc_.path, "mesh {} primitive {}: accessor {} element {} is index {}, but POSITION accessor {} has {} vertices",
             layout_.mesh, layout_.primitive, layout_.indices, i, index, layout_.positions, layout_.vertices);
    return index;
}

std::array<uint32_t, 3> GltfPrimitiveReader::triangle(uint64_t t) {
    const std::array<uint64_t, 3> c = gltfTriangleCorners(layout_.mode, t);
    return {sequence(c[0]), sequence(c[1]), sequence(c[2])};
}

glm::vec3 GltfPrimitiveReader::position(uint64_t v) {
    glm::vec3 p;
    if (draco_) {
        p = draco_->positions[size_t(v)];
    } else {
        p = glm::vec3(decodeGltfElement(positions_->at(v), positions_->accessor()));
    }
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        fail(layout_.where(doc_), "POSITION accessor {} element {} is not finite", layout_.positions, v);
    return p;
}

bool GltfPrimitiveReader::has(const std::string& name) const { return desc_.attribute(name) >= 0; }

GltfElements& GltfPrimitiveReader::checkedAttribute(const std::string& name, int components) {
    const int index = desc_.attribute(name);
    for (auto& [accessor, elements] : attributes_)
        if (accessor == index) return elements;
    const std::string where = layout_.where(doc_);
    if (index < 0) fail(where, "has no {} attribute", name);
    const GltfAccessor& a = doc_.accessors[size_t(index)];
    if (a.components != components) fail(where, "{} accessor {} is not VEC{}", name, index, components);
    if (a.count != layout_.vertices)
        fail(where, "{} accessor {} has {} elements, POSITION has {}", name, index, a.count, layout_.vertices);
    if (!draco_ && a.bufferView < 0 && a.count > 0 && !a.sparse) fail(where, "{} accessor {} has no bufferView", name, index);
    if (draco_ && a.sparse) fail(where, "{} accessor {} of a Draco-compressed primitive is sparse", name, index);
    if (a.componentType == kGltfUnsignedInt)
        fail(where, "{} accessor {} has componentType {}, which glTF does not allow", name, index, a.componentType);
    return attributes_.emplace_back(index, GltfElements(doc_, bytes_, index, where)).second;
}

glm::vec4 GltfPrimitiveReader::attribute(const std::string& name, int components, uint64_t v) {
    GltfElements& elements = checkedAttribute(name, components);
    glm::vec4 x;
    if (draco_) {
        auto it = std::find_if(draco_->attributes.begin(), draco_->attributes.end(), [&](const auto& e) { return e.first == name; });
        if (it == draco_->attributes.end()) fail(layout_.where(doc_), "{} is not in the Draco data", name);
        x = it->second[size_t(v)];
    } else {
        x = decodeGltfElement(elements.at(v), elements.accessor());
    }
    if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z) || !std::isfinite(x.w))
        fail(layout_.where(doc_), "{} accessor {} element {} is not finite", name, desc_.attribute(name), v);
    return x;
}

}  // namespace penumbra
