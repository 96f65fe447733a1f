#include "stream/GltfStreamWriter.h"

#include "stream/util/Memory.h"
#include "stream/GlbBuilder.h"
#include "stream/GltfBuffers.h"
#include "stream/GltfDocument.h"
#include "stream/util/AnonymousFile.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"

#include <glm/common.hpp>
#include <nlohmann/json.hpp>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>

#include <unistd.h>

namespace penumbra {

namespace {

/// A mesh name as JSON: an OBJ's group names are bytes, often Latin-1 from old exporters, which
/// JSON cannot hold; broken UTF-8 becomes U+FFFD instead of failing the write.
std::string nameJson(const std::string& name) {
    return nlohmann::json(name).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}


constexpr uint32_t kEmptySlot = std::numeric_limits<uint32_t>::max();
constexpr int kFloat = 5126, kUnsignedInt = 5125;         // glTF componentType
constexpr int kArrayBuffer = 34962, kElementBuffer = 34963;  // bufferView target

uint64_t mix(uint64_t x) {  // splitmix64's finalizer
    x ^= x >> 30, x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27, x *= 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

}  // namespace

/// The unnamed file the primitives' bytes wait in until commit().
struct GltfStreamWriter::Scratch {
    std::string dir = scratchDirectory();
    int fd = createAnonymousFile(dir);
    uint64_t size = 0;

    Scratch() {
        if (fd < 0) fail(dir, "cannot create a scratch file for the glTF being written: {}", std::strerror(errno));
    }
    ~Scratch() { ::close(fd); }

    uint64_t append(const void* data, size_t bytes) {
        const uint64_t at = size;
        const char* p = static_cast<const char*>(data);
        for (size_t done = 0; done < bytes;) {
            const ssize_t n = ::pwrite(fd, p + done, bytes - done, off_t(at + done));
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) fail(dir, "cannot write the scratch file of the glTF being written: {}", std::strerror(n < 0 ? errno : EIO));
            done += size_t(n);
        }
        size += bytes;
        return at;
    }
    /// Calls @p consume with the file's bytes in order, a block at a time.
    template <typename Consume>
    void read(Consume&& consume) const {
        std::vector<char> block(1u << 20);
        for (uint64_t at = 0; at < size;) {
            const ssize_t n = ::pread(fd, block.data(), size_t(std::min<uint64_t>(block.size(), size - at)), off_t(at));
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) fail(dir, "cannot read the scratch file of the glTF being written: {}", std::strerror(n < 0 ? errno : EIO));
            consume(block.data(), size_t(n));
            at += uint64_t(n);
        }
    }
};

/// A mesh: the primitives already in the scratch file, and the open one.
struct GltfStreamWriter::Mesh {
    struct Primitive {
        uint64_t offset = 0;  ///< of POSITION; NORMAL, TEXCOORD_0/1 and indices follow in that order
        uint64_t vertices = 0, indices = 0;
        glm::vec3 lo{0.0f}, hi{0.0f};
    };
    std::string name;
    GltfVertexLayout layout;
    Indexing indexing;
    std::vector<Primitive> written;
    std::vector<glm::vec3> position, normal;
    std::vector<glm::vec2> uv0, uv1;
    std::vector<uint32_t> indices;
    std::vector<uint32_t> slots;  ///< welding table: vertex ids, kEmptySlot when free

    uint64_t vertexBytes() const { return 12 + (layout.normal ? 12 : 0) + (layout.uv0 ? 8 : 0) + (layout.uv1 ? 8 : 0); }
    uint64_t openBytes() const { return position.size() * vertexBytes() + (indices.size() + slots.size()) * 4; }
    bool open() const { return !position.empty(); }

