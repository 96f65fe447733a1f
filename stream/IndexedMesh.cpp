#include "stream/IndexedMesh.h"
#include "stream/GeometryFile.h"
#include "stream/util/PathText.h"

#include "stream/util/Error.h"
#include "stream/util/Progress.h"
#include "stream/GltfBytes.h"
#include "stream/GltfDocument.h"
#include "stream/GltfInstancing.h"
#include "stream/GltfPrimitive.h"
#include "stream/ObjTokenizer.h"
#include "stream/PolygonTriangulation.h"
#include "stream/Transform.h"

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string_view>

namespace penumbra {
namespace {

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

/// Applies the load transform (and a node's world matrix) to a finished mesh.
void place(IndexedMesh& mesh, const glm::dmat4& m, const std::string& path, bool positions = true) {
    const MeshPlacement placement(m);
    for (glm::vec3& p : mesh.position) {
        if (positions) p = placement.position(p);
        if (!finite(p)) fail(path, "a transformed vertex position is not finite");
    }
    for (glm::vec3& n : mesh.normal) n = placement.normal(n);
    if (placement.mirrors)
        for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) std::swap(mesh.indices[t + 1], mesh.indices[t + 2]);
}

// ---------------------------------------------------------------------------------------------
// OBJ

/// One o/g group of an OBJ: a mesh of its own, its corners deduplicated by (v, vt, vn).
struct ObjPart {
    std::string name;
    std::map<std::array<int64_t, 3>, uint32_t> corners;  // (v, vt, vn), -1 when absent -> vertex
    IndexedMesh mesh;
    bool allHaveUv = true, allHaveNormal = true;
};

/// Reads statements through the tokenizer the blocker stream uses (ObjTokenizer.h), so a file
/// gives both the same coordinates and the same errors.
struct ObjParser {
    std::string path;
    ObjLocation where;  // "path:line" of the current statement
    std::vector<glm::vec3> v, vn;
    std::vector<glm::vec2> vt;
    std::vector<ObjPart> parts;
    ObjGroupIndex groups;
    size_t current = 0;
    std::vector<ObjCorner> face;
    std::vector<glm::vec3> positions;  // face's corners
    std::vector<uint32_t> vertexOf;    // face's corners as the part's vertices
    std::vector<std::array<uint32_t, 3>> triangles;

    ObjParser(const std::string& file) : path(file), where{path, 0} { parts.emplace_back(); }

    uint32_t corner(ObjPart& part, const ObjCorner& c) {
        auto [it, added] = part.corners.emplace(std::array<int64_t, 3>{c.v, c.vt, c.vn}, uint32_t(part.mesh.position.size()));
        if (added) {
            if (part.mesh.position.size() == UINT32_MAX) fail(where.text(), "more than 2^32 vertices in one mesh");
            part.mesh.position.push_back(v[size_t(c.v)]);
            part.mesh.uv0.push_back(c.vt >= 0 ? vt[size_t(c.vt)] : glm::vec2(0.0f));
            part.mesh.normal.push_back(c.vn >= 0 ? vn[size_t(c.vn)] : glm::vec3(0.0f));
        }
        part.allHaveUv &= c.vt >= 0, part.allHaveNormal &= c.vn >= 0;
        return it->second;
    }

