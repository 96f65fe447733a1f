#include "stream/GltfConvert.h"

#include "stream/GltfBytes.h"
#include "stream/GltfDocument.h"
#include "stream/GltfInstancing.h"
#include "stream/GltfPrimitive.h"
#include "stream/IndexedMesh.h"
#include "stream/ObjTokenizer.h"
#include "stream/PolygonTriangulation.h"
#include "stream/VertexStore.h"
#include "stream/util/Error.h"
#include "stream/util/PathText.h"
#include "stream/util/Progress.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>

namespace penumbra {
namespace {

// ---------------------------------------------------------------------------------------------
// OBJ

/// An o/g group: one output mesh, with the attributes every corner of it names.
struct ObjGroup {
    std::string name;
    bool faces = false, uv = true, normal = true;
    int mesh = -1;
};

/// The groups in the order they first appear (ObjGroupIndex, as IndexedMesh.cpp's loader).
struct ObjGroups {
    std::vector<ObjGroup> list{1};
    ObjGroupIndex index;
    size_t current = 0;

    void select(std::string_view name) {
        current = index.select(name);
        if (current == list.size()) list.emplace_back().name = name;
    }
};

/// Calls @p statement(tokens, kind, where) for every line of the OBJ at @p path, with a progress
/// phase named @p phase.
template <typename Statement>
void forEachObjStatement(const std::string& path, const char* phase, Statement&& statement) {
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, "cannot open: {}", std::strerror(errno));
    std::error_code sizeError;
    const uint64_t fileBytes = std::filesystem::file_size(path, sizeError);
    OpeningPhase progress(std::string(phase) + " " + std::filesystem::path(path).filename().string(), sizeError ? 0 : fileBytes);
    ObjLocation where{path, 0};
    uint64_t bytes = 0;
    for (std::string text; std::getline(in, text);) {
        ++where.line;
        ObjTokens tokens(objLineText(text, where.line));
        statement(tokens, tokens.next(), where);
        progress.advance(bytes += text.size() + 1);  // with its '\n'
    }
    if (in.bad()) fail(path, "read error");
    progress.finish();
}

/// The first pass: every statement checked, the groups and their attributes found.
uint64_t checkObj(const std::string& path, ObjGroups& groups) {
    uint64_t counts[3] = {0, 0, 0}, faces = 0;  // v, vt, vn
    std::vector<ObjCorner> face;
    forEachObjStatement(path, "check", [&](ObjTokens& tokens, std::string_view kind, const ObjLocation& where) {
        if (kind == "v") {
            parseObjVector(tokens, 3, "vertex", where), ++counts[0];
        } else if (kind == "vt") {
            parseObjVector(tokens, 2, "texture coordinate", where), ++counts[1];
        } else if (kind == "vn") {
            parseObjVector(tokens, 3, "normal", where), ++counts[2];
        } else if (kind == "o" || kind == "g") {
            groups.select(tokens.rest());
        } else if (kind == "f") {
            parseObjFace(tokens, counts, face, where);
            ObjGroup& group = groups.list[groups.current];
            group.faces = true;
            for (const ObjCorner& c : face) group.uv &= c.vt >= 0, group.normal &= c.vn >= 0;
            ++faces;
        }
    });
    return faces;
}

void addObjMeshes(const std::string& path, GltfStreamWriter& out) {
    ObjGroups checked;
    const uint64_t faces = checkObj(path, checked);
    size_t withFaces = 0;
    for (const ObjGroup& g : checked.list) withFaces += g.faces;
    const std::string stem = std::filesystem::path(path).stem().string();
    for (ObjGroup& g : checked.list)
        if (g.faces) g.mesh = out.addMesh(withFaces == 1 || g.name.empty() ? stem : g.name, {g.normal, g.uv, false});

    VertexStore v(path), vt(path), vn(path);  // vt as (u, 1 - v, 0): glTF's top-left origin
    ObjGroups groups;
    const MeshPlacement identity{glm::dmat4(1.0)};
    std::vector<ObjCorner> face;
    std::vector<glm::vec3> positions;
    std::vector<std::array<uint32_t, 3>> triangles;
    uint64_t seen = 0;
    auto changed = [&] { fail(path, "file changed while it was being read: {} faces when checked, {} in this pass", faces, seen); };
    forEachObjStatement(path, "load", [&](ObjTokens& tokens, std::string_view kind, const ObjLocation& where) {
        if (kind == "v") {
            v.push(parseObjVector(tokens, 3, "vertex", where));
        } else if (kind == "vt") {
            const glm::vec3 t = parseObjVector(tokens, 2, "texture coordinate", where);
            vt.push(glm::vec3(t.x, float(1.0 - double(t.y)), 0.0f));
        } else if (kind == "vn") {
            vn.push(parseObjVector(tokens, 3, "normal", where));
        } else if (kind == "o" || kind == "g") {
            groups.select(tokens.rest());
        } else if (kind == "f") {
            const uint64_t counts[3] = {v.size(), vt.size(), vn.size()};
            parseObjFace(tokens, counts, face, where);
            if (++seen > faces || groups.current >= checked.list.size()) changed();
            const ObjGroup& group = checked.list[groups.current];
            positions.resize(face.size());
            for (size_t c = 0; c < face.size(); ++c) positions[c] = v[uint64_t(face[c].v)];
            triangulatePolygon(positions, triangles);  // as the blocker stream does (ObjReader.cpp)
            for (const std::array<uint32_t, 3>& t : triangles) {
                std::array<GltfCorner, 3> corners;
                for (int k = 0; k < 3; ++k) {
                    const ObjCorner& c = face[t[size_t(k)]];
                    corners[size_t(k)].position = positions[t[size_t(k)]];
                    if (group.normal) corners[size_t(k)].normal = identity.normal(unitOrZero(vn[uint64_t(c.vn)]));
                    if (group.uv) corners[size_t(k)].uv0 = glm::vec2(vt[uint64_t(c.vt)]);
                }
                out.addTriangle(group.mesh, corners);
            }
        }
    });
    if (seen != faces) changed();
}

// ---------------------------------------------------------------------------------------------
// glTF

/// The attributes every triangle primitive of mesh @p m has, from the document alone (a reader
/// would decode a Draco primitive to answer).
GltfVertexLayout commonLayout(const GltfDocument& doc, int m) {
    GltfVertexLayout common{true, true, true};
    for (size_t p = 0; p < doc.meshes[size_t(m)].primitives.size(); ++p) {
        if (!gltfTrianglePrimitive(doc, m, int(p))) continue;
        const GltfPrimitiveDesc& desc = doc.meshes[size_t(m)].primitives[p];
        common.normal &= desc.attribute("NORMAL") >= 0, common.uv0 &= desc.attribute("TEXCOORD_0") >= 0;
        common.uv1 &= desc.attribute("TEXCOORD_1") >= 0;
    }
    return common;
}

/// Mesh @p m's triangle primitives, placed by @p placement, as the triangles of output mesh @p id.
void addGltfMesh(const GltfDocument& doc, GltfBytes& bytes, int m, const MeshPlacement& placement, GltfVertexLayout layout,
                 int id, GltfStreamWriter& out) {
    for (size_t p = 0; p < doc.meshes[size_t(m)].primitives.size(); ++p) {
        const auto primitive = gltfTrianglePrimitive(doc, m, int(p));
        if (!primitive) continue;  // points and lines have no surface (the blocker reader warns)
        GltfPrimitiveReader reader(doc, bytes, *primitive, true);
        for (uint64_t t = 0; t < primitive->triangles; ++t) {
            const std::array<uint32_t, 3> v = reader.triangle(t);
            std::array<GltfCorner, 3> corners;
            for (size_t k = 0; k < 3; ++k) {
                GltfCorner& c = corners[k];
                c.position = placement.position(reader.position(v[k]));
                if (!std::isfinite(c.position.x) || !std::isfinite(c.position.y) || !std::isfinite(c.position.z))
                    fail(doc.path, "a transformed vertex position is not finite");
                if (layout.normal) c.normal = placement.normal(unitOrZero(glm::vec3(reader.attribute("NORMAL", 3, v[k]))));
                if (layout.uv0) c.uv0 = glm::vec2(reader.attribute("TEXCOORD_0", 2, v[k]));
                if (layout.uv1) c.uv1 = glm::vec2(reader.attribute("TEXCOORD_1", 2, v[k]));
            }
            if (placement.mirrors) std::swap(corners[1], corners[2]);
            out.addTriangle(id, corners);
        }
    }
}

/// Triangles of mesh @p m's triangle primitives, in all and with materials that cut out or let
/// light through (alphaMode MASK or BLEND), which the output carries as plain surfaces.
std::pair<uint64_t, uint64_t> meshTriangles(const GltfDocument& doc, int m) {
    uint64_t all = 0, notOpaque = 0;
    for (size_t p = 0; p < doc.meshes[size_t(m)].primitives.size(); ++p) {
        const auto primitive = gltfTrianglePrimitive(doc, m, int(p));
        if (!primitive) continue;
        all += primitive->triangles;
        const int material = doc.meshes[size_t(m)].primitives[p].material;
        if (material >= 0 && doc.materials.materials[size_t(material)].alphaMode != GltfMaterialDesc::AlphaMode::Opaque)
            notOpaque += primitive->triangles;
    }
    return {all, notOpaque};
}

void addGltfMeshes(const std::string& path, GltfStreamWriter& out) {
    const GltfDocument doc = loadGltfDocument(path);
    GltfBytes bytes(doc, UINT64_MAX);  // meshopt views are decoded whole and kept, as for receivers
    const std::vector<GltfMeshNode> placedMeshes = walkGltfScene(doc);
    uint64_t total = 0;
    for (const GltfMeshNode& placed : placedMeshes)
        total += meshTriangles(doc, placed.mesh).first * gltfInstancingOf(doc, placed.node).instances;
    warnIfMaterialsDropped(path, doc);
    std::optional<ProgressReporter> progress;  // inside convert's scope only, as the OBJ passes
    if (const std::optional<bool> quiet = OpeningProgress::active())
        progress.emplace("convert " + std::filesystem::path(path).filename().string(), total, *quiet);
    for (const GltfMeshNode& placed : placedMeshes) {
        const GltfInstancing instancing = gltfInstancingOf(doc, placed.node);
        const GltfVertexLayout layout = commonLayout(doc, placed.mesh);
        const std::string& meshName = doc.meshes[size_t(placed.mesh)].name;
        const std::string name = !meshName.empty() ? meshName : doc.nodes[size_t(placed.node)].name;
        // EXT_mesh_gpu_instancing: a mesh per instance, where the blockers are.
        for (uint64_t i = 0; i < instancing.instances; ++i) {
            const int id = out.addMesh(instancing.instances > 1 ? fmt::format("{} instance {}", name, i) : name, layout);
            const MeshPlacement placement(placed.world * gltfInstanceLocal(doc, bytes, instancing, placed.node, i));
            addGltfMesh(doc, bytes, placed.mesh, placement, layout, id, out);
            if (progress) progress->update(meshTriangles(doc, placed.mesh).first);
        }
    }
}

}  // namespace