    /// The corner's bits as welding compares them, in @p words; @return how many.
    size_t key(const GltfCorner& c, uint32_t (&words)[10]) const {
        size_t n = 0;
        auto put = [&](const float* f, size_t count) {
            std::memcpy(words + n, f, count * 4);
            n += count;
        };
        put(&c.position.x, 3);
        if (layout.normal) put(&c.normal.x, 3);
        if (layout.uv0) put(&c.uv0.x, 2);
        if (layout.uv1) put(&c.uv1.x, 2);
        return n;
    }
    GltfCorner corner(uint32_t v) const {
        GltfCorner c;
        c.position = position[v];
        if (layout.normal) c.normal = normal[v];
        if (layout.uv0) c.uv0 = uv0[v];
        if (layout.uv1) c.uv1 = uv1[v];
        return c;
    }
    uint32_t push(const GltfCorner& c) {
        position.push_back(c.position);
        if (layout.normal) normal.push_back(c.normal);
        if (layout.uv0) uv0.push_back(c.uv0);
        if (layout.uv1) uv1.push_back(c.uv1);
        return uint32_t(position.size() - 1);
    }
    static uint64_t hashOf(const uint32_t* words, size_t n) {
        uint64_t h = 0x9e3779b97f4a7c15ull;
        for (size_t i = 0; i < n; ++i) h = mix(h ^ words[i]);
        return h;
    }
    /// The vertex of corner @p c, added when no vertex has its bits.
    uint32_t weld(const GltfCorner& c) {
        if ((position.size() + 1) * 2 > slots.size()) rehash(std::max<size_t>(64, slots.size() * 2));
        uint32_t words[10], other[10];
        const size_t n = key(c, words);
        const size_t mask = slots.size() - 1;
        for (size_t s = size_t(hashOf(words, n)) & mask;; s = (s + 1) & mask) {
            if (slots[s] == kEmptySlot) return slots[s] = push(c);
            key(corner(slots[s]), other);
            if (std::memcmp(words, other, n * 4) == 0) return slots[s];
        }
    }
    void rehash(size_t size) {
        slots.assign(size, kEmptySlot);
        uint32_t words[10];
        for (uint32_t v = 0; v < position.size(); ++v) {
            const size_t n = key(corner(v), words);
            size_t s = size_t(hashOf(words, n)) & (size - 1);
            while (slots[s] != kEmptySlot) s = (s + 1) & (size - 1);
            slots[s] = v;
        }
    }
};

GltfStreamWriter::GltfStreamWriter(std::string path, bool binary, uint64_t openBytes)
    : path_(std::move(path)), binary_(binary), openLimit_(openBytes) {
    // Whether the buffer goes to STEM.bin is known only at the end; a folder of that name is found now.
    std::error_code ec;
    const std::filesystem::path bin = externalBufferPath(path_, 0, 1);
    if (!binary_ && std::filesystem::exists(bin, ec) && !std::filesystem::is_regular_file(bin, ec)) checkOutputPath(bin.string());
}

GltfStreamWriter::~GltfStreamWriter() = default;

int GltfStreamWriter::addMesh(std::string name, GltfVertexLayout layout, Indexing indexing) {
    auto mesh = std::make_unique<Mesh>();
    mesh->name = std::move(name);
    mesh->layout = layout;
    mesh->indexing = indexing;
    if (indexing == Indexing::None) mesh->layout = {};  // a triangle soup has positions only
    meshes_.push_back(std::move(mesh));
    return int(meshes_.size() - 1);
}

void GltfStreamWriter::addTriangle(int meshId, const std::array<GltfCorner, 3>& corners) {
    Mesh& mesh = *meshes_.at(size_t(meshId));
    const uint64_t before = mesh.openBytes();
    for (const GltfCorner& c : corners) {
        if (mesh.indexing == Indexing::None)
            mesh.push(c);
        else
            mesh.indices.push_back(mesh.weld(c));
    }
    openBytes_ += mesh.openBytes() - before;
    const uint64_t total = openBytes_ + (scratch_ ? scratch_->size : 0);
    if (total > kMaxBufferBytes)
        fail(path_, "more than {} bytes of vertices and indices do not fit in one glTF buffer (at most 4 GiB)", kMaxBufferBytes);
    if (openBytes_ > openLimit_) flushAll(&mesh);
}

void GltfStreamWriter::flush(Mesh& mesh, bool keepStorage) {
    if (!mesh.open()) return;
    if (!scratch_) scratch_ = std::make_unique<Scratch>();
    Mesh::Primitive p;
    p.vertices = mesh.position.size();
    p.indices = mesh.indices.size();
    p.lo = p.hi = mesh.position[0];
    for (const glm::vec3& v : mesh.position) p.lo = glm::min(p.lo, v), p.hi = glm::max(p.hi, v);
    p.offset = scratch_->append(mesh.position.data(), mesh.position.size() * sizeof(glm::vec3));
    scratch_->append(mesh.normal.data(), mesh.normal.size() * sizeof(glm::vec3));
    scratch_->append(mesh.uv0.data(), mesh.uv0.size() * sizeof(glm::vec2));
    scratch_->append(mesh.uv1.data(), mesh.uv1.size() * sizeof(glm::vec2));
    scratch_->append(mesh.indices.data(), mesh.indices.size() * sizeof(uint32_t));
    mesh.written.push_back(p);
    openBytes_ -= mesh.openBytes();
    // The mesh being added to keeps its arrays' storage for the next primitive: a large mesh
    // refilling them from nothing left the heap fragmented, and a 175 MB OBJ then ran out of a
    // 160 MiB address space. Every other mesh gives it back: it may never grow again (an OBJ's
    // groups kept 3 MB each to the end).
    auto empty = [keepStorage](auto& v) { keepStorage ? v.clear() : releaseStorage(v); };
    empty(mesh.position), empty(mesh.normal), empty(mesh.indices), empty(mesh.uv0), empty(mesh.uv1), empty(mesh.slots);
}