    void statement(std::string_view text) {
        ObjTokens tokens(text);
        const std::string_view kind = tokens.next();
        if (kind == "v") {
            v.push_back(parseObjVector(tokens, 3, "vertex", where));
        } else if (kind == "vn") {
            vn.push_back(parseObjVector(tokens, 3, "normal", where));
        } else if (kind == "vt") {
            const glm::vec3 t = parseObjVector(tokens, 2, "texture coordinate", where);
            vt.emplace_back(t.x, float(1.0 - double(t.y)));  // to glTF's top-left origin
        } else if (kind == "o" || kind == "g") {
            const std::string_view name = tokens.rest();
            current = groups.select(name);
            if (current == parts.size()) parts.emplace_back().name = name;
        } else if (kind == "f") {
            const uint64_t counts[3] = {v.size(), vt.size(), vn.size()};
            parseObjFace(tokens, counts, face, where);
            ObjPart& part = parts[current];
            positions.resize(face.size()), vertexOf.resize(face.size());
            for (size_t c = 0; c < face.size(); ++c) positions[c] = v[size_t(face[c].v)], vertexOf[c] = corner(part, face[c]);
            triangulatePolygon(positions, triangles);  // as the blocker stream does (ObjReader.cpp)
            for (const std::array<uint32_t, 3>& t : triangles)
                part.mesh.indices.insert(part.mesh.indices.end(), {vertexOf[t[0]], vertexOf[t[1]], vertexOf[t[2]]});
        }
    }
};

/// The meshes of an OBJ: one per o/g group that has faces (only those named in @p wanted when it
/// is not empty). A file of one group gives one mesh named after the file's stem.
std::vector<IndexedMesh> loadObjMeshes(const std::string& path, const std::vector<std::string>& wanted) {
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, "cannot open: {}", std::strerror(errno));
    ObjParser parser(path);
    // A phase of its own inside an OpeningProgress scope, for a large file (ObjSource's check
    // pass does the same); its bytes are the work.
    std::error_code sizeError;
    const uint64_t fileBytes = std::filesystem::file_size(path, sizeError);
    OpeningPhase progress("load " + std::filesystem::path(path).filename().string(), sizeError ? 0 : fileBytes);
    uint64_t line = 0, bytes = 0;
    for (std::string text; std::getline(in, text);) {
        parser.where.line = ++line;
        parser.statement(objLineText(text, line));
        progress.advance(bytes += text.size() + 1);  // with its '\n'
    }
    if (in.bad()) fail(path, "read error");
    progress.finish();
    for (const std::string& name : wanted)
        if (std::none_of(parser.parts.begin(), parser.parts.end(), [&](const ObjPart& p) { return p.name == name; }))
            fail(path, "has no o/g group named \"{}\" (it has {})", name, parser.parts.size() - 1);
    std::vector<IndexedMesh> meshes;
    size_t withFaces = 0;
    for (const ObjPart& part : parser.parts) withFaces += !part.mesh.indices.empty();
    const std::string stem = std::filesystem::path(path).stem().string();
    for (ObjPart& part : parser.parts) {
        if (part.mesh.indices.empty()) continue;
        if (!wanted.empty() && std::find(wanted.begin(), wanted.end(), part.name) == wanted.end()) continue;
        IndexedMesh mesh = std::move(part.mesh);
        if (!part.allHaveUv) mesh.uv0.clear();
        if (!part.allHaveNormal) mesh.normal.clear();
        mesh.name = withFaces == 1 || part.name.empty() ? stem : part.name;
        meshes.push_back(std::move(mesh));
    }
    return meshes;
}

// ---------------------------------------------------------------------------------------------
// glTF

/// The receiver meshes of a glTF file: one per node that draws a mesh, every triangle primitive
/// of it merged, read through the shared walker (GltfPrimitive.h).
class GltfMeshReader {
public:
    explicit GltfMeshReader(const std::string& path) : doc_(loadGltfDocument(path)), bytes_(doc_, UINT64_MAX) {}

