#include "python/BakeRun.h"

#include "bake/BakeOutputs.h"
#include "bake/LibraryErrors.h"
#include "bake/Pipeline.h"
#include "bake/cast/Caster.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"
#include "stream/util/Memory.h"
#include "python/PythonSources.h"
#include "stream/util/Progress.h"
#include "stream/util/TempRegistry.h"
#include "stream/SourceRegistry.h"

#include <pybind11/stl.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <system_error>
#include <thread>

namespace py = pybind11;

namespace penumbra::python {
namespace {

PyObject* errorType = nullptr;       // penumbra.Error
PyObject* sceneErrorType = nullptr;  // penumbra.SceneError

/// How often the calling thread wakes during a bake: progress, Ctrl-C.
constexpr auto kPollInterval = std::chrono::milliseconds(100);
/// One bake at a time per process: the cancel flag, the scratch directory and the thread limit
/// are the process's. A second caller's bake waits (with the GIL released) for the first.
std::timed_mutex bakeMutex;

}  // namespace

py::object toPython(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }
namespace {

/// Raises SceneError "ROOT: PATH: WHAT" (the CLI's "file: key: message").
[[noreturn]] void raiseSceneValue(const std::string& root, const std::string& path, const std::string& what) {
    PyErr_SetString(sceneErrorType, fmt::format("{}: {}{}", root, path.empty() ? "" : path + ": ", what).c_str());
    throw py::error_already_set();
}

/// @p o as JSON, naming the key (@p path) of a value JSON cannot hold: json.dumps wrote NaN and
/// inf as bare words, which the parser then refused at a column of a text the caller never saw.
/// Scene JSON nests at most this deep, as a scene file (the CLI's parser): a dict that holds
/// itself, or one nested thousands deep, overflowed the stack.
constexpr int kMaxSceneDepth = 64;

nlohmann::json toJsonAt(py::handle o, const std::string& path, const std::string& root, int depth = 0) {
    auto fail = [&](const std::string& what) { raiseSceneValue(root, path, what); };
    if (o.is_none()) return nullptr;
    if (depth > kMaxSceneDepth)
        fail(fmt::format("nests deeper than {} levels (a dict or list that holds itself?)", kMaxSceneDepth));
    if (py::isinstance<py::bool_>(o)) return o.cast<bool>();
    if (py::isinstance<py::int_>(o)) {
        const long long value = PyLong_AsLongLong(o.ptr());
        if (!(value == -1 && PyErr_Occurred())) return value;
        PyErr_Clear();
        const unsigned long long positive = PyLong_AsUnsignedLongLong(o.ptr());
        if (!(positive == static_cast<unsigned long long>(-1) && PyErr_Occurred())) return positive;
        PyErr_Clear();
        fail(fmt::format("{} is out of the 64-bit integer range", std::string(py::str(o))));
    }
    if (py::isinstance<py::float_>(o)) {
        const double value = o.cast<double>();
        if (!std::isfinite(value)) fail(fmt::format("{} is not a finite number", std::string(py::str(o))));
        return value;
    }
    if (py::isinstance<py::str>(o)) return o.cast<std::string>();
    if (py::isinstance<py::dict>(o)) {
        nlohmann::json object = nlohmann::json::object();
        for (const auto& [key, value] : py::reinterpret_borrow<py::dict>(o)) {
            if (!py::isinstance<py::str>(key)) fail(fmt::format("key {} is not a string", std::string(py::repr(key))));
            const std::string name = key.cast<std::string>();
            object[name] = toJsonAt(value, path.empty() ? name : path + "." + name, root, depth + 1);
        }
        return object;
    }
    if (py::isinstance<py::list>(o) || py::isinstance<py::tuple>(o)) {
        nlohmann::json array = nlohmann::json::array();
        size_t i = 0;
        for (py::handle item : o) array.push_back(toJsonAt(item, fmt::format("{}[{}]", path, i++), root, depth + 1));
        return array;
    }
    if (py::hasattr(o, "tolist")) return toJsonAt(o.attr("tolist")(), path, root, depth + 1);  // NumPy scalars and arrays
    fail(fmt::format("a value of type '{}' is not a JSON value", std::string(py::str(py::type::of(o).attr("__name__")))));
}

}  // namespace

nlohmann::json toJson(py::handle o, const std::string& where, const std::string& path) { return toJsonAt(o, path, where); }

void registerExceptions(py::module_& m) {
    errorType = PyErr_NewExceptionWithDoc("penumbra.Error", "A bake or scene problem, as the CLI reports it.",
                                          PyExc_RuntimeError, nullptr);
    py::tuple bases = py::make_tuple(py::handle(errorType), py::handle(PyExc_ValueError));
    sceneErrorType = PyErr_NewExceptionWithDoc("penumbra.SceneError", "A scene key or value is wrong; the message names it.",
                                               bases.ptr(), nullptr);
    m.add_object("Error", py::handle(errorType));
    m.add_object("SceneError", py::handle(sceneErrorType));
}

namespace {

/// The CLI's option names in a message, as a Python caller gave them: "--memory-budget 1 MiB is
/// too small" was said to a caller who passed memory_budget="1M".
std::string withPythonNames(std::string message) {
    static const std::pair<const char*, const char*> kNames[] = {
        {"--memory-budget", "memory_budget"}, {"--method", "method"}, {"--threads", "threads"},
        {"--tmp", "tmp_dir"},                 {"--output", "write()"}, {"-o", "write()"}};
    for (const auto& [cli, python] : kNames) {
        const std::string from = cli;
        for (size_t at = message.find(from); at != std::string::npos; at = message.find(from, at)) {
            const size_t end = at + from.size();
            const bool word = (at == 0 || message[at - 1] == ' ' || message[at - 1] == '(') &&
                              (end == message.size() || message[end] == ' ' || message[end] == ':' || message[end] == ',' || message[end] == ')');
            if (!word) {
                at = end;
                continue;
            }
            message.replace(at, from.size(), python);
            at += std::string(python).size();
        }
    }
    return message;
}

}  // namespace

void raiseCurrent(bool scene) {
    std::string message;
    PyObject* type = scene ? sceneErrorType : errorType;
    try {
        throw;
    } catch (const Cancelled&) {
        PyErr_SetNone(PyExc_KeyboardInterrupt);
        throw py::error_already_set();
    } catch (const InputError& e) {
        message = e.what();
    } catch (const std::bad_alloc&) {
        PyErr_SetString(PyExc_MemoryError, "out of memory (try memory_budget= or fewer receivers)");
        throw py::error_already_set();
    } catch (const std::exception& e) {
        std::optional<std::string> library = libraryErrorMessage(e);
        message = library ? *library : std::string("internal error: ") + e.what();
        if (!library) type = errorType;
    }
    PyErr_SetString(type, withPythonNames(message).c_str());
    throw py::error_already_set();
}

/// Scene checks: InputError becomes SceneError.
template <class F>
auto sceneChecks(F&& f) -> decltype(f()) {
    return translateErrors(std::forward<F>(f), true);
}

void PyScene::reparse() {
    desc = sceneChecks([&] { return parseScene(document, file); });
    desc.outputFromScene = false;  // a Python caller names its outputs itself (write(path))
}

void PyScene::addGeometry(const std::string& type, nlohmann::json params) {
    nlohmann::json entry = std::move(params);
    entry["type"] = type;
    nlohmann::json next = document;
    if (!next.contains("geometry")) next["geometry"] = nlohmann::json::array();
    if (!next["geometry"].is_array()) sceneChecks([&] { fail(file + ": geometry", "expected an array of geometry entries"); });
    next["geometry"].push_back(entry);
    SceneDesc parsed = sceneChecks([&] { return parseScene(next, file); });
    const GeometryDesc& g = parsed.geometry.back();
    sceneChecks([&] { openSource(g.type, SourceRequest{g.params, parsed.file, g.path, parsed.baseDir}); });
    document = std::move(next);
    desc = std::move(parsed);
    desc.outputFromScene = false;
}

std::string PyScene::nextGeometryKey() const {
    const auto geometry = document.find("geometry");
    return fmt::format("geometry[{}]", geometry != document.end() && geometry->is_array() ? geometry->size() : 0);
}

void PyScene::addSource(py::object source, bool alpha, std::optional<bool> closed, std::optional<uint64_t> count) {
    std::shared_ptr<SourceSpec> spec = addSourceSpec(std::move(source), alpha, count);
    nlohmann::json entry = {{"type", "python"}, {"source", spec->id}, {"alpha", alpha}};
    if (closed) entry["closed"] = *closed;
    if (!document.contains("geometry")) document["geometry"] = nlohmann::json::array();
    document["geometry"].push_back(entry);
    sources.push_back(std::move(spec));
    reparse();
}

void PyScene::setPoints(py::handle positions, py::handle normals) {
    points = addPointsSpec(positions, normals);
    document["receivers"] = {{"type", "python-points"}, {"source", points->id}};
    reparse();
}

std::shared_ptr<PyScene> makeScene(nlohmann::json document, const std::string& baseDir,
                                   const std::optional<py::tuple>& points) {
    auto s = std::make_shared<PyScene>();
    s->document = std::move(document);
    s->file = (std::filesystem::path(baseDir) / "<dict>").lexically_normal().string();
    if (!s->document.is_object()) sceneChecks([&] { fail(s->file, "expected a JSON object"); });
    if (!s->document.contains("geometry")) s->document["geometry"] = nlohmann::json::array();
    if (points) {
        if (points->size() != 2) throw py::value_error("points: expected (positions, normals)");
        s->setPoints((*points)[0], (*points)[1]);
    } else {
        s->reparse();
    }
    return s;
}

std::shared_ptr<PyScene> loadPyScene(const std::string& path) {
    auto s = std::make_shared<PyScene>();
    s->file = path;
    s->document = sceneChecks([&] { return readJsonFile(path); });
    s->reparse();
    return s;
}

py::array PyResult::lightVisibility(py::object self) {
    const ReceiverResults& r = capture->results;
    const py::ssize_t n = py::ssize_t(size()), l = r.lights;
    return readOnly(py::array_t<float>({n, l}, l > 1 ? r.lightVisibility.data() : r.visibility.data(), self));
}

py::array PyResult::lightIrradiance(py::object self) {
    const ReceiverResults& r = capture->results;
    const py::ssize_t n = py::ssize_t(size()), l = r.lights;
    const glm::vec3* data = l > 1 ? r.lightIrradiance.data() : r.irradiance.data();
    return readOnly(py::array_t<float>({n, l, py::ssize_t(3)}, &data->x, self));
}

py::object PyResult::masks() {
    if (masksCache) return *masksCache;
    if (capture->masks.words.empty() && size() > 0) return py::none();
    auto* words = new std::vector<uint64_t>(capture->masks.toDumpLayout(capture->samples));
    py::capsule owner(words, [](void* p) { delete static_cast<std::vector<uint64_t>*>(p); });
    const py::ssize_t perReceiver = (capture->samples.sampleCount + 63) / 64;
    masksCache = readOnly(py::array_t<uint64_t>({py::ssize_t(size()), perReceiver}, words->data(), owner));
    return *masksCache;
}

py::object PyResult::imageShape() const {
    const nlohmann::json& r = desc.receivers;
    if (r.value("type", "") != "camera") return py::none();
    return py::make_tuple(r.at("height").get<int64_t>(), r.at("width").get<int64_t>());
}

py::array PyResult::image(const std::string& values) const {
    py::object shape = imageShape();
    if (shape.is_none()) throw py::value_error("image(): the receivers are not a camera");
    const auto h = shape.cast<py::tuple>()[0].cast<py::ssize_t>(), w = shape.cast<py::tuple>()[1].cast<py::ssize_t>();
    const int channels = values == "visibility" ? 1 : values == "irradiance" ? 3 : 0;
    if (!channels) throw py::value_error("image(): values must be \"visibility\" or \"irradiance\"");
    std::vector<py::ssize_t> dims = {h, w};
    if (channels == 3) dims.push_back(3);
    py::array_t<float> out(dims);
    float* p = out.mutable_data();
    std::fill(p, p + h * w * channels, NAN);
    const ReceiverSet& rs = capture->receivers;
    const ReceiverResults& res = capture->results;
    const size_t pixels = size_t(h) * size_t(w), first = std::min(capture->firstPass, rs.pixel.size());
    // Deeper layers' receivers (pixel >= W * H) are left out: the image is the nearest surface,
    // as the EXR's first layer and the preview are.
    for (size_t i = 0; i < first; ++i) {
        const size_t px = rs.pixel[i];
        if (px >= pixels) continue;
        if (channels == 1) p[px] = res.visibility[i];
        else for (int c = 0; c < 3; ++c) p[3 * px + c] = res.irradiance[i][c];
    }
    // An antialiased pixel holds the mean of its sub-pixel receivers (consecutive, one pixel
    // each), summed in double in receiver order, exactly as the EXR writes it (CameraOutput.cpp).
    for (size_t begin = first, end; begin < rs.pixel.size(); begin = end) {
        const size_t px = rs.pixel[begin];
        double v = 0;
        glm::dvec3 e(0.0);
        for (end = begin; end < rs.pixel.size() && rs.pixel[end] == px; ++end)
            v += res.visibility[end], e += glm::dvec3(res.irradiance[end]);
        if (px >= pixels) continue;
        const double count = double(end - begin);
        if (channels == 1) p[px] = float(v / count);
        else for (int c = 0; c < 3; ++c) p[3 * px + c] = glm::vec3(e / count)[c];
    }
    return out;
}

void PyResult::write(const std::string& path) const {
    // Named temporaries (PENUMBRA_NO_TMPFILE, or a file system without O_TMPFILE) are removed by
    // a SIGTERM that would end the interpreter anyway, as the CLI removes them.
    const ScopedSignalCleanup cleanup;
    // On a thread of its own, as a bake: Ctrl-C stops a camera's write between strips, and no
    // file is left (a 10 s EXR write ran to its end, then raised).
    InsideSource::refuse("Result.write()");
    // As the CLI's -o: never over a file the bake read (a points file, the glTF a vertices bake copies).
    translateErrors([&] { checkOutputAgainstInputs(desc, path); });
    runInterruptibly([&] { writeCapturedOutputs(desc, *capture, path); }, py::none());
}

namespace {

/// The callback's view of the phase running now.
void reportProgress(const py::object& progress);

/// Starts @p body on a thread of its own. No thread to be had, most often because an address-space
/// limit leaves no room for its stack, raises penumbra.Error saying so, not a bare RuntimeError.
std::thread startBakeThread(std::function<void()> body) {
    try {
        return std::thread(std::move(body));
    } catch (const std::system_error& e) {
        const uint64_t limit = addressSpaceLimit();
        const InputError refusal(limit ? fmt::format("the address-space limit (prlimit --as, ulimit -v) of {} leaves no room "
                                                     "for the bake's thread and its stack ({})",
                                                     formatBytes(limit), e.what())
                                       : fmt::format("cannot start the bake's thread: {}", e.what()));
        return translateErrors([&]() -> std::thread { throw refusal; });
    }
}

}  // namespace

void runInterruptibly(const std::function<void()>& work, const py::object& progress) {
    std::mutex mutex;
    std::condition_variable finishedChanged;
    bool finished = false;
    std::exception_ptr error;
    // A caller waits for another's bake to end: until its own starts, its callback and Ctrl-C
    // are its own business, and cancel only its wait (they cancelled the other's bake).
    std::atomic<bool> started{false}, abandoned{false};
    // Under an address-space limit the bake keeps one malloc arena (fitAddressSpace()), but that
    // comes too late for a thread of its own: its first allocation would reserve an arena (64 MiB
    // of address space) before the plan looks, and the minimum a refusal names then grew with the
    // limit given (sweep P at stop 63).
    if (addressSpaceLimit() != 0) useOneMallocArena();
    std::thread worker = startBakeThread([&] {
        try {
            std::unique_lock one(bakeMutex, std::defer_lock);
            while (!one.try_lock_for(std::chrono::milliseconds(20)))
                if (abandoned) break;
            if (one.owns_lock()) {
                clearCancel();
                started = true;
                if (!abandoned) work();
            }
        } catch (...) {
            error = std::current_exception();
        }
        std::lock_guard lock(mutex);
        finished = true;
        finishedChanged.notify_all();
    });
    // Whatever unwinds this frame (a daemon thread that finalization ends, in the callback or as
    // it takes the GIL back) stops the worker first: it uses this frame's locals, and a joinable
    // std::thread destroyed aborts the process.
    // The order (abandoned, then started; the worker the other way) leaves no gap: a worker that
    // missed the abandoning is seen as started, and its bake is cancelled.
    auto cancelOwn = [&] {
        abandoned = true;
        if (started) requestCancel();
    };
    struct StopOnUnwind {
        std::thread& worker;
        const std::function<void()> cancel;
        ~StopOnUnwind() {
            if (!worker.joinable()) return;
            cancel();
            worker.join();
        }
    } stopWorker{worker, cancelOwn};
    // This thread keeps the GIL only to check for signals and to call the callback; a Python
    // source on the bake's reader thread takes it in between.
    std::optional<py::error_already_set> interrupted;
    for (;;) {
        // Not py::gil_scoped_release: taking the GIL back while the interpreter finalizes ends a
        // daemon thread (pthread_exit), and in that guard's noexcept destructor the unwinding
        // aborted the process ("terminate called without an active exception"). Here it unwinds
        // this frame, and stopWorker stops the worker first.
        PyThreadState* state = PyEval_SaveThread();
        bool done = false;
        {
            std::unique_lock lock(mutex);
            done = finishedChanged.wait_for(lock, kPollInterval, [&] { return finished; });
        }
        PyEval_RestoreThread(state);
        if (done) break;
        if (interrupted) continue;
        try {
            if (PyErr_CheckSignals() != 0) throw py::error_already_set();
            if (!progress.is_none() && started) reportProgress(progress);  // not another caller's phase
        } catch (py::error_already_set& e) {  // Ctrl-C, or the callback raised: the work stops
            interrupted.emplace(std::move(e));
            cancelOwn();
        }
    }
    if (worker.joinable()) {
        py::gil_scoped_release release;
        worker.join();
    }
    if (interrupted) throw std::move(*interrupted);
    if (error) translateErrors([&] { std::rethrow_exception(error); });
}

namespace {

/// The callback's view of the phase running now.
void reportProgress(const py::object& progress) {
    std::optional<ProgressSnapshot> s = currentProgress();
    if (!s) return;
    py::object fraction = py::none(), eta = py::none();
    if (s->total) {  // the terminal display's share and ETA (ProgressEstimate.h)
        fraction = py::float_(s->fraction);
        if (s->remainingSeconds) eta = py::float_(*s->remainingSeconds);
    }
    progress(s->phase, fraction, eta);
}

BakeSettings settingsOf(const std::string& method, std::optional<int> threads, const py::object& memoryBudget,
                        const std::optional<std::string>& tmpDir) {
    BakeSettings settings;
    // Wrong argument values are ValueErrors named as the arguments are, not as the CLI's options.
    try {
        settings.method = casterEntry(method).name;
    } catch (const InputError& e) {
        std::string text = e.what();
        if (text.rfind("--method: ", 0) == 0) text = "method: " + text.substr(10);
        throw py::value_error(text);
    }
    settings.threads = threads.value_or(0);
    if (settings.threads < 0 || settings.threads > kMaxThreads)
        throw py::value_error(fmt::format("threads: must be in 0..{} (0 or None: all cores), got {}", kMaxThreads, settings.threads));
    settings.quiet = true;
    if (!memoryBudget.is_none()) {
        if (py::isinstance<py::str>(memoryBudget)) {
            // A malformed size is a wrong value, as a wrong int is: ValueError, not penumbra.Error.
            try {
                settings.memoryBudget = parseByteSize(memoryBudget.cast<std::string>(), "memory_budget");
            } catch (const InputError& e) {
                throw py::value_error(e.what());
            }
        } else {
            // An int of bytes; anything else (a negative or float count, a list) is named here,
            // not as pybind11's "Unable to cast Python instance to C++ type".
            const py::int_ whole = py::isinstance<py::int_>(memoryBudget) && !py::isinstance<py::bool_>(memoryBudget)
                                       ? py::reinterpret_borrow<py::int_>(memoryBudget) : py::int_(-1);
            if (whole < py::int_(0) || whole > py::int_(INT64_MAX))
                throw py::value_error(fmt::format("memory_budget: expected bytes as a non-negative int or a size such as '512M', got {}",
                                                  std::string(py::repr(memoryBudget))));
            settings.memoryBudget = whole.cast<uint64_t>();
        }
        if (settings.memoryBudget == 0) throw py::value_error("memory_budget: must be more than 0 (None for no budget)");
    }
    settings.tmpDir = tmpDir.value_or("");
    return settings;
}

}  // namespace

namespace {

/// The threads argument: None or an int. A bool is an int to Python, and threads=True ran one
/// thread; it is refused as the wrong type, as a scene's "width": true is.
std::optional<int> threadsArgument(const py::object& threads) {
    if (threads.is_none()) return std::nullopt;
    if (py::isinstance<py::bool_>(threads) || !py::isinstance<py::int_>(threads))
        throw py::type_error(fmt::format("threads: expected an int or None, got {}", std::string(py::str(threads.get_type().attr("__name__")))));
    return threads.cast<int>();
}

}  // namespace

std::shared_ptr<PyResult> bake(std::shared_ptr<PyScene> scene, const std::string& method, const py::object& threadsArg,
                               py::object memoryBudget, py::object progress, std::optional<std::string> tmpDir, bool masks,
                               std::optional<std::string> output) {
    InsideSource::refuse("penumbra.bake()");
    const std::optional<int> threads = threadsArgument(threadsArg);
    auto result = std::make_shared<PyResult>();
    result->scene = scene;
    result->desc = scene->desc;
    if (output) result->desc.output = *output;  // kinds that name their files when made (vertices)
    result->capture = std::make_shared<BakeCapture>();
    BakeSettings settings = settingsOf(method, threads, memoryBudget, tmpDir);
    result->capture->wantMasks = masks && casterEntry(settings.method).traits.masks;
    settings.capture = result->capture.get();

    const ScopedSignalCleanup cleanup;  // scratch and bucket files named for a moment (see write())
    runInterruptibly([&] { result->stats = runBake(result->desc, settings); }, progress);
    if (!progress.is_none()) progress("done", py::float_(1.0), py::float_(0.0));
    return result;
}

}  // namespace penumbra::python
