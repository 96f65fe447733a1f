#include "stream/GltfBytes.h"

#include "stream/util/Error.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include <fcntl.h>
#include <unistd.h>

namespace penumbra {

uint64_t gltfDecodedViewBytes(const GltfDocument& doc, int view) {
    if (view < 0 || size_t(view) >= doc.views.size() || !doc.views[size_t(view)].meshopt) return 0;
    const GltfMeshoptView& m = *doc.views[size_t(view)].meshopt;
    // The decoder writes whole 16-byte-aligned rows; the compressed input is read alongside.
    return m.count * m.byteStride + m.byteLength + 64;
}

GltfBytes::GltfBytes(const GltfDocument& doc, uint64_t decodedBudget)
    : doc_(doc), decodedBudget_(decodedBudget), fds_(doc.buffers.size(), -1) {}

GltfBytes::~GltfBytes() {
    for (int fd : fds_)
        if (fd >= 0) ::close(fd);
}

void GltfBytes::clear() {
    blocks_.clear();
    decoded_.clear();
    blockBytes_ = decodedBytes_ = 0;
    mru_[0] = mru_[1] = 0;
}

void GltfBytes::note() { peak_ = std::max(peak_, blockBytes_ + decodedBytes_); }

int GltfBytes::descriptor(int buffer) {
    int& fd = fds_[size_t(buffer)];
    if (fd < 0) {
        const std::string& file = doc_.buffers[size_t(buffer)].file;
        fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
        if (fd < 0) fail(file, "cannot open: {} (buffer {} of {})", std::strerror(errno), buffer, doc_.path);
    }
    return fd;
}

void GltfBytes::copy(int buffer, uint64_t offset, uint64_t size, uint8_t* out) {
    const GltfBuffer& b = doc_.buffers[size_t(buffer)];
    if (b.source == GltfBuffer::Source::DataUri) {
        std::memcpy(out, b.bytes.data() + offset, size_t(size));
        return;
    }
    if (b.source == GltfBuffer::Source::None) fail(doc_.path, "buffer {} has no data (a meshopt fallback buffer)", buffer);
    const int fd = descriptor(buffer);
    uint64_t at = b.fileOffset + offset;
    while (size > 0) {
        ssize_t got = ::pread(fd, out, size_t(std::min<uint64_t>(size, 1u << 30)), off_t(at));
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) fail(b.file, "read error: {}", std::strerror(errno));
        if (got == 0) fail(b.file, "file is shorter than buffer {} says (truncated while being read?)", buffer);
        out += got, at += uint64_t(got), size -= uint64_t(got);
    }
}

GltfBytes::Block& GltfBytes::block(int buffer, uint64_t index) {
    ++clock_;
    for (size_t m : mru_)
        if (m < blocks_.size() && blocks_[m].buffer == buffer && blocks_[m].index == index) {
            blocks_[m].lastUse = clock_;
            return blocks_[m];
        }
    size_t slot = blocks_.size();
    for (size_t i = 0; i < blocks_.size(); ++i)
        if (blocks_[i].buffer == buffer && blocks_[i].index == index) slot = i;
    if (slot == blocks_.size()) {
        if (blocks_.size() < kGltfCacheBlocks) {
            blocks_.emplace_back();
            blocks_.back().data = std::make_unique<uint8_t[]>(kGltfBlockBytes);
            blockBytes_ += kGltfBlockBytes;
            note();
        } else {
            slot = size_t(std::min_element(blocks_.begin(), blocks_.end(),
                                           [](const Block& a, const Block& b) { return a.lastUse < b.lastUse; }) -
                          blocks_.begin());
        }
        Block& b = blocks_[slot];
        const uint64_t start = index * kGltfBlockBytes, length = doc_.buffers[size_t(buffer)].byteLength;
        b.buffer = -1;  // invalid until the read succeeded
        b.size = size_t(std::min<uint64_t>(kGltfBlockBytes, length - start));
        copy(buffer, start, b.size, b.data.get());
        b.buffer = buffer, b.index = index;
    }
    blocks_[slot].lastUse = clock_;
    mru_[1] = mru_[0], mru_[0] = slot;
    return blocks_[slot];
}

