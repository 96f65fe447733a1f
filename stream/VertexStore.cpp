#include "stream/VertexStore.h"

#include "stream/util/Memory.h"
#include "stream/util/AnonymousFile.h"
#include "stream/util/Error.h"

#include <algorithm>
#include <cerrno>
#include <cstring>

#include <unistd.h>

namespace penumbra {

VertexStore::VertexStore(std::string name, uint64_t residentVertices)
    : name_(std::move(name)), residentLimit_(residentVertices) {}

VertexStore::~VertexStore() {
    if (fd_ >= 0) ::close(fd_);
}

uint64_t VertexStore::residentBytes(uint64_t vertices) {
    if (vertices <= kResidentVertices) return vertices * sizeof(glm::vec3) * 2;  // vector growth: twice the size at worst
    return (2 * kResidentVertices + kVertexBlock * (kVertexCacheBlocks + 1)) * sizeof(glm::vec3);
}

void VertexStore::clear() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    releaseStorage(resident_), releaseStorage(tail_), releaseStorage(cache_);
    count_ = spilled_ = 0;
}

void VertexStore::push(const glm::vec3& p) {
    if (count_ < residentLimit_) {
        resident_.push_back(p);
    } else {
        if (tail_.capacity() == 0) tail_.reserve(kVertexBlock);
        tail_.push_back(p);
        if (tail_.size() == kVertexBlock) flushTail();
    }
    ++count_;
}

void VertexStore::flushTail() {
    if (tail_.empty()) return;
    if (fd_ < 0) {
        directory_ = scratchDirectory();
        fd_ = createAnonymousFile(directory_);
        if (fd_ < 0) fail(directory_, "cannot create a scratch file for the vertices of {}: {}", name_, std::strerror(errno));
    }
    // Blocks are written whole (a partial last block is padded), so block b is at b * blockBytes.
    const size_t bytes = kVertexBlock * sizeof(glm::vec3);
    tail_.resize(kVertexBlock, glm::vec3(0.0f));
    const char* p = reinterpret_cast<const char*>(tail_.data());
    for (size_t done = 0; done < bytes;) {
        ssize_t n = ::pwrite(fd_, p + done, bytes - done, off_t(spilled_ + done));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0)
            fail(directory_, "cannot write the scratch file for the vertices of {}: {}", name_,
                 std::strerror(n < 0 ? errno : EIO));
        done += size_t(n);
    }
    spilled_ += bytes;
    tail_.clear();
}

VertexStore::Block& VertexStore::block(uint64_t index) {
    ++clock_;
    if (mru_ < cache_.size() && cache_[mru_].index == index) {
        cache_[mru_].lastUse = clock_;
        return cache_[mru_];
    }
    size_t slot = cache_.size();
    for (size_t i = 0; i < cache_.size(); ++i)
        if (cache_[i].index == index) slot = i;
    if (slot == cache_.size()) {
        if (cache_.size() < kVertexCacheBlocks) {
            cache_.emplace_back();
            cache_.back().data.resize(kVertexBlock);
        } else {
            slot = size_t(std::min_element(cache_.begin(), cache_.end(),
                                           [](const Block& a, const Block& b) { return a.lastUse < b.lastUse; }) -
                          cache_.begin());
        }
        Block& b = cache_[slot];
        b.index = UINT64_MAX;
        const size_t bytes = kVertexBlock * sizeof(glm::vec3);
        char* p = reinterpret_cast<char*>(b.data.data());
        for (size_t done = 0; done < bytes;) {
            ssize_t n = ::pread(fd_, p + done, bytes - done, off_t(index * bytes + done));
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) fail(directory_, "cannot read back the vertices of {}: {}", name_, std::strerror(n < 0 ? errno : EIO));
            done += size_t(n);
        }
        b.index = index;
    }
    cache_[slot].lastUse = clock_;
    mru_ = slot;
    return cache_[slot];
}

glm::vec3 VertexStore::operator[](uint64_t i) {
    if (i < resident_.size()) return resident_[size_t(i)];
    const uint64_t spilledIndex = i - residentLimit_;
    const uint64_t b = spilledIndex / kVertexBlock, written = spilled_ / (kVertexBlock * sizeof(glm::vec3));
    if (b >= written) return tail_[size_t(spilledIndex % kVertexBlock)];  // still in the block being filled
    return block(b).data[size_t(spilledIndex % kVertexBlock)];
}

}  // namespace penumbra
