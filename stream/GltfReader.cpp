#include "stream/GltfReader.h"

#include "stream/Error.h"
#include "stream/GltfModel.h"
#include "stream/GltfPrecheck.h"

#include <tiny_gltf.h>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>

#include <sys/stat.h>

namespace penumbra {

namespace {

using AccessorView = GltfAccessorView;

/// A triangle-mode primitive whose indices have all been checked against its vertex count.
struct PrimitiveGeometry {
    AccessorView positions;
    std::optional<AccessorView> indices;
    int mode = TINYGLTF_MODE_TRIANGLES;
    uint64_t triangles = 0;
    int mesh = 0, primitive = 0;
    int positionAccessor = 0;
};

/// One placement of a primitive in the scene.
struct Draw {
    size_t geometry = 0;
    glm::dmat4 world{1.0};
    bool identity = true;  // skip the multiply so coordinates stay bit-exact
    bool mirrored = false;
    int node = 0;
};

size_t componentBytes(int componentType) {
    switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
    }
}

int componentsIn(int type) {
    switch (type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4:
    case TINYGLTF_TYPE_MAT2: return 4;
    case TINYGLTF_TYPE_MAT3: return 9;
    case TINYGLTF_TYPE_MAT4: return 16;
    default: return 0;
    }
}

const char* modeName(int mode) {
    switch (mode) {
    case TINYGLTF_MODE_POINTS: return "POINTS";
    case TINYGLTF_MODE_LINE: return "LINES";
    case TINYGLTF_MODE_LINE_LOOP: return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP: return "LINE_STRIP";
    default: return "unknown-mode";
    }
}

/// The glTF image callback: geometry needs no pixels, so images are neither decoded nor checked.
bool ignoreImage(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                 void*) {
    return true;
}

bool isImageFile(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    for (const char* image : {".png", ".jpg", ".jpeg", ".webp", ".ktx", ".ktx2", ".basis", ".dds", ".bmp", ".tga"})
        if (ext == image) return true;
    return false;
}

// File-system callbacks for tinygltf, replacing its defaults for two reasons. Its default
// ExpandFilePath runs URIs through wordexp(3), shell word expansion ($VARS, ~ and, depending on
// how the library was built, $(command) substitution), which has no business touching names
// taken from a downloaded scene; here a URI is only ever a file name. And only regular files are
// read, so a URI naming /dev/zero or a FIFO cannot hang the load. Images are reported as
// unreadable (tinygltf then only warns) so that gigabytes of textures are never read just to
// be ignored.
bool regularFileExists(const std::string& path, void*) {
    std::error_code error;
    return std::filesystem::is_regular_file(path, error);
}

std::string pathAsIs(const std::string& path, void*) { return path; }

std::vector<unsigned char> readWholeFile(const std::string& path);

bool readRegularFile(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
    if (!regularFileExists(path, nullptr) || isImageFile(path)) {
        if (err) *err = "not read (not a regular file, or an image)";
        return false;
    }
    try {
        *out = readWholeFile(path);
    } catch (const InputError& e) {
        if (err) *err = e.what();
        return false;
    }
    return true;
}

bool refuseWrite(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    if (err) *err = "penumbra does not write files while loading glTF";
    return false;
}

/// Reads a regular file whole; anything else (a device, a FIFO) could never end.
std::vector<unsigned char> readWholeFile(const std::string& path) {
    std::FILE* file = std::fopen(path.c_str(), "rb");
    if (!file) fail(path, "cannot open: {}", std::strerror(errno));
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> guard(file, &std::fclose);
    struct stat status {};
    if (::fstat(::fileno(file), &status) != 0) fail(path, "cannot stat: {}", std::strerror(errno));
    if (!S_ISREG(status.st_mode)) fail(path, "not a regular file");
    // tinygltf takes lengths as unsigned int.
    if (uint64_t(status.st_size) > std::numeric_limits<unsigned int>::max())
        fail(path, "file is larger than 4 GiB, which tinygltf cannot address");
    std::vector<unsigned char> bytes;
    bytes.reserve(size_t(status.st_size));
    unsigned char block[1 << 16];
    while (size_t n = std::fread(block, 1, sizeof block, file)) bytes.insert(bytes.end(), block, block + n);
    if (std::ferror(file)) fail(path, "read error: {}", std::strerror(errno));
    return bytes;
}

uint32_t readU32(const unsigned char* p) {
    uint32_t v;
    std::memcpy(&v, p, 4);
    return v;
}

/// @brief Checks the GLB container (header and the JSON and BIN chunk headers) so that
/// tinygltf, which trusts some of those lengths, only ever sees a consistent file.
/// @return the byte length the GLB header declares.
size_t checkGlbContainer(const std::string& path, const std::vector<unsigned char>& bytes) {
    if (bytes.size() < 20) fail(path, "truncated GLB header (expected at least 20 bytes, found {})", bytes.size());
    if (uint32_t version = readU32(&bytes[4]); version != 2) fail(path, "unsupported GLB version {}", version);
    uint64_t length = readU32(&bytes[8]);
    if (length > bytes.size()) fail(path, "truncated (GLB header declares {} bytes, file has {})", length, bytes.size());
    uint64_t jsonLength = readU32(&bytes[12]);
    if (readU32(&bytes[16]) != 0x4E4F534Au) fail(path, "first GLB chunk is not JSON");
    uint64_t binStart = 20 + jsonLength;
    if (binStart > length) fail(path, "GLB JSON chunk ({} bytes) runs past the end of the file", jsonLength);
    if (binStart < length) {
        if (binStart + 8 > length) fail(path, "truncated GLB chunk header after the JSON chunk");
        uint64_t binLength = readU32(&bytes[binStart]);
        if (binStart + 8 + binLength > length)
            fail(path, "GLB BIN chunk ({} bytes) runs past the end of the file", binLength);
        if (readU32(&bytes[binStart + 4]) != 0x004E4942u) fail(path, "second GLB chunk is not BIN");
    }
    return static_cast<size_t>(length);
}

/// Loads the model with tinygltf, turning every failure into an InputError.
void loadModel(const std::string& path, tinygltf::Model& model) {
    std::vector<unsigned char> bytes = readWholeFile(path);
    checkGltfBeforeParsing(path, bytes);
    if (bytes.size() > std::numeric_limits<unsigned int>::max())  // grew while being read
        fail(path, "file is larger than 4 GiB, which tinygltf cannot address");
    std::string baseDir = std::filesystem::path(path).parent_path().string();
    if (baseDir.empty()) baseDir = ".";

    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(&ignoreImage, nullptr);
    loader.SetFsCallbacks({&regularFileExists, &pathAsIs, &readRegularFile, &refuseWrite, nullptr});
    std::string error, warning;
    bool loaded = false;
    try {
        if (bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0) {
            size_t length = checkGlbContainer(path, bytes);
            loaded = loader.LoadBinaryFromMemory(&model, &error, &warning, bytes.data(),
                                                 static_cast<unsigned int>(length), baseDir);
        } else {
            loaded = loader.LoadASCIIFromString(&model, &error, &warning, reinterpret_cast<const char*>(bytes.data()),
                                                static_cast<unsigned int>(bytes.size()), baseDir);
        }
    } catch (const std::exception& e) {  // tinygltf's JSON layer may throw on hostile input
        fail(path, "{}", e.what());
    }
    if (!loaded) {
        std::string firstLine = error.substr(0, error.find('\n'));
        fail(path, "{}", firstLine.empty() ? std::string("tinygltf could not load the file") : firstLine);
    }
}

void checkBufferViews(const std::string& path, const tinygltf::Model& model) {
    for (size_t i = 0; i < model.bufferViews.size(); ++i) {
        const tinygltf::BufferView& view = model.bufferViews[i];
        if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size())
            fail(path, "bufferView {} refers to buffer {} (file has {})", i, view.buffer, model.buffers.size());
        size_t bufferBytes = model.buffers[size_t(view.buffer)].data.size();
        uint64_t end = 0;
        if (__builtin_add_overflow(uint64_t(view.byteOffset), uint64_t(view.byteLength), &end) || end > bufferBytes)
            fail(path, "bufferView {} (bytes {}..+{}) lies outside buffer {} ({} bytes)", i, view.byteOffset,
                 view.byteLength, view.buffer, bufferBytes);
    }
}

