#include "python/PythonSources.h"

#include "bake/kinds/ReceiverKind.h"
#include "stream/util/AnonymousFile.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/Npy.h"
#include "stream/util/Progress.h"
#include "stream/SourceRegistry.h"
#include "stream/TriangleSource.h"

#include <pybind11/numpy.h>

#include <nlohmann/json.hpp>

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <optional>

namespace py = pybind11;

namespace penumbra::python {
namespace {

std::mutex tableMutex;
int64_t nextId = 1;
std::map<int64_t, std::weak_ptr<SourceSpec>>& sourceTable() {
    static std::map<int64_t, std::weak_ptr<SourceSpec>> table;
    return table;
}
std::map<int64_t, std::weak_ptr<PointsSpec>>& pointsTable() {
    static std::map<int64_t, std::weak_ptr<PointsSpec>> table;
    return table;
}

template <class Spec>
std::shared_ptr<Spec> lookup(std::map<int64_t, std::weak_ptr<Spec>>& table, int64_t id, const std::string& where) {
    std::lock_guard lock(tableMutex);
    auto it = table.find(id);
    std::shared_ptr<Spec> spec = it == table.end() ? nullptr : it->second.lock();
    if (!spec) fail(where, "no Python object with id {} (entries of this type come from add_source / points=)", id);
    return spec;
}

/// How a source is read again for the second pass.
enum class Replay { Call, Iterate, Buffer };

/// Triangles from Python: each item a float32 array (n, 3, 3) or (n, 9). Callables are called once
/// per pass, re-iterables iterated once per pass; a one-shot iterator is copied to an unnamed
/// scratch file during the first pass and replayed from there.
class PythonSource final : public TriangleSource {
public:
    /// @param where the scene entry, for messages ("<dict>: geometry[1]")
    PythonSource(std::shared_ptr<SourceSpec> spec, std::string where) : spec_(std::move(spec)), where_(std::move(where)) {
        py::gil_scoped_acquire gil;
        const py::object& o = spec_->object;
        if (py::isinstance<py::function>(o) || (!py::hasattr(o, "__iter__") && PyCallable_Check(o.ptr())))
            replay_ = Replay::Call;
        else if (PyIter_Check(o.ptr()))  // an iterator (it has __next__): one pass only; iter(o) would be a call of __iter__
            replay_ = Replay::Buffer;
        else
            replay_ = Replay::Iterate;
    }
    ~PythonSource() override {
        py::gil_scoped_acquire gil;
        iterator_ = py::object(), slice_ = py::object();
        if (fd_ >= 0) ::close(fd_);
    }
    size_t read(std::span<Triangle> out) override {
        if (replaying_) return readBuffer(out);
        size_t n = 0;
        while (n < out.size()) {
            if (next_ == pending_.size() && !fetch()) break;
            const size_t take = std::min(out.size() - n, pending_.size() - next_);
            std::copy_n(pending_.begin() + ptrdiff_t(next_), take, out.begin() + ptrdiff_t(n));
            next_ += take, n += take, passTriangles_ += take;
        }
        if (replay_ == Replay::Buffer && n) append(out.first(n));
        return n;
    }
    void rewind() override {
        if (replay_ == Replay::Buffer) {
            if (!replaying_) {  // the rest of the first pass goes to the file too
                std::vector<Triangle> rest(kTriangleChunk);
                while (read(rest)) {
                }
            }
            replaying_ = true, offset_ = 0;
            return;
        }
        py::gil_scoped_acquire gil;
        iterator_ = py::object(), started_ = false, chunk_ = 0;
        slice_ = py::object(), sliceNext_ = sliceCount_ = 0;
        pending_.clear(), next_ = 0;
        passTriangles_ = 0, ended_ = false;
    }
    std::string name() const override { return where_ + " (add_source)"; }
    std::optional<uint64_t> sizeHint() const override { return spec_->count; }

private:
    /// The next chunk from Python into pending_; false at the end of the pass.
    bool fetch() {
        py::gil_scoped_acquire gil;
        const InsideSource inside;  // a bake() from the source would wait for this one forever
        if (!started_) {
            if (replay_ == Replay::Buffer && spec_->consumed)
                fail(name(), "is a one-shot iterator that an earlier bake or generate() has read; give a callable that returns "
                             "a new iterator, or a list, to use the scene more than once");
            py::object iterable = replay_ == Replay::Call ? spec_->object() : spec_->object;
            if (!py::hasattr(iterable, "__iter__"))  // py::iter's TypeError named no scene entry
                throw py::type_error(fmt::format("{}: the source gave an object of type '{}', not an iterable of chunks", name(),
                                                 std::string(py::str(py::type::of(iterable).attr("__name__")))));
            iterator_ = py::iter(iterable);
            started_ = true;
            spec_->consumed = replay_ == Replay::Buffer;
        }
        pending_.clear(), next_ = 0;
        if (sliceNext_ < sliceCount_) return takeSlice(), true;
        while (pending_.empty()) {
            // Ctrl-C is seen by the calling thread, which cancels: a source of a few triangles a
            // second was called for thousands more before the chunk was full.
            if (cancelFlag.load(std::memory_order_relaxed)) throw Cancelled();
            PyObject* item = PyIter_Next(iterator_.ptr());
            if (!item) {
                if (PyErr_Occurred()) throw py::error_already_set();
                endOfPass();
                return false;
            }
            convert(py::reinterpret_steal<py::object>(item));
            ++chunk_;
        }
        return true;
    }
    /// A pass's count against `count` and against the first pass's: a source that replayed other
    /// triangles baked the first pass's receivers under the second pass's blockers, silently.
    void endOfPass() {
        if (ended_) return;
        ended_ = true;
        const uint64_t total = passTriangles_;  // everything fetched before the end was handed out
        if (spec_->count && total != *spec_->count)
            fail(name(), "gave {} triangles in a pass, but its count is {}", total, *spec_->count);
        if (firstPass_ && total != *firstPass_)
            fail(name(), "gave {} triangles on a later pass and {} on the first: a source must give the same triangles on every "
                         "pass (a callable or re-iterable starts again from the beginning each time)",
                 total, *firstPass_);
        firstPass_ = total;
    }
    void convert(const py::object& item) {
        const std::string where = fmt::format("{} chunk {}", name(), chunk_);
        if (!py::isinstance<py::array>(item))
            throw py::type_error(fmt::format("{}: expected a NumPy float32 array of shape (n, 3, 3) or (n, 9), got {}",
                                             where, std::string(py::str(py::type::of(item).attr("__name__")))));
        auto a = py::reinterpret_borrow<py::array>(item);
        if (!a.dtype().is(py::dtype::of<float>()))
            throw py::type_error(fmt::format("{}: expected dtype float32, got {}", where, std::string(py::str(a.dtype()))));
        const bool shape339 = a.ndim() == 3 && a.shape(1) == 3 && a.shape(2) == 3;
        const bool shape9 = a.ndim() == 2 && a.shape(1) == 9;
        if (!shape339 && !shape9) {
            std::string shape;
            for (py::ssize_t d = 0; d < a.ndim(); ++d) shape += (d ? ", " : "") + std::to_string(a.shape(d));
            if (a.ndim() == 1) shape += ",";  // Python's spelling of a 1-tuple
            throw py::value_error(fmt::format("{}: expected shape (n, 3, 3) or (n, 9), got ({})", where, shape));
        }
        // Read in place through the array's strides, a slice of at most kTriangleChunk at a time:
        // a copy of the whole chunk (to C order, then to triangles) was 45-75 bytes a triangle
        // that no memory budget counted (a 4M-triangle chunk: 165 MiB over an 83M budget).
        slice_ = a, sliceNext_ = 0, sliceCount_ = size_t(a.shape(0));
        sliceBase_ = static_cast<const char*>(a.data());
        sliceStride_[0] = a.strides(0);
        for (int k = 0; k < 3; ++k)
            for (int c = 0; c < 3; ++c)
                sliceStride_[1 + 3 * k + c] = shape339 ? k * a.strides(1) + c * a.strides(2) : (3 * k + c) * a.strides(1);
        if (sliceCount_ > 0) takeSlice();
    }
    /// The next slice of the array being read into pending_ (GIL held: the array is Python's).
    void takeSlice() {
        const size_t n = std::min(sliceCount_ - sliceNext_, size_t(kTriangleChunk));
        pending_.resize(n);
        const uint32_t flags = spec_->alpha ? kTriangleAlphaMatte : 0u;
        for (size_t t = 0; t < n; ++t) {
            const char* row = sliceBase_ + py::ssize_t(sliceNext_ + t) * sliceStride_[0];
            auto at = [&](int e) { float v; std::memcpy(&v, row + sliceStride_[1 + e], sizeof v); return v; };
            Triangle& tri = pending_[t];
            for (int k = 0; k < 3; ++k) tri.v[k] = glm::vec3(at(3 * k), at(3 * k + 1), at(3 * k + 2));
            tri.flags = flags;
        }
        sliceNext_ += n;
        if (sliceNext_ == sliceCount_) slice_ = py::object(), sliceCount_ = sliceNext_ = 0;
    }
    void append(std::span<const Triangle> tris) {
        if (fd_ < 0 && (fd_ = createAnonymousFile(scratchDirectory())) < 0)
            fail(scratchDirectory(), "cannot create a scratch file for a one-shot Python source: {}", std::strerror(errno));
        const char* bytes = reinterpret_cast<const char*>(tris.data());
        size_t left = tris.size_bytes();
        while (left) {
            const ssize_t w = ::pwrite(fd_, bytes, left, off_t(written_));
            if (w < 0 && errno == EINTR) continue;
            if (w <= 0) fail(scratchDirectory(), "writing a one-shot Python source's scratch file: {}", std::strerror(errno));
            bytes += w, left -= size_t(w), written_ += uint64_t(w);
        }
    }
    size_t readBuffer(std::span<Triangle> out) {
        const uint64_t want = std::min<uint64_t>(out.size_bytes(), written_ - offset_);
        char* bytes = reinterpret_cast<char*>(out.data());
        uint64_t got = 0;
        while (got < want) {
            const ssize_t r = ::pread(fd_, bytes + got, want - got, off_t(offset_ + got));
            if (r < 0 && errno == EINTR) continue;
            if (r <= 0) fail(scratchDirectory(), "reading a one-shot Python source's scratch file: {}", std::strerror(errno));
            got += uint64_t(r);
        }
        offset_ += got;
        return size_t(got / sizeof(Triangle));
    }

