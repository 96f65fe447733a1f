#include "stream/IndexedMesh.h"

#include "stream/Error.h"
#include "stream/GltfModel.h"

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

class GltfMeshReader {
public:
    explicit GltfMeshReader(std::string path) : path_(std::move(path)) {
        loadGltfModel(path_, model_);
        accessors_ = checkGltfAccessors(path_, model_);
    }

    std::vector<IndexedMesh> read(const glm::dmat4& transform) {
        std::vector<IndexedMesh> meshes;
        for (const GltfMeshNode& placed : walkGltfScene(path_, model_)) {
            IndexedMesh mesh = meshOf(placed.mesh);
            if (mesh.indices.empty()) continue;
            const tinygltf::Node& node = model_.nodes[size_t(placed.node)];
            mesh.name = !model_.meshes[size_t(placed.mesh)].name.empty() ? model_.meshes[size_t(placed.mesh)].name : node.name;
            place(mesh, transform * placed.world, path_);
            meshes.push_back(std::move(mesh));
        }
        return meshes;
    }

private:
    /// The checked view of accessor @p index of an attribute of @p components floats.
    const GltfAccessorView& attribute(int index, int components, size_t vertices, const std::string& where,
                                      const std::string& name) const {
        const GltfAccessorView& view = accessors_[size_t(index)];
        if (view.components != components)
            fail(where, "{} accessor {} is not VEC{}", name, index, components);
        if (view.sparse) fail(where, "{} accessor {} uses sparse storage, which penumbra does not support", name, index);
        if (view.count != vertices)
            fail(where, "{} accessor {} has {} elements, POSITION has {}", name, index, view.count, vertices);
        if (!view.data && view.count > 0) fail(where, "{} accessor {} has no bufferView", name, index);
        int type = view.componentType;
        if (type == TINYGLTF_COMPONENT_TYPE_INT || type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
            fail(where, "{} accessor {} has componentType {}, which glTF does not allow", name, index, type);
        return view;
    }

    IndexedMesh meshOf(int meshIndex) const {
        IndexedMesh mesh;
        bool allNormals = true, allUv0 = true, allUv1 = true;
        const tinygltf::Mesh& source = model_.meshes[size_t(meshIndex)];
        for (size_t p = 0; p < source.primitives.size(); ++p) {
            const tinygltf::Primitive& primitive = source.primitives[p];
            const std::string where = fmt::format("{}: mesh {} primitive {}", path_, meshIndex, p);
            for (const auto& [name, accessor] : primitive.attributes)
                if (accessor < 0 || size_t(accessor) >= accessors_.size())
                    fail(where, "attribute {} refers to accessor {} (file has {})", name, accessor, accessors_.size());
            if (primitive.indices < -1 || primitive.indices >= int(accessors_.size()))
                fail(where, "indices refer to accessor {} (file has {})", primitive.indices, accessors_.size());
            const int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
            auto found = primitive.attributes.find("POSITION");
            if (found == primitive.attributes.end() ||
                (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN))
                continue;  // not drawn as triangles: no surface to bake on (the blocker reader warns)

            const GltfAccessorView& positions = accessors_[size_t(found->second)];
            if (positions.components != 3) fail(where, "POSITION accessor {} is not VEC3", found->second);
            const size_t vertices = positions.count;
            attribute(found->second, 3, vertices, where, "POSITION");
            const uint32_t base = uint32_t(mesh.position.size());
            if (uint64_t(base) + vertices > UINT32_MAX) fail(where, "more than 2^32 vertices in one mesh");
            for (size_t i = 0; i < vertices; ++i) {
                glm::vec3 x(readGltfElement(positions, i));
                if (!finite(x)) fail(where, "POSITION accessor {} element {} is not finite", found->second, i);
                mesh.position.push_back(x);
            }
            auto optional = [&](const char* name, int components, bool& all, auto&& store) {
                auto it = primitive.attributes.find(name);
                if (it == primitive.attributes.end()) {
                    all = false;
                    return;
                }
                const GltfAccessorView& view = attribute(it->second, components, vertices, where, name);
                for (size_t i = 0; i < vertices; ++i) {
                    glm::vec4 x = readGltfElement(view, i);
                    if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z))
                        fail(where, "{} accessor {} element {} is not finite", name, it->second, i);
                    store(x);
                }
            };
            optional("NORMAL", 3, allNormals, [&](glm::vec4 x) { mesh.normal.emplace_back(x); });
            optional("TEXCOORD_0", 2, allUv0, [&](glm::vec4 x) { mesh.uv0.emplace_back(x); });
            optional("TEXCOORD_1", 2, allUv1, [&](glm::vec4 x) { mesh.uv1.emplace_back(x); });

            // The drawing sequence, validated, then turned into a triangle list.
            std::vector<uint32_t> sequence;
            if (primitive.indices >= 0) {
                const GltfAccessorView& indices = accessors_[size_t(primitive.indices)];
                int type = indices.componentType;
                if (indices.components != 1 || indices.sparse ||
                    (type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                     type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
                    fail(where, "indices accessor {} is not a dense SCALAR of unsigned integers", primitive.indices);
                for (size_t i = 0; i < indices.count; ++i) {
                    uint32_t index = readGltfIndex(indices, i);
                    if (index >= vertices)
                        fail(where, "accessor {} element {} is index {}, but POSITION has {} vertices", primitive.indices,
                             i, index, vertices);
                    sequence.push_back(index);
                }
            } else {
                for (size_t i = 0; i < vertices; ++i) sequence.push_back(uint32_t(i));
            }
            auto add = [&](uint32_t a, uint32_t b, uint32_t c) { mesh.indices.insert(mesh.indices.end(), {base + a, base + b, base + c}); };
            if (mode == TINYGLTF_MODE_TRIANGLES) {
                if (sequence.size() % 3 != 0)
                    fail(where, "TRIANGLES primitive has {} vertices, not a multiple of 3", sequence.size());
                for (size_t t = 0; t < sequence.size(); t += 3) add(sequence[t], sequence[t + 1], sequence[t + 2]);
            } else {
                for (size_t t = 0; t + 2 < sequence.size(); ++t) {
                    if (mode == TINYGLTF_MODE_TRIANGLE_FAN) add(sequence[t + 1], sequence[t + 2], sequence[0]);
                    else if (t % 2 == 0) add(sequence[t], sequence[t + 1], sequence[t + 2]);
                    else add(sequence[t], sequence[t + 2], sequence[t + 1]);  // strips alternate winding
                }
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

    std::string path_;
    tinygltf::Model model_;
    std::vector<GltfAccessorView> accessors_;
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