std::vector<AccessorView> checkAccessorsOf(const std::string& path, const tinygltf::Model& model) {
    checkBufferViews(path, model);
    std::vector<AccessorView> accessors(model.accessors.size());
    for (size_t i = 0; i < model.accessors.size(); ++i) {
        const tinygltf::Accessor& a = model.accessors[i];
        AccessorView& v = accessors[i];
        size_t componentSize = componentBytes(a.componentType);
        v.components = componentsIn(a.type);
        if (componentSize == 0) fail(path, "accessor {} has invalid componentType {}", i, a.componentType);
        if (v.components == 0) fail(path, "accessor {} has invalid type {}", i, a.type);
        v.componentType = a.componentType;
        v.normalized = a.normalized;
        v.count = a.count;
        v.sparse = a.sparse.isSparse;
        size_t elementSize = componentSize * size_t(v.components);
        if (a.bufferView < 0) {
            // No bufferView: the spec defines the elements as zeros (before sparse substitution).
            if (a.bufferView != -1) fail(path, "accessor {} refers to bufferView {}", i, a.bufferView);
            continue;
        }
        if (size_t(a.bufferView) >= model.bufferViews.size())
            fail(path, "accessor {} refers to bufferView {} (file has {})", i, a.bufferView,
                 model.bufferViews.size());
        const tinygltf::BufferView& view = model.bufferViews[size_t(a.bufferView)];
        v.stride = view.byteStride == 0 ? elementSize : view.byteStride;
        if (v.stride < elementSize)
            fail(path, "accessor {}: bufferView {} byteStride {} is smaller than the {}-byte element", i,
                 a.bufferView, view.byteStride, elementSize);
        if (a.count > 0) {
            // byteOffset + stride * (count - 1) + elementSize, with every step overflow-checked:
            // the operands come straight from the JSON.
            uint64_t needed = 0;
            bool overflow = __builtin_mul_overflow(uint64_t(v.stride), uint64_t(a.count - 1), &needed) ||
                            __builtin_add_overflow(needed, uint64_t(a.byteOffset), &needed) ||
                            __builtin_add_overflow(needed, uint64_t(elementSize), &needed);
            if (overflow || needed > view.byteLength) {
                if (overflow)
                    fail(path, "accessor {} reads past the end of bufferView {} (needs more than 2^64 bytes, has {})",
                         i, a.bufferView, view.byteLength);
                fail(path, "accessor {} reads past the end of bufferView {} (needs {} bytes, has {})", i,
                     a.bufferView, needed, view.byteLength);
            }
        }
        v.data = model.buffers[size_t(view.buffer)].data.data() + view.byteOffset + a.byteOffset;
    }
    return accessors;
}