const uint8_t* GltfBytes::raw(int buffer, uint64_t offset, uint32_t size) {
    const GltfBuffer& b = doc_.buffers[size_t(buffer)];
    if (b.source == GltfBuffer::Source::DataUri) return b.bytes.data() + offset;
    const uint64_t first = offset / kGltfBlockBytes, last = (offset + size - 1) / kGltfBlockBytes;
    if (first == last) return block(buffer, first).data.get() + (offset - first * kGltfBlockBytes);
    // An element across a block boundary is assembled in the scratch buffer.
    const uint32_t head = uint32_t((first + 1) * kGltfBlockBytes - offset);
    std::memcpy(scratch_, block(buffer, first).data.get() + (offset - first * kGltfBlockBytes), head);
    std::memcpy(scratch_ + head, block(buffer, last).data.get(), size - head);
    return scratch_;
}

const std::vector<uint8_t>& GltfBytes::decoded(int view) {
    for (auto it = decoded_.begin(); it != decoded_.end(); ++it)
        if (it->view == view) {
            decoded_.splice(decoded_.begin(), decoded_, it);
            return decoded_.front().bytes;
        }
    const GltfMeshoptView& m = *doc_.views[size_t(view)].meshopt;
    const uint64_t need = m.count * m.byteStride;
    // Make room first, keeping the most recent view (the other half of a primitive).
    while (decoded_.size() > 1 && decodedBytes_ + need > decodedBudget_) {
        decodedBytes_ -= decoded_.back().bytes.size();
        decoded_.pop_back();
    }
    Decoded d;
    d.view = view;
    d.bytes.resize(size_t(need));
    {
        std::vector<uint8_t> input(size_t(m.byteLength));
        copy(m.buffer, m.byteOffset, m.byteLength, input.data());
        peak_ = std::max(peak_, bytesHeld() + need + input.size());
        int status = -1;
        switch (m.mode) {
        case GltfMeshoptView::Mode::Attributes:
            status = meshopt_decodeVertexBuffer(d.bytes.data(), size_t(m.count), m.byteStride, input.data(), input.size());
            break;
        case GltfMeshoptView::Mode::Triangles:
            if (m.count % 3 == 0)
                status = meshopt_decodeIndexBuffer(d.bytes.data(), size_t(m.count), m.byteStride, input.data(), input.size());
            break;
        case GltfMeshoptView::Mode::Indices:
            status = meshopt_decodeIndexSequence(d.bytes.data(), size_t(m.count), m.byteStride, input.data(), input.size());
            break;
        }
        if (status != 0)
            fail(doc_.path, "bufferView {}: EXT_meshopt_compression data does not decode (corrupt or truncated, code {})", view,
                 status);
    }
    switch (m.filter) {
    case GltfMeshoptView::Filter::None: break;
    case GltfMeshoptView::Filter::Octahedral:
        if (m.byteStride != 4 && m.byteStride != 8) fail(doc_.path, "bufferView {}: OCTAHEDRAL filter needs byteStride 4 or 8", view);
        meshopt_decodeFilterOct(d.bytes.data(), size_t(m.count), m.byteStride);
        break;
    case GltfMeshoptView::Filter::Quaternion:
        if (m.byteStride != 8) fail(doc_.path, "bufferView {}: QUATERNION filter needs byteStride 8", view);
        meshopt_decodeFilterQuat(d.bytes.data(), size_t(m.count), m.byteStride);
        break;
    case GltfMeshoptView::Filter::Exponential:
        if (m.byteStride % 4 != 0) fail(doc_.path, "bufferView {}: EXPONENTIAL filter needs a byteStride multiple of 4", view);
        meshopt_decodeFilterExp(d.bytes.data(), size_t(m.count), m.byteStride);
        break;
    }
    decodedBytes_ += d.bytes.size();
    note();
    decoded_.push_front(std::move(d));
    return decoded_.front().bytes;
}

const uint8_t* GltfBytes::at(int view, uint64_t offset, uint32_t size) {
    const GltfBufferView& v = doc_.views[size_t(view)];
    if (v.meshopt) return decoded(view).data() + offset;
    return raw(v.buffer, v.byteOffset + offset, size);
}

}  // namespace penumbra