    std::vector<IndexedMesh> read(const glm::dmat4& transform) {
        std::vector<IndexedMesh> meshes;
        for (const GltfMeshNode& placed : walkGltfScene(doc_)) {
            const GltfInstancing instancing = gltfInstancingOf(doc_, placed.node);
            if (instancing.instances == 0) continue;
            IndexedMesh mesh = meshOf(placed.mesh);
            if (mesh.indices.empty()) continue;
            const std::string& meshName = doc_.meshes[size_t(placed.mesh)].name;
            mesh.name = !meshName.empty() ? meshName : doc_.nodes[size_t(placed.node)].name;
            // EXT_mesh_gpu_instancing: a mesh per instance, where the blockers are (it was placed
            // once, at the node, and `convert` to glTF dropped the instances).
            for (uint64_t i = 0; i < instancing.instances; ++i) {
                IndexedMesh copy = i + 1 < instancing.instances ? mesh : std::move(mesh);
                if (instancing.instances > 1) copy.name += fmt::format(" instance {}", i);
                place(copy, transform * placed.world * gltfInstanceLocal(doc_, bytes_, instancing, placed.node, i), doc_.path);
                meshes.push_back(std::move(copy));
            }
        }
        return meshes;
    }

private:
    IndexedMesh meshOf(int meshIndex) {
        IndexedMesh mesh;
        bool allNormals = true, allUv0 = true, allUv1 = true;
        for (size_t p = 0; p < doc_.meshes[size_t(meshIndex)].primitives.size(); ++p) {
            // Points, lines and primitives without POSITION have no surface to bake on (the
            // blocker reader warns about them).
            const auto layout = gltfTrianglePrimitive(doc_, meshIndex, int(p));
            if (!layout) continue;
            GltfPrimitiveReader reader(doc_, bytes_, *layout, true);
            const uint32_t base = uint32_t(mesh.position.size());
            if (uint64_t(base) + layout->vertices > UINT32_MAX) fail(layout->where(doc_), "more than 2^32 vertices in one mesh");
            for (uint64_t i = 0; i < layout->vertices; ++i) mesh.position.push_back(reader.position(i));
            auto optional = [&](const char* name, int components, bool& all, auto&& store) {
                if (!reader.has(name)) {
                    all = false;
                    return;
                }
                for (uint64_t i = 0; i < layout->vertices; ++i) store(reader.attribute(name, components, i));
            };
            optional("NORMAL", 3, allNormals, [&](glm::vec4 x) { mesh.normal.emplace_back(x); });
            optional("TEXCOORD_0", 2, allUv0, [&](glm::vec4 x) { mesh.uv0.emplace_back(x); });
            optional("TEXCOORD_1", 2, allUv1, [&](glm::vec4 x) { mesh.uv1.emplace_back(x); });
            for (uint64_t t = 0; t < layout->triangles; ++t) {
                const std::array<uint32_t, 3> v = reader.triangle(t);
                mesh.indices.insert(mesh.indices.end(), {base + v[0], base + v[1], base + v[2]});
            }
        }
        if (!allNormals) mesh.normal.clear();
        if (!allUv0) mesh.uv0.clear();
        if (!allUv1) mesh.uv1.clear();
        for (glm::vec3& n : mesh.normal) n = unitOrZero(n);
        return mesh;
    }

    GltfDocument doc_;
    GltfBytes bytes_;
};

}  // namespace

glm::vec3 unitOrZero(const glm::vec3& n) {
    const float length = glm::length(n);
    return length > 0 ? n / length : glm::vec3(0.0f);
}

MeshPlacement::MeshPlacement(const glm::dmat4& m)
    : matrix(m), normalMatrix(glm::transpose(glm::inverse(glm::dmat3(m)))), mirrors(glm::determinant(glm::dmat3(m)) < 0.0) {}

glm::vec3 MeshPlacement::position(const glm::vec3& p) const { return glm::vec3(matrix * glm::dvec4(p, 1.0)); }

glm::vec3 MeshPlacement::normal(const glm::vec3& n) const {
    const glm::dvec3 t = normalMatrix * glm::dvec3(n);
    const double length = glm::length(t);
    return length > 0 && std::isfinite(length) ? glm::vec3(t / length) : glm::vec3(0.0f);
}

std::vector<IndexedMesh> loadIndexedMeshes(const std::string& path, const glm::mat4& transform,
                                           const std::vector<std::string>& parts, std::optional<GeometryFormat> format) {
    const bool obj = format ? *format == GeometryFormat::Obj : lowercaseExtension(path) == ".obj";
    if (!obj) {
        if (!parts.empty()) fail(path, "\"parts\" selects o/g groups of OBJ files only");
        return GltfMeshReader(path).read(glm::dmat4(transform));
    }
    std::vector<IndexedMesh> meshes = loadObjMeshes(path, parts);
    for (IndexedMesh& mesh : meshes) {
        for (glm::vec3& n : mesh.normal) n = unitOrZero(n);
        // Positions go through the same float arithmetic as the blocker stream's
        // TransformedSource, so receivers and blockers of one OBJ have the same bits.
        // (An identity is not applied at all, as the blocker stream skips it: -0 stays -0.)
        if (transform != glm::mat4(1.0f))
            for (glm::vec3& p : mesh.position) p = transformPoint(transform, p);
        place(mesh, glm::dmat4(transform), path, false);
    }
    return meshes;
}

}  // namespace penumbra