class GltfSource final : public TriangleSource {
public:
    explicit GltfSource(std::string path);

    size_t read(std::span<Triangle> out) override;
    void rewind() override { nextDraw_ = 0, nextTriangle_ = 0; }
    std::string name() const override { return path_; }
    std::optional<uint64_t> sizeHint() const override { return triangleCount_; }

private:
    void checkMeshes();
    void checkIndices(const PrimitiveGeometry& g, int indexAccessor) const;
    void placeScene();
    Triangle triangle(const Draw& draw, uint64_t t) const;

    std::string path_;
    tinygltf::Model model_;
    std::vector<AccessorView> accessors_;
    std::vector<PrimitiveGeometry> geometries_;
    std::vector<std::vector<size_t>> meshGeometries_;  // mesh -> its triangle primitives
    std::vector<Draw> draws_;
    uint64_t triangleCount_ = 0;
    size_t nextDraw_ = 0;
    uint64_t nextTriangle_ = 0;
};

GltfSource::GltfSource(std::string path) : path_(std::move(path)) {
    loadModel(path_, model_);
    accessors_ = checkAccessorsOf(path_, model_);
    checkMeshes();
    placeScene();
}

void GltfSource::checkMeshes() {
    std::map<int, size_t> skippedModes;  // mode -> primitives skipped, for one warning per mode
    size_t withoutPositions = 0;
    meshGeometries_.resize(model_.meshes.size());
    for (size_t m = 0; m < model_.meshes.size(); ++m) {
        for (size_t p = 0; p < model_.meshes[m].primitives.size(); ++p) {
            const tinygltf::Primitive& primitive = model_.meshes[m].primitives[p];
            auto where = [&] { return fmt::format("{}: mesh {} primitive {}", path_, m, p); };
            for (const auto& [attribute, accessor] : primitive.attributes)
                if (accessor < 0 || size_t(accessor) >= accessors_.size())
                    fail(where(), "attribute {} refers to accessor {} (file has {})", attribute, accessor,
                         accessors_.size());
            if (primitive.indices < -1 || primitive.indices >= int(accessors_.size()))
                fail(where(), "indices refer to accessor {} (file has {})", primitive.indices, accessors_.size());

            int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
            if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
                mode != TINYGLTF_MODE_TRIANGLE_FAN) {
                if (mode > TINYGLTF_MODE_TRIANGLE_FAN) fail(where(), "invalid mode {}", mode);
                ++skippedModes[mode];
                continue;
            }
            auto position = primitive.attributes.find("POSITION");
            if (position == primitive.attributes.end()) {
                ++withoutPositions;  // the spec says such primitives are not rendered
                continue;
            }

            PrimitiveGeometry g;
            g.mesh = int(m), g.primitive = int(p), g.mode = mode;
            g.positionAccessor = position->second;
            g.positions = accessors_[size_t(position->second)];
            int pc = g.positions.componentType;
            if (g.positions.components != 3)
                fail(where(), "POSITION accessor {} is not VEC3", position->second);
            if (pc == TINYGLTF_COMPONENT_TYPE_INT || pc == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
                fail(where(), "POSITION accessor {} has componentType {}, which glTF does not allow", position->second,
                     pc);
            if (g.positions.sparse)
                fail(where(), "POSITION accessor {} uses sparse storage, which penumbra does not support",
                     position->second);
            // Without a bufferView every position is zero: only degenerate triangles, and a count
            // bounded by nothing but the JSON (a tiny file could ask for 2^60 of them).
            if (!g.positions.data && g.positions.count > 0)
                fail(where(), "POSITION accessor {} has no bufferView", position->second);

            uint64_t sequence = g.positions.count;  // vertices in drawing order
            if (primitive.indices >= 0) {
                const AccessorView& indices = accessors_[size_t(primitive.indices)];
                int ic = indices.componentType;
                if (indices.components != 1) fail(where(), "indices accessor {} is not SCALAR", primitive.indices);
                if (ic != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ic != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                    ic != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
                    fail(where(), "indices accessor {} has componentType {} (must be an unsigned integer type)",
                         primitive.indices, ic);
                if (indices.sparse)
                    fail(where(), "indices accessor {} uses sparse storage, which penumbra does not support",
                         primitive.indices);
                g.indices = indices;
                sequence = indices.count;
                checkIndices(g, primitive.indices);
            }
            if (mode == TINYGLTF_MODE_TRIANGLES) {
                if (sequence % 3 != 0) fail(where(), "TRIANGLES primitive has {} vertices, not a multiple of 3", sequence);
                g.triangles = sequence / 3;
            } else {
                g.triangles = sequence >= 3 ? sequence - 2 : 0;
            }
            meshGeometries_[m].push_back(geometries_.size());
            geometries_.push_back(std::move(g));
        }
    }
    for (const auto& [mode, count] : skippedModes)
        fmt::print(stderr, "penumbra: warning: {}: skipped {} {} primitive{} (only triangles cast shadows)\n", path_,
                   count, modeName(mode), count == 1 ? "" : "s");
    if (withoutPositions > 0)
        fmt::print(stderr, "penumbra: warning: {}: skipped {} primitive{} without POSITION\n", path_,
                   withoutPositions, withoutPositions == 1 ? "" : "s");
}

uint32_t readIndex(const AccessorView& v, uint64_t i) {
    if (!v.data) return 0;
    const unsigned char* p = v.data + i * v.stride;
    switch (v.componentType) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return *p;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t x;
        std::memcpy(&x, p, 2);
        return x;
    }
    default: {
        uint32_t x;
        std::memcpy(&x, p, 4);
        return x;
    }
    }
}

