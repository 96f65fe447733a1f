#pragma once
/// @file VertexStore.h
/// @brief The vertex array of a streamed OBJ in bounded memory.
///
/// Memory contract: the first kResidentVertices vertices (1M, 12 MiB) stay in memory. Beyond
/// them, vertices are appended to an anonymous scratch file (AnonymousFile.h, in `--tmp`) in
/// blocks of kVertexBlock (4096 vertices, 48 KiB) and read back through a cache of
/// kVertexCacheBlocks blocks (64, 3 MiB), least recently used first out. Faces of real exports
/// refer to vertices near one another, so the cache serves them; a file whose faces jump
/// anywhere is slower, never larger. residentBytes() is the bound: 15 MiB held, 27 MiB at most while
/// the resident array grows (a vector doubles), whatever the file.

#include <glm/vec3.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace penumbra {

class VertexStore {
public:
    static constexpr uint64_t kResidentVertices = 1u << 20;
    static constexpr uint64_t kVertexBlock = 4096;
    static constexpr size_t kVertexCacheBlocks = 64;

    /// @param name the file the vertices come from, for messages.
    /// @param residentVertices how many stay in memory (tests use small values to force spills).
    explicit VertexStore(std::string name, uint64_t residentVertices = kResidentVertices);
    ~VertexStore();
    VertexStore(const VertexStore&) = delete;
    VertexStore& operator=(const VertexStore&) = delete;

    /// @brief Appends a vertex. @throw InputError naming the scratch directory when the spill
    /// file cannot be created or written (a full disk).
    void push(const glm::vec3& p);
    /// @brief Vertex @p i (< size()); for spilled vertices the block is read from the file.
    glm::vec3 operator[](uint64_t i);

    uint64_t size() const { return count_; }
    /// Bytes written to the scratch file so far.
    uint64_t spilledBytes() const { return spilled_; }
    /// @brief Heap bytes held at most for @p vertices vertices (at most the contract above), for
    /// memory plans.
    static uint64_t residentBytes(uint64_t vertices);
    /// Drops everything (back to empty).
    void clear();

private:
    struct Block {
        uint64_t index = UINT64_MAX;
        uint64_t lastUse = 0;
        std::vector<glm::vec3> data;
    };
    void flushTail();
    Block& block(uint64_t index);

    std::string name_;
    uint64_t residentLimit_;
    std::vector<glm::vec3> resident_;
    std::vector<glm::vec3> tail_;  // the spilled block being filled
    std::vector<Block> cache_;
    uint64_t count_ = 0, spilled_ = 0, clock_ = 0;
    size_t mru_ = 0;
    int fd_ = -1;
    std::string directory_;
};

}  // namespace penumbra