void GltfStreamWriter::flushAll(const Mesh* current) {
    for (auto& mesh : meshes_) flush(*mesh, mesh.get() == current);
}

size_t GltfStreamWriter::primitiveCount() const {
    size_t n = 0;
    for (const auto& mesh : meshes_) n += mesh->written.size();
    return n;
}

void GltfStreamWriter::writeDocument(const std::string& uri, const std::function<void(std::string_view)>& sink) const {
    // Written as text straight to @p sink, not built as a JSON tree: a tree costs kilobytes a mesh
    // (1.5 GB for an OBJ of 300,000 groups), and even the text is about 450 bytes a mesh. Arrays
    // are written in passes over the primitives, each numbering accessors and views the same way.
    fmt::memory_buffer out;
    auto put = [&]<typename... A>(fmt::format_string<A...> format, A&&... args) {
        fmt::format_to(std::back_inserter(out), format, std::forward<A>(args)...);
        if (out.size() >= (1u << 16)) sink(std::string_view(out.data(), out.size())), out.clear();
    };
    const char* sep = binary_ ? "" : "\n  ";  // a .gltf gets a line per element
    put(R"({{"asset":{{"version":"2.0","generator":"penumbra"}})");
    auto forEachPrimitive = [&](auto&& visit) {
        for (const auto& mesh : meshes_)
            for (const Mesh::Primitive& p : mesh->written) visit(*mesh, p);
    };
    bool any = false;
    forEachPrimitive([&](const Mesh&, const Mesh::Primitive&) { any = true; });
    if (!any) {  // an empty model has no buffer and no scene (an empty scene would be invalid)
        put("}}\n");
        return sink(std::string_view(out.data(), out.size()));
    }
    put(R"(,"buffers":[{{"byteLength":{})", scratch_->size);
    if (!uri.empty()) put(R"(,"uri":{})", nlohmann::json(uri).dump());
    put("}}]");
    // Each primitive's accessors in order: POSITION, NORMAL, TEXCOORD_0, TEXCOORD_1, indices.
    auto accessorsOf = [](const Mesh& mesh, const Mesh::Primitive& p, auto&& visit) {
        uint64_t at = p.offset;
        auto one = [&](uint64_t count, int components, int target) {
            visit(at, count, components, target);
            at += count * uint64_t(components) * 4;
        };
        one(p.vertices, 3, kArrayBuffer);
        if (mesh.layout.normal) one(p.vertices, 3, kArrayBuffer);
        if (mesh.layout.uv0) one(p.vertices, 2, kArrayBuffer);
        if (mesh.layout.uv1) one(p.vertices, 2, kArrayBuffer);
        if (p.indices > 0) one(p.indices, 1, kElementBuffer);
    };
    const char* comma = "";
    put(R"(,"bufferViews":[)");
    forEachPrimitive([&](const Mesh& mesh, const Mesh::Primitive& p) {
        accessorsOf(mesh, p, [&](uint64_t at, uint64_t count, int components, int target) {
            put(R"({}{}{{"buffer":0,"byteOffset":{},"byteLength":{},"target":{}}})", comma, sep, at, count * uint64_t(components) * 4, target);
            comma = ",";
        });
    });
    put(R"(],"accessors":[)");
    static const char* const kTypes[] = {"", "SCALAR", "VEC2", "VEC3"};
    uint64_t view = 0;
    comma = "";
    forEachPrimitive([&](const Mesh& mesh, const Mesh::Primitive& p) {
        accessorsOf(mesh, p, [&](uint64_t at, uint64_t count, int components, int target) {
            put(R"({}{}{{"bufferView":{},"componentType":{},"count":{},"type":"{}")", comma, sep, view, target == kElementBuffer ? kUnsignedInt : kFloat,
                count, kTypes[components]);
            if (at == p.offset)  // POSITION: min and max are required; floats print as the shortest text that reads back exactly
                put(R"(,"min":[{},{},{}],"max":[{},{},{}])", p.lo.x, p.lo.y, p.lo.z, p.hi.x, p.hi.y, p.hi.z);
            put("}}");
            ++view, comma = ",";
        });
    });
    put(R"(],"meshes":[)");
    uint64_t accessor = 0, meshes = 0;
    comma = "";
    for (const auto& mesh : meshes_) {
        if (mesh->written.empty()) continue;
        put(R"({}{}{{)", comma, sep);
        if (!mesh->name.empty()) put(R"("name":{},)", nameJson(mesh->name));
        put(R"("primitives":[)");
        for (size_t i = 0; i < mesh->written.size(); ++i) {
            put(R"({}{{"attributes":{{"POSITION":{})", i ? "," : "", accessor++);
            if (mesh->layout.normal) put(R"(,"NORMAL":{})", accessor++);
            if (mesh->layout.uv0) put(R"(,"TEXCOORD_0":{})", accessor++);
            if (mesh->layout.uv1) put(R"(,"TEXCOORD_1":{})", accessor++);
            put("}}");
            if (mesh->written[i].indices > 0) put(R"(,"indices":{})", accessor++);
            put(R"(,"mode":4}})");  // TRIANGLES
        }
        put("]}}");
        ++meshes, comma = ",";
    }
    put(R"(],"nodes":[)");
    comma = "";
    uint64_t node = 0;
    for (const auto& mesh : meshes_) {
        if (mesh->written.empty()) continue;
        put(R"({}{}{{)", comma, sep);
        if (!mesh->name.empty()) put(R"("name":{},)", nameJson(mesh->name));
        put(R"("mesh":{}}})", node++);
        comma = ",";
    }
    put(R"(],"scenes":[{{"nodes":[)");
    for (uint64_t n = 0; n < meshes; ++n) put("{}{}", n ? "," : "", n);
    put("]}}],\"scene\":0}}\n");
    sink(std::string_view(out.data(), out.size()));
}