void GltfSource::checkIndices(const PrimitiveGeometry& g, int indexAccessor) const {
    for (uint64_t i = 0; i < g.indices->count; ++i) {
        uint32_t index = readIndex(*g.indices, i);
        if (index >= g.positions.count)
            fail(path_, "mesh {} primitive {}: accessor {} element {} is index {}, but POSITION accessor {} has {} vertices",
                 g.mesh, g.primitive, indexAccessor, i, index, g.positionAccessor, g.positions.count);
    }
}

/// Reads one element (up to 4 components), decoding KHR_mesh_quantization integer and
/// normalized forms.
glm::vec4 readElement(const AccessorView& v, uint64_t i) {
    glm::vec4 p(0.0f);
    if (!v.data) return p;
    const unsigned char* at = v.data + i * v.stride;
    for (int c = 0; c < std::min(v.components, 4); ++c) {
        switch (v.componentType) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: std::memcpy(&p[c], at + 4 * c, 4); break;
        case TINYGLTF_COMPONENT_TYPE_BYTE: {
            auto x = static_cast<int8_t>(at[c]);
            p[c] = v.normalized ? std::max(float(x) / 127.0f, -1.0f) : float(x);
            break;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: p[c] = v.normalized ? float(at[c]) / 255.0f : float(at[c]); break;
        case TINYGLTF_COMPONENT_TYPE_SHORT: {
            int16_t x;
            std::memcpy(&x, at + 2 * c, 2);
            p[c] = v.normalized ? std::max(float(x) / 32767.0f, -1.0f) : float(x);
            break;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            uint16_t x;
            std::memcpy(&x, at + 2 * c, 2);
            p[c] = v.normalized ? float(x) / 65535.0f : float(x);
            break;
        }
        }
    }
    return p;
}

