#pragma once
/// @file BakeRun.h
/// @brief The Python module's scene, bake and result types (Module.cpp binds them).

#include "python/PythonSources.h"

#include "bake/BakeCapture.h"
#include "bake/Scene.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace penumbra::python {

/// @brief @p a with NumPy's WRITEABLE flag cleared: the arrays of a Result are views of the
/// bake's buffers, which write() reads (scaling one in place changed the files it wrote).
inline pybind11::array readOnly(pybind11::array a) {
    pybind11::detail::array_proxy(a.ptr())->flags &= ~pybind11::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    return a;
}

/// JSON through Python's json module (dicts of plain values, both ways).
pybind11::object toPython(const nlohmann::json& j);
/// @brief @p o (a dict of the scene format) as JSON.
/// @param where what the message of a bad value starts with (the scene's name, "<dict>")
/// @param path the key @p o sits at ("geometry[2]" for add_geometry()'s parameters; "": the top)
/// @throw SceneError naming the key of a value JSON cannot hold (NaN, inf, a non-string key)
nlohmann::json toJson(pybind11::handle o, const std::string& where, const std::string& path = "");

/// @brief A scene as the JSON document it is, parsed again (with every check) after each change.
struct PyScene {
    nlohmann::json document;
    std::string file;  ///< for messages and relative paths: the scene file, or BASE/<dict>
    SceneDesc desc;
    std::vector<std::shared_ptr<SourceSpec>> sources;  ///< keeps add_source() objects alive
    std::shared_ptr<PointsSpec> points;

    /// @brief Appends {"type": type, ...params} to "geometry" and opens it once to check it.
    /// @throw SceneError naming the key.
    void addGeometry(const std::string& type, nlohmann::json params);
    /// The key the next add_geometry() entry will have, for messages: "geometry[N]".
    std::string nextGeometryKey() const;
    /// @brief Appends a Python source (PythonSources.h).
    void addSource(pybind11::object source, bool alpha, std::optional<bool> closed, std::optional<uint64_t> count);
    /// @brief Receivers from arrays, replacing the scene's "receivers".
    void setPoints(pybind11::handle positions, pybind11::handle normals);
    /// @brief parseScene() of the document. @throw SceneError.
    void reparse();
};

std::shared_ptr<PyScene> makeScene(nlohmann::json document, const std::string& baseDir,
                                   const std::optional<pybind11::tuple>& points);
std::shared_ptr<PyScene> loadPyScene(const std::string& path);

/// @brief A finished bake: what the pipeline captured, and the scene to write its outputs for.
struct PyResult {
    std::shared_ptr<PyScene> scene;  ///< keeps the scene's Python sources alive
    SceneDesc desc;                  ///< the scene as baked (with bake()'s output)
    std::shared_ptr<BakeCapture> capture;
    nlohmann::json stats;
    std::optional<pybind11::array> masksCache;

    size_t size() const { return capture->receivers.size(); }
    pybind11::array lightVisibility(pybind11::object self);
    pybind11::array lightIrradiance(pybind11::object self);
    pybind11::object masks();
    pybind11::object imageShape() const;
    pybind11::array image(const std::string& values) const;
    void write(const std::string& path) const;
};

/// @brief Runs @p work on a thread of its own while this (the caller's) thread checks for signals
/// and calls @p progress (None: no callback) about ten times a second; Ctrl-C or a raising
/// callback cancels the work (requestCancel()) and is raised once it has stopped. GIL held.
void runInterruptibly(const std::function<void()>& work, const pybind11::object& progress);

/// @brief penumbra.bake(): runBake on a thread of its own while this (the caller's) thread
/// polls progress, calls the callback and watches for KeyboardInterrupt.
std::shared_ptr<PyResult> bake(std::shared_ptr<PyScene> scene, const std::string& method, const pybind11::object& threads,
                               pybind11::object memoryBudget, pybind11::object progress, std::optional<std::string> tmpDir,
                               bool masks, std::optional<std::string> output);

/// @brief penumbra.Error (RuntimeError) and penumbra.SceneError (Error, ValueError).
void registerExceptions(pybind11::module_& m);

/// @brief Runs @p f, turning InputError into penumbra.Error (SceneError when @p scene) and library
/// errors into their messages; Python exceptions pass through.
template <class F>
auto translateErrors(F&& f, bool scene = false) -> decltype(f());
/// @brief Raises penumbra.Error (or SceneError when @p scene) for the current C++ exception.
[[noreturn]] void raiseCurrent(bool scene);

template <class F>
auto translateErrors(F&& f, bool scene) -> decltype(f()) {
    try {
        return f();
    } catch (pybind11::error_already_set&) {
        throw;
    } catch (pybind11::builtin_exception&) {
        throw;
    } catch (...) {
        raiseCurrent(scene);
    }
}

}  // namespace penumbra::python