void GltfStreamWriter::commit() {
    flushAll();
    const uint64_t payload = scratch_ ? scratch_->size : 0;
    if (binary_) return writeGlb();
    auto writeGltf = [&](const std::string& uri) {
        AtomicFile file(path_);
        writeDocument(uri, [&](std::string_view text) { file.write(text.data(), text.size()); });
        file.commit();
    };
    if (payload <= kMaxDataUriBytes) {
        std::vector<uint8_t> bytes;
        if (scratch_) scratch_->read([&](const char* p, size_t n) { bytes.insert(bytes.end(), p, p + n); });
        return writeGltf(payload ? "data:application/octet-stream;base64," + encodeBase64(bytes) : "");
    }
    // Above what readers keep in a data URI, the buffer goes to STEM.bin beside the .gltf, as
    // exporters do; it is removed again if the .gltf cannot be written.
    const std::filesystem::path bin = externalBufferPath(path_, 0, 1);
    {
        AtomicFile file(bin.string());
        scratch_->read([&](const char* p, size_t n) { file.write(p, n); });
        file.commit();
    }
    try {
        writeGltf(bin.filename().string());
    } catch (...) {
        std::error_code ignored;
        std::filesystem::remove(bin, ignored);
        throw;
    }
}

void GltfStreamWriter::writeGlb() {
    uint64_t length = 0;  // the JSON chunk's length comes first: the document is written twice
    writeDocument("", [&](std::string_view text) { length += text.size(); });
    const uint64_t padded = (length + 3) / 4 * 4;            // chunks are 4-byte aligned; JSON pads with spaces
    const uint64_t payload = scratch_ ? scratch_->size : 0;  // floats and indices: a multiple of 4
    const uint64_t total = 12 + 8 + padded + (payload ? 8 + payload : 0);
    if (total > std::numeric_limits<uint32_t>::max())
        fail(path_, "{} bytes do not fit in one GLB file (at most 4 GiB)", total);
    AtomicFile file(path_);
    auto word = [&](uint32_t w) { file.write(&w, 4); };
    word(0x46546C67u), word(2), word(uint32_t(total));  // "glTF", version 2
    word(uint32_t(padded)), word(0x4E4F534Au);           // "JSON"
    writeDocument("", [&](std::string_view text) { file.write(text.data(), text.size()); });
    file.write("   ", padded - length);
    if (payload) {
        word(uint32_t(payload)), word(0x004E4942u);  // "BIN\0"
        scratch_->read([&](const char* p, size_t n) { file.write(p, n); });
    }
    file.commit();
}

}  // namespace penumbra