glm::vec3 readPosition(const AccessorView& v, uint64_t i) { return glm::vec3(readElement(v, i)); }

glm::dmat4 localMatrix(const std::string& path, const tinygltf::Model& model, int index) {
    const tinygltf::Node& node = model.nodes[size_t(index)];
    auto check = [&](const std::vector<double>& values, size_t expected, const char* what) {
        if (!values.empty() && values.size() != expected)
            fail(path, "node {} {} has {} values (needs {})", index, what, values.size(), expected);
        for (double x : values)
            if (!std::isfinite(x)) fail(path, "node {} {} is not finite", index, what);
        return !values.empty();
    };
    if (check(node.matrix, 16, "matrix")) return glm::make_mat4(node.matrix.data());  // both column-major
    glm::dmat4 m(1.0);
    if (check(node.translation, 3, "translation"))
        m = glm::translate(m, glm::dvec3(node.translation[0], node.translation[1], node.translation[2]));
    if (check(node.rotation, 4, "rotation")) {
        const auto& q = node.rotation;  // glTF order x, y, z, w
        m *= glm::mat4_cast(glm::normalize(glm::dquat(q[3], q[0], q[1], q[2])));
    }
    if (check(node.scale, 3, "scale")) m = glm::scale(m, glm::dvec3(node.scale[0], node.scale[1], node.scale[2]));
    return m;
}

std::vector<GltfMeshNode> walkScene(const std::string& path, const tinygltf::Model& model) {
    const size_t nodeCount = model.nodes.size();
    for (size_t n = 0; n < nodeCount; ++n) {
        const tinygltf::Node& node = model.nodes[n];
        if (node.mesh < -1 || node.mesh >= int(model.meshes.size()))
            fail(path, "node {} refers to mesh {} (file has {})", n, node.mesh, model.meshes.size());
        for (int child : node.children)
            if (child < 0 || size_t(child) >= nodeCount)
                fail(path, "node {} has child {} (file has {} nodes)", n, child, nodeCount);
    }

    std::vector<int> roots;
    int scene = model.defaultScene;
    if (scene >= 0 && size_t(scene) >= model.scenes.size())
        fail(path, "default scene {} does not exist (file has {})", scene, model.scenes.size());
    if (scene < 0 && !model.scenes.empty()) scene = 0;
    if (scene >= 0) {
        roots = model.scenes[size_t(scene)].nodes;
        for (int root : roots)
            if (root < 0 || size_t(root) >= nodeCount)
                fail(path, "scene {} refers to node {} (file has {})", scene, root, nodeCount);
    } else {
        // No scenes: every node that is nobody's child is a root.
        std::vector<bool> isChild(nodeCount, false);
        for (const auto& node : model.nodes)
            for (int child : node.children) isChild[size_t(child)] = true;
        for (size_t n = 0; n < nodeCount; ++n)
            if (!isChild[n]) roots.push_back(int(n));
    }

    // Iterative depth-first walk. glTF requires the hierarchy to be a forest; reaching a node
    // twice means a cycle (infinite recursion) or a shared child (exponential instancing), both
    // rejected.
    std::vector<GltfMeshNode> placed;
    std::vector<bool> reached(nodeCount, false);
    std::vector<std::pair<int, glm::dmat4>> stack;
    for (auto r = roots.rbegin(); r != roots.rend(); ++r) stack.emplace_back(*r, glm::dmat4(1.0));
    while (!stack.empty()) {
        auto [n, parent] = stack.back();
        stack.pop_back();
        if (reached[size_t(n)]) fail(path, "node {} is reached twice (the node hierarchy must be a tree)", n);
        reached[size_t(n)] = true;
        glm::dmat4 world = parent * localMatrix(path, model, n);
        const tinygltf::Node& node = model.nodes[size_t(n)];
        if (node.mesh >= 0) placed.push_back({n, node.mesh, world});
        for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.emplace_back(*c, world);
    }
    return placed;
}

