#pragma once
/// @file PythonSources.h
/// @brief Geometry and receivers that live in the Python process: the "python" geometry type
/// (triangle chunks from a callable or an iterable) and the "python-points" receiver kind (NumPy
/// positions and normals). Scene entries name them by id ({"type": "python", "source": 3}); the
/// objects stay in a table while a Scene holds them.

#include "receivers/ReceiverSet.h"

#include <pybind11/pybind11.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

namespace penumbra::python {

/// @brief A Python triangle source as add_source() received it.
struct SourceSpec {
    pybind11::object object;        ///< callable, re-iterable, or a one-shot iterator
    bool alpha = false;             ///< every triangle is alpha-matte (kTriangleAlphaMatte)
    std::optional<uint64_t> count;  ///< triangles per pass when the caller knows (progress, disk plan)
    int64_t id = 0;
    /// A one-shot iterator that a bake or generate() began to read: it cannot give its triangles
    /// again (a second bake of the scene saw none, silently). GIL held.
    bool consumed = false;
};

/// @brief Marks the thread as inside a Python source's call while alive: a bake() or generate()
/// that the source starts there is refused (it would wait for the bake that calls the source).
struct InsideSource {
    static inline thread_local int depth = 0;
    InsideSource() { ++depth; }
    ~InsideSource() { --depth; }
    InsideSource(const InsideSource&) = delete;
    InsideSource& operator=(const InsideSource&) = delete;

    /// @brief Refuses @p call (`penumbra.bake()`, ...) on a thread inside a source's call.
    /// @throw pybind11::value_error naming it: it would wait forever for the bake that called the source.
    static void refuse(const char* call) {
        if (depth > 0)
            throw pybind11::value_error(std::string(call) + " was called from inside a source of a running bake, which it "
                                        "would wait for forever; call it after the bake returns");
    }
};

/// @brief Receiver points copied from NumPy when the scene was given them.
struct PointsSpec {
    ReceiverSet receivers;
    int64_t id = 0;
};

/// @brief Keeps @p spec reachable under its id while the returned pointer lives. GIL held.
std::shared_ptr<SourceSpec> addSourceSpec(pybind11::object object, bool alpha, std::optional<uint64_t> count);
/// @brief Same for receiver points: (N, 3) positions and normals, float32 or float64.
/// @throw ValueError naming the array when shapes differ or a value is not finite.
std::shared_ptr<PointsSpec> addPointsSpec(pybind11::handle positions, pybind11::handle normals);

/// @brief Registers the "python" geometry type and the "python-points" receiver kind. Idempotent.
void registerPythonSources();

}  // namespace penumbra::python