    std::shared_ptr<SourceSpec> spec_;
    std::string where_;
    Replay replay_ = Replay::Iterate;
    py::object iterator_;  // touched with the GIL held only
    bool started_ = false;
    uint64_t chunk_ = 0;
    std::vector<Triangle> pending_;
    size_t next_ = 0;
    py::object slice_;                   // the array being read, a slice at a time (GIL held)
    const char* sliceBase_ = nullptr;
    py::ssize_t sliceStride_[10] = {};   // bytes: per triangle, then per coordinate of its corners
    size_t sliceNext_ = 0, sliceCount_ = 0;
    int fd_ = -1;  // the one-shot source's copy
    uint64_t written_ = 0, offset_ = 0;
    bool replaying_ = false;
    uint64_t passTriangles_ = 0;         // handed out in this pass so far
    std::optional<uint64_t> firstPass_;  // the first pass's count, once it has ended
    bool ended_ = false;                 // this pass's end was checked
};

/// Receivers given as arrays; writes the points kind's .npy of visibilities.
class PythonPointsKind final : public ReceiverKind {
public:
    explicit PythonPointsKind(std::shared_ptr<PointsSpec> spec) : spec_(std::move(spec)) {}
    std::optional<uint64_t> receiverBound() const override { return spec_->receivers.size(); }
    ReceiverSet receivers() override { return spec_->receivers; }
    void write(const OutputContext& c) override {
        uint64_t shape[1] = {c.results.visibility.size()};
        ensureParentDirectory(c.output);
        writeNpy(c.output, "<f4", shape, c.results.visibility.data(), c.results.visibility.size() * sizeof(float));
    }

private:
    std::shared_ptr<PointsSpec> spec_;
};

/// (N, 3) rows of a float array as vec3s. @throw ValueError naming @p what.
std::vector<glm::vec3> rowsOf(py::handle h, const char* what) {
    // Real numbers only: forcecast took complex values' real part and booleans as 0 and 1.
    if (const auto given = py::array::ensure(h)) {
        const char kind = given.dtype().kind();
        if (kind != 'f' && kind != 'i' && kind != 'u')
            throw py::type_error(fmt::format("points: {} must hold real numbers, got dtype {}", what, std::string(py::str(given.dtype()))));
    }
    auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(h);
    if (!a || a.ndim() != 2 || a.shape(1) != 3)
        throw py::value_error(fmt::format("points: {} must be a float array of shape (N, 3)", what));
    std::vector<glm::vec3> rows(size_t(a.shape(0)));
    const float* p = a.data();
    for (size_t i = 0; i < rows.size(); ++i, p += 3) {
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
            throw py::value_error(fmt::format("points: {}[{}] is not finite", what, i));
        rows[i] = glm::vec3(p[0], p[1], p[2]);
    }
    return rows;
}

}  // namespace

std::shared_ptr<SourceSpec> addSourceSpec(py::object object, bool alpha, std::optional<uint64_t> count) {
    if (!PyCallable_Check(object.ptr()) && !py::hasattr(object, "__iter__"))
        throw py::type_error("add_source: expected a callable returning an iterable of chunks, or an iterable of chunks");
    auto spec = std::make_shared<SourceSpec>(SourceSpec{std::move(object), alpha, count, 0});
    std::lock_guard lock(tableMutex);
    spec->id = nextId++;
    sourceTable()[spec->id] = spec;
    return spec;
}

std::shared_ptr<PointsSpec> addPointsSpec(py::handle positions, py::handle normals) {
    auto spec = std::make_shared<PointsSpec>();
    spec->receivers.position = rowsOf(positions, "positions");
    spec->receivers.normal = rowsOf(normals, "normals");
    if (spec->receivers.position.size() != spec->receivers.normal.size())
        throw py::value_error(fmt::format("points: {} positions but {} normals", spec->receivers.position.size(),
                                          spec->receivers.normal.size()));
    for (glm::vec3& n : spec->receivers.normal)  // as the points file reader does
        if (const float length = glm::length(n); length > 0) n /= length;
    std::lock_guard lock(tableMutex);
    spec->id = nextId++;
    pointsTable()[spec->id] = spec;
    return spec;
}

void registerPythonSources() {
    static std::once_flag once;
    std::call_once(once, [] {
        registerSourceType("python", [](const SourceRequest& r) -> TriangleSourcePtr {
            JsonParams j(r.params, r.file, r.path);
            const int64_t id = j.integer("source", 1, INT64_MAX);
            j.boolean("alpha", false);  // read by add_source already; consumed so finish() accepts it
            j.finish();
            return std::make_unique<PythonSource>(lookup(sourceTable(), id, j.where("source")), r.where());
        });
        registerReceiverKind("python-points", [](const JsonParams& j, const SceneDesc&, KindUse use) -> std::unique_ptr<ReceiverKind> {
            auto points = lookup(pointsTable(), j.integer("source", 1, INT64_MAX), j.where("source"));
            if (use == KindUse::Validate) return nullptr;
            return std::make_unique<PythonPointsKind>(std::move(points));
        }, ".npy");
    });
}

}  // namespace penumbra::python
