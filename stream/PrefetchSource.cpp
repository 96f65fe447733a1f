#include "stream/PrefetchSource.h"

#include <algorithm>
#include <system_error>

namespace penumbra {

PrefetchSource::PrefetchSource(TriangleSourcePtr inner, size_t chunkTriangles, size_t depth)
    : inner_(std::move(inner)), chunkTriangles_(std::max<size_t>(1, chunkTriangles)), depth_(std::max<size_t>(1, depth)) {
    start();
}

PrefetchSource::~PrefetchSource() { stop(); }

void PrefetchSource::start() {
    ready_.clear();
    current_ = {};
    currentPos_ = 0, currentPart_ = 0;
    finished_ = stopping_ = false;
    error_ = nullptr;
    try {
        thread_ = std::thread([this] { run(); });
        inline_ = false;
    } catch (const std::system_error&) {
        // No thread to be had (an address-space or process limit): read in the caller's thread,
        // same triangles, same order, no overlap.
        inline_ = true;
    }
}

void PrefetchSource::stop() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    changed_.notify_all();
    if (thread_.joinable()) thread_.join();
}

void PrefetchSource::run() {
    try {
        for (;;) {
            Chunk chunk{std::vector<Triangle>(chunkTriangles_), 0};
            size_t n = inner_->read(chunk.triangles);
            chunk.triangles.resize(n);
            chunk.part = inner_->part();
            std::unique_lock lock(mutex_);
            changed_.wait(lock, [&] { return stopping_ || ready_.size() < depth_; });
            if (stopping_) return;
            if (n == 0) {
                finished_ = true;
                changed_.notify_all();
                return;
            }
            ready_.push_back(std::move(chunk));
            changed_.notify_all();
        }
    } catch (...) {
        std::lock_guard lock(mutex_);
        error_ = std::current_exception();
        finished_ = true;
        changed_.notify_all();
    }
}

size_t PrefetchSource::read(std::span<Triangle> out) {
    if (inline_) return inner_->read(out);
    size_t written = 0;
    while (written < out.size()) {
        if (currentPos_ == current_.triangles.size()) {
            std::unique_lock lock(mutex_);
            changed_.wait(lock, [&] { return !ready_.empty() || finished_; });
            if (ready_.empty()) {
                if (error_ && written == 0) std::rethrow_exception(error_);
                break;  // end (or an error, reported on the next call, after the good triangles)
            }
            if (written > 0 && ready_.front().part != currentPart_) break;  // one part per read
            current_ = std::move(ready_.front());
            ready_.pop_front();
            currentPos_ = 0;
            changed_.notify_all();
        }
        currentPart_ = current_.part;
        size_t n = std::min(out.size() - written, current_.triangles.size() - currentPos_);
        std::copy_n(current_.triangles.begin() + std::ptrdiff_t(currentPos_), n, out.begin() + std::ptrdiff_t(written));
        currentPos_ += n, written += n;
    }
    return written;
}

void PrefetchSource::rewind() {
    stop();
    inner_->rewind();
    start();
}

void PrefetchSource::rewindWrapped(const std::function<TriangleSourcePtr(TriangleSourcePtr)>& wrap) {
    stop();
    inner_->rewind();
    inner_ = wrap(std::move(inner_));
    start();
}

}  // namespace penumbra