void GltfSource::placeScene() {
    for (const GltfMeshNode& placed : walkScene(path_, model_)) {
        for (size_t g : meshGeometries_[size_t(placed.mesh)]) {
            Draw draw;
            draw.geometry = g, draw.world = placed.world, draw.node = placed.node;
            draw.identity = placed.world == glm::dmat4(1.0);
            draw.mirrored = glm::determinant(glm::dmat3(placed.world)) < 0.0;
            if (geometries_[g].triangles == 0) continue;
            triangleCount_ += geometries_[g].triangles;
            draws_.push_back(draw);
        }
    }
}

Triangle GltfSource::triangle(const Draw& draw, uint64_t t) const {
    const PrimitiveGeometry& g = geometries_[draw.geometry];
    uint64_t corner[3];
    switch (g.mode) {
    case TINYGLTF_MODE_TRIANGLE_STRIP:  // every other triangle is flipped to keep the winding
        corner[0] = t, corner[1] = t + 1 + t % 2, corner[2] = t + 2 - t % 2;
        break;
    case TINYGLTF_MODE_TRIANGLE_FAN: corner[0] = t + 1, corner[1] = t + 2, corner[2] = 0; break;
    default: corner[0] = 3 * t, corner[1] = 3 * t + 1, corner[2] = 3 * t + 2; break;
    }
    Triangle tri;
    for (int i = 0; i < 3; ++i) {
        uint64_t vertex = g.indices ? readIndex(*g.indices, corner[i]) : corner[i];
        glm::vec3 p = readPosition(g.positions, vertex);
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            fail(path_, "mesh {} primitive {}: POSITION accessor {} element {} is not finite", g.mesh, g.primitive,
                 g.positionAccessor, vertex);
        tri.v[size_t(i)] = draw.identity ? p : glm::vec3(draw.world * glm::dvec4(p, 1.0));
    }
    if (draw.mirrored) std::swap(tri.v[1], tri.v[2]);
    if (!isFinite(tri))
        fail(path_, "node {} transforms mesh {} primitive {} to a non-finite position", draw.node, g.mesh,
             g.primitive);
    return tri;
}

size_t GltfSource::read(std::span<Triangle> out) {
    size_t written = 0;
    while (written < out.size() && nextDraw_ < draws_.size()) {
        const Draw& draw = draws_[nextDraw_];
        uint64_t total = geometries_[draw.geometry].triangles;
        while (written < out.size() && nextTriangle_ < total) out[written++] = triangle(draw, nextTriangle_++);
        if (nextTriangle_ == total) ++nextDraw_, nextTriangle_ = 0;
    }
    return written;
}

}  // namespace

TriangleSourcePtr openGltf(const std::string& path) { return std::make_unique<GltfSource>(path); }

void loadGltfModel(const std::string& path, tinygltf::Model& model) { loadModel(path, model); }

std::vector<GltfAccessorView> checkGltfAccessors(const std::string& path, const tinygltf::Model& model) {
    return checkAccessorsOf(path, model);
}

uint32_t readGltfIndex(const GltfAccessorView& view, uint64_t i) { return readIndex(view, i); }

glm::vec4 readGltfElement(const GltfAccessorView& view, uint64_t i) { return readElement(view, i); }

std::vector<GltfMeshNode> walkGltfScene(const std::string& path, const tinygltf::Model& model) {
    return walkScene(path, model);
}

}  // namespace penumbra