void warnIfMaterialsDropped(const std::string& path, const GltfDocument& doc, const char* command) {
    uint64_t notOpaque = 0;
    for (const GltfMeshNode& placed : walkGltfScene(doc))
        notOpaque += meshTriangles(doc, placed.mesh).second * gltfInstancingOf(doc, placed.node).instances;
    if (notOpaque > 0)
        printWarning("{}: {} triangle(s) with cut-out or blended materials (alphaMode MASK or BLEND) are written as plain "
                     "surfaces: {} carries geometry, not materials, so they will block as opaque ones; bake the "
                     "original to keep them",
                     path, notOpaque, command);
}

void addMeshesOfFile(const std::string& path, GltfStreamWriter& out) {
    if (lowercaseExtension(path) == ".obj") return addObjMeshes(path, out);
    addGltfMeshes(path, out);
}

void addTrianglesOf(TriangleSource& source, GltfStreamWriter& out, std::string name, GltfStreamWriter::Indexing indexing) {
    const int id = out.addMesh(std::move(name), {}, indexing);
    source.rewind();
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t n = source.read(chunk))
        for (size_t t = 0; t < n; ++t) {
            std::array<GltfCorner, 3> corners;
            for (size_t k = 0; k < 3; ++k) corners[k].position = chunk[t].v[k];
            out.addTriangle(id, corners);
        }
}

}  // namespace penumbra
