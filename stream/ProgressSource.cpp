#include "stream/ProgressSource.h"

namespace penumbra {

ProgressSource::~ProgressSource() {
    if (pass_) pass_->abandon();  // left before its end: no "done" line
}

size_t ProgressSource::read(std::span<Triangle> out) {
    if (!pass_ && !finished_) pass_ = std::make_unique<ProgressReporter>(phase_, inner_->sizeHint().value_or(0), quiet_);
    const size_t n = inner_->read(out);
    if (!pass_) return n;
    pass_->update(n);
    if (n == 0) pass_->done(), pass_.reset(), finished_ = true;
    return n;
}

void ProgressSource::rewind() {
    // An unfinished pass ends without its "done" line: it did not read everything.
    if (pass_) pass_->abandon();
    pass_.reset(), finished_ = false;
    inner_->rewind();
}

}  // namespace penumbra
