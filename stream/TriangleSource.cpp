#include "stream/TriangleSource.h"

#include "stream/util/Error.h"

#include <algorithm>

namespace penumbra {

size_t VectorSource::read(std::span<Triangle> out) {
    size_t n = std::min(out.size(), triangles_.size() - next_);
    std::copy_n(triangles_.begin() + static_cast<std::ptrdiff_t>(next_), n, out.begin());
    next_ += n;
    return n;
}

size_t FiniteSource::read(std::span<Triangle> out) {
    const size_t n = inner_->read(out);
    for (size_t i = 0; i < n; ++i)
        if (!isFinite(out[i]))
            fail(where_, "triangle {} has a non-finite (NaN or infinite) vertex (in its data, or from a transform or scale "
                 "that overflows float)", position_ + i);
    position_ += n;
    return n;
}

uint64_t TriangleSource::skip(uint64_t count) {
    std::vector<Triangle> scratch(size_t(std::min<uint64_t>(count, kTriangleChunk)));
    uint64_t skipped = 0;
    while (skipped < count) {
        const size_t n = read(std::span<Triangle>(scratch).first(size_t(std::min<uint64_t>(count - skipped, scratch.size()))));
        if (n == 0) break;
        skipped += n;
    }
    return skipped;
}

uint64_t VectorSource::skip(uint64_t count) {
    const uint64_t n = std::min<uint64_t>(count, triangles_.size() - next_);
    next_ += size_t(n);
    return n;
}

uint64_t ConcatSource::skip(uint64_t count) {
    uint64_t skipped = 0;
    while (skipped < count && current_ < parts_.size()) {
        const uint64_t n = parts_[current_]->skip(count - skipped);
        skipped += n;
        if (skipped < count) ++current_;  // this part is at its end
    }
    return skipped;
}

size_t ConcatSource::read(std::span<Triangle> out) {
    while (current_ < parts_.size()) {
        if (size_t n = parts_[current_]->read(out)) return n;
        ++current_;
    }
    return 0;
}

void ConcatSource::rewind() {
    for (auto& p : parts_) p->rewind();
    current_ = 0;
}

namespace {

/// The sum of @p count over @p parts, or nullopt when one part's is unknown.
template <class Count>
std::optional<uint64_t> sumOf(const std::vector<TriangleSourcePtr>& parts, Count&& count) {
    uint64_t total = 0;
    for (const auto& p : parts) {
        std::optional<uint64_t> n = count(*p);
        if (!n) return std::nullopt;
        total += *n;
    }
    return total;
}

}  // namespace

std::optional<uint64_t> ConcatSource::sizeHint() const {
    return sumOf(parts_, [](const TriangleSource& s) { return s.sizeHint(); });
}

std::optional<uint64_t> ConcatSource::knownSize() const {
    return sumOf(parts_, [](const TriangleSource& s) { return s.knownSize(); });
}

uint64_t ConcatSource::residentBytes() const {
    uint64_t total = 0;
    for (const auto& p : parts_) total += p->residentBytes();
    return total;
}

std::string ConcatSource::residentDetail() const {
    const TriangleSource* largest = nullptr;
    for (const auto& p : parts_)
        if (!p->residentDetail().empty() && (!largest || p->residentBytes() > largest->residentBytes())) largest = p.get();
    return largest ? largest->residentDetail() : std::string();
}

std::vector<Triangle> readAll(TriangleSource& source) {
    std::vector<Triangle> all;
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t n = source.read(chunk)) all.insert(all.end(), chunk.begin(), chunk.begin() + n);
    return all;
}

}  // namespace penumbra
