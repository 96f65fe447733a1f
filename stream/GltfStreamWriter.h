#pragma once
/// @file GltfStreamWriter.h
/// @brief glTF output in bounded memory, for `penumbra convert` and `generate`: triangles go in
/// one at a time, per mesh, and the file is written at commit().
///
/// Memory contract: the vertices and indices of the meshes' open primitives, and the welding
/// table over them, at most about kOpenBytes (32 MiB) in all (twice that while a vector grows), whatever the file's size. When a
/// triangle takes the open data past that, every open primitive is written to an anonymous
/// scratch file (AnonymousFile.h, in `--tmp` or $TMPDIR) and the mesh goes on in a new
/// primitive. A mesh whose vertices fit in one primitive comes out exactly as a whole-mesh weld
/// would make it; a larger one is split into primitives of its own vertices, a vertex on a split
/// appearing in both. Meshes whose triangles interleave (OBJ groups that come back) are open
/// together, so when together they pass the bound each is split too. Splits depend only on the order of the triangles, so the bytes are the same
/// on every run. Besides, each mesh costs about a kilobyte until commit() (its record and its
/// primitives' offsets): 277 MB of RSS for an OBJ of 300,000 groups. At commit() the JSON is
/// written as text straight to the file (twice for a .glb, whose header states its length first)
/// and the scratch data copied behind it, so the disk holds the payload twice for a moment.
///
/// Welding merges corners whose position, normal and texture coordinates (those the mesh has)
/// agree bit for bit: -0 stays apart from +0, as a reader sees them. Vertices keep the order in
/// which their first corner arrived.

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace penumbra {

/// The attributes a mesh writes besides POSITION.
struct GltfVertexLayout {
    bool normal = false, uv0 = false, uv1 = false;
};

/// One corner of a triangle; attributes the mesh's layout lacks are ignored.
struct GltfCorner {
    glm::vec3 position{0.0f}, normal{0.0f};
    glm::vec2 uv0{0.0f}, uv1{0.0f};
};

class GltfStreamWriter {
public:
    static constexpr uint64_t kOpenBytes = 32ull << 20;
    /// The most vertex and index bytes one file holds: a GLB's length fields are 32-bit, and its
    /// headers and JSON need room too.
    static constexpr uint64_t kMaxBufferBytes = (1ull << 32) - 1 - (1u << 20);

    enum class Indexing {
        Welded,  ///< indexed, corners that agree bit for bit share a vertex
        None,    ///< three vertices per triangle, no indices (a plain triangle soup)
    };

    /// @param path the .glb or .gltf to write (binary when @p binary); a .gltf keeps its buffer
    ///        in a data URI up to kMaxDataUriBytes, else in "STEM.bin" beside it.
    /// @param openBytes the memory bound above (tests use small values to force splits).
    /// @throw InputError before any work when a .gltf's "STEM.bin" exists and is not a file.
    GltfStreamWriter(std::string path, bool binary, uint64_t openBytes = kOpenBytes);
    ~GltfStreamWriter();
    GltfStreamWriter(const GltfStreamWriter&) = delete;
    GltfStreamWriter& operator=(const GltfStreamWriter&) = delete;

    /// @brief Adds a mesh (and a node drawing it) named @p name. Meshes without triangles are
    /// left out of the file. @return the mesh's id for addTriangle().
    int addMesh(std::string name, GltfVertexLayout layout, Indexing indexing = Indexing::Welded);
    /// @brief Appends a triangle (counter-clockwise front face) to mesh @p mesh.
    /// @throw InputError naming the scratch directory when a spill cannot be written, or the
    ///        output when the data outgrows one glTF buffer (4 GiB).
    void addTriangle(int mesh, const std::array<GltfCorner, 3>& corners);
    /// @brief Writes the file atomically (the .bin first, removed again if the .gltf fails).
    /// @throw InputError naming the file that could not be written.
    void commit();

    /// Primitives written so far (for tests).
    size_t primitiveCount() const;

private:
    struct Mesh;
    struct Scratch;
    /// Writes @p mesh's open primitive to the scratch file; @p keepStorage keeps its arrays'
    /// capacity (the mesh being added to), else it is given back.
    void flush(Mesh& mesh, bool keepStorage = false);
    void flushAll(const Mesh* current = nullptr);
    /// @brief Writes the JSON document to @p sink in pieces; buffer 0 gets @p uri when it is
    /// not empty. The same text on every call.
    void writeDocument(const std::string& uri, const std::function<void(std::string_view)>& sink) const;
    void writeGlb();

    std::string path_;
    bool binary_;
    uint64_t openLimit_;
    uint64_t openBytes_ = 0;
    std::vector<std::unique_ptr<Mesh>> meshes_;
    std::unique_ptr<Scratch> scratch_;
};

}  // namespace penumbra
