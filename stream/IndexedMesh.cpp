#include "stream/IndexedMesh.h"

#include "stream/Error.h"
#include "stream/GltfBytes.h"
#include "stream/GltfDocument.h"
#include "stream/GltfPrimitive.h"

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string_view>

namespace penumbra {
namespace {

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

/// Applies the load transform (and a node's world matrix) to a finished mesh. Normals use the
/// inverse transpose so that non-uniform scales keep them perpendicular to the surface.
void place(IndexedMesh& mesh, const glm::dmat4& m, const std::string& path) {
    const glm::dmat3 normalMatrix = glm::transpose(glm::inverse(glm::dmat3(m)));
    for (glm::vec3& p : mesh.position) {
        p = glm::vec3(m * glm::dvec4(p, 1.0));
        if (!finite(p)) fail(path, "a transformed vertex position is not finite");
    }
    for (glm::vec3& n : mesh.normal) {
        glm::dvec3 t = normalMatrix * glm::dvec3(n);
        double length = glm::length(t);
        n = length > 0 && std::isfinite(length) ? glm::vec3(t / length) : glm::vec3(0.0f);
    }
    if (glm::determinant(glm::dmat3(m)) < 0.0)
        for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) std::swap(mesh.indices[t + 1], mesh.indices[t + 2]);
}

// ---------------------------------------------------------------------------------------------
// OBJ

struct ObjParser {
    std::string path;
    size_t line = 0;
    std::vector<glm::vec3> v, vn;
    std::vector<glm::vec2> vt;
    std::map<std::array<int64_t, 3>, uint32_t> corners;  // (v, vt, vn), -1 when absent -> vertex
    IndexedMesh mesh;
    bool allHaveUv = true, allHaveNormal = true;

    [[noreturn]] void error(const std::string& what) const { fail(fmt::format("{}:{}", path, line), "{}", what); }

    double number(std::string_view token) const {
        double x = 0;
        auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), x);
        if (ec != std::errc() || end != token.data() + token.size())
            error(fmt::format("cannot parse number \"{}\"", token));
        if (!std::isfinite(x)) error(fmt::format("coordinate \"{}\" is not finite", token));
        return x;
    }

    /// A 1-based (or negative, relative) OBJ index into a list of @p count entries.
    int64_t resolve(std::string_view token, size_t count, const char* what) const {
        int64_t i = 0;
        auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), i);
        if (ec != std::errc() || end != token.data() + token.size())
            error(fmt::format("cannot parse {} index \"{}\"", what, token));
        int64_t resolved = i < 0 ? int64_t(count) + i : i - 1;
        if (i == 0 || resolved < 0 || resolved >= int64_t(count))
            error(fmt::format("face {} index {} out of range ({} {}s)", what, i, count, what));
        return resolved;
    }

    uint32_t corner(std::string_view token) {
        std::array<std::string_view, 3> part{};
        size_t n = 0;
        while (n < 3) {
            size_t slash = token.find('/');
            part[n++] = token.substr(0, slash);
            if (slash == std::string_view::npos) break;
            token.remove_prefix(slash + 1);
        }
        std::array<int64_t, 3> key{resolve(part[0], v.size(), "vertex"), -1, -1};
        if (!part[1].empty()) key[1] = resolve(part[1], vt.size(), "texture coordinate");
        if (!part[2].empty()) key[2] = resolve(part[2], vn.size(), "normal");
        allHaveUv &= key[1] >= 0, allHaveNormal &= key[2] >= 0;
        auto [it, added] = corners.emplace(key, uint32_t(mesh.position.size()));
        if (added) {
            mesh.position.push_back(v[size_t(key[0])]);
            mesh.uv0.push_back(key[1] >= 0 ? vt[size_t(key[1])] : glm::vec2(0.0f));
            mesh.normal.push_back(key[2] >= 0 ? vn[size_t(key[2])] : glm::vec3(0.0f));
        }
        return it->second;
    }

    void statement(std::string_view text) {
        std::vector<std::string_view> tokens;
        for (size_t i = 0; i < text.size();) {
            while (i < text.size() && (text[i] == ' ' || text[i] == '\t' || text[i] == '\r')) ++i;
            size_t start = i;
            while (i < text.size() && text[i] != ' ' && text[i] != '\t' && text[i] != '\r') ++i;
            if (i > start) tokens.push_back(text.substr(start, i - start));
        }
        if (tokens.empty() || tokens[0][0] == '#') return;
        const std::string_view kind = tokens[0];
        if (kind == "v" || kind == "vn") {
            if (tokens.size() < 4) error(fmt::format("\"{}\" needs three coordinates", kind));
            glm::vec3 p(number(tokens[1]), number(tokens[2]), number(tokens[3]));
            (kind == "v" ? v : vn).push_back(p);
        } else if (kind == "vt") {
            if (tokens.size() < 3) error("\"vt\" needs two coordinates");
            vt.emplace_back(number(tokens[1]), 1.0 - number(tokens[2]));  // to glTF's top-left origin
        } else if (kind == "f") {
            if (tokens.size() < 4) error(fmt::format("face has {} corners (needs at least 3)", tokens.size() - 1));
            const uint32_t first = corner(tokens[1]);
            uint32_t previous = corner(tokens[2]);
            for (size_t c = 3; c < tokens.size(); ++c) {
                uint32_t next = corner(tokens[c]);
                mesh.indices.insert(mesh.indices.end(), {first, previous, next});
                previous = next;
            }
        }
    }
};

IndexedMesh loadObjMesh(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, "cannot open: {}", std::strerror(errno));
    ObjParser parser;
    parser.path = path;
    for (std::string text; std::getline(in, text);) {
        ++parser.line;
        parser.statement(text);
    }
    if (in.bad()) fail(path, "read error");
    IndexedMesh mesh = std::move(parser.mesh);
    if (!parser.allHaveUv) mesh.uv0.clear();
    if (!parser.allHaveNormal) mesh.normal.clear();
    mesh.name = std::filesystem::path(path).stem().string();
    return mesh;
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
            IndexedMesh mesh = meshOf(placed.mesh);
            if (mesh.indices.empty()) continue;
            const std::string& meshName = doc_.meshes[size_t(placed.mesh)].name;
            mesh.name = !meshName.empty() ? meshName : doc_.nodes[size_t(placed.node)].name;
            place(mesh, transform * placed.world, doc_.path);
            meshes.push_back(std::move(mesh));
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
        for (glm::vec3& n : mesh.normal) {
            float length = glm::length(n);
            n = length > 0 ? n / length : glm::vec3(0.0f);
        }
        return mesh;
    }

    GltfDocument doc_;
    GltfBytes bytes_;
};

}  // namespace

std::vector<IndexedMesh> loadIndexedMeshes(const std::string& path, const glm::mat4& transform) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".obj") {
        IndexedMesh mesh = loadObjMesh(path);
        for (glm::vec3& n : mesh.normal) {
            float length = glm::length(n);
            n = length > 0 ? n / length : glm::vec3(0.0f);
        }
        place(mesh, glm::dmat4(transform), path);
        std::vector<IndexedMesh> meshes;
        meshes.push_back(std::move(mesh));
        return meshes;
    }
    return GltfMeshReader(path).read(glm::dmat4(transform));
}

}  // namespace penumbra
