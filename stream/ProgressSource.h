#pragma once
/// @file ProgressSource.h
/// @brief A pass over a source shown as a phase on stderr: `[read mesh.obj] 42.0% (420000/1000000)
/// elapsed 1.2s ETA 1.7s`, for the commands that read a whole file or scene without a bake's own
/// phases (`info`, `convert`, `generate`).

#include "stream/TriangleSource.h"
#include "stream/util/Progress.h"

#include <memory>
#include <optional>
#include <string>

namespace penumbra {

/// @brief Passes @p inner's triangles through unchanged and counts them in a ProgressReporter,
/// one per pass: it starts at the first read after construction or rewind() and ends, with its
/// "done" line, when a read returns 0. The total is the inner source's sizeHint() (no percentage
/// or ETA without one). A pass left unfinished (an error, or a rewind before the end) prints no
/// "done" line.
class ProgressSource final : public DecoratedSource {
public:
    /// @param phase the name in brackets; @param quiet nothing printed (currentProgress() still
    /// sees the pass, as for a quiet bake).
    ProgressSource(TriangleSourcePtr inner, std::string phase, bool quiet)
        : DecoratedSource(std::move(inner)), phase_(std::move(phase)), quiet_(quiet) {}
    ~ProgressSource() override;
    ProgressSource(const ProgressSource&) = delete;
    ProgressSource& operator=(const ProgressSource&) = delete;
    /// @throw what the inner source throws; Cancelled after requestCancel().
    size_t read(std::span<Triangle> out) override;
    void rewind() override;

private:
    std::string phase_;
    bool quiet_;
    bool finished_ = false;  ///< this pass has ended: reads past the end start no new display
    std::unique_ptr<ProgressReporter> pass_;
};

}  // namespace penumbra
