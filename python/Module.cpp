/// @file Module.cpp
/// @brief The `penumbra` Python module: scenes from JSON, dicts and Python triangle sources,
/// bakes run by the same pipeline as the CLI (bake/Pipeline.h), results as NumPy arrays.

#include "python/BakeRun.h"
#include "python/PythonSources.h"

#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "bake/cast/Caster.h"
#include "procedural/Generators.h"
#include "stream/util/CheckedMath.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

namespace py = pybind11;
using namespace penumbra;
using namespace penumbra::python;

namespace {


/// (n, 3, 3) float32 triangles and their (n,) uint32 flags from a chunk.
py::tuple chunkArrays(const std::vector<Triangle>& chunk, size_t n) {
    py::array_t<float> tris({py::ssize_t(n), py::ssize_t(3), py::ssize_t(3)});
    py::array_t<uint32_t> flags{py::ssize_t(n)};
    float* t = tris.mutable_data();
    uint32_t* f = flags.mutable_data();
    for (size_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) t[9 * i + 3 * k] = chunk[i].v[k].x, t[9 * i + 3 * k + 1] = chunk[i].v[k].y, t[9 * i + 3 * k + 2] = chunk[i].v[k].z;
        f[i] = chunk[i].flags;
    }
    return py::make_tuple(tris, flags);
}

/// Triangles per chunk that generate() hands out at most: 2^24 (a 1.5 GB buffer with flags).
constexpr size_t kMaxGenerateChunk = size_t(1) << 24;

/// A whole-number argument in 0..@p max, or nothing for None; pybind's own conversion answered
/// -1 or 1.5 with a dump of every signature.
/// @throw TypeError or ValueError naming @p function and @p name.
std::optional<uint64_t> countArgument(const py::object& value, const char* function, const char* name, uint64_t max) {
    if (value.is_none()) return std::nullopt;
    if (!py::isinstance<py::int_>(value) || py::isinstance<py::bool_>(value))
        throw py::type_error(fmt::format("{}(): {} must be an integer, got {}", function, name,
                                         std::string(py::str(py::type::of(value).attr("__name__")))));
    const py::int_ number = py::reinterpret_borrow<py::int_>(value);
    if (number < py::int_(0) || number > py::int_(max))
        throw py::value_error(fmt::format("{}(): {} must be in 0..{}, got {}", function, name, max, std::string(py::str(value))));
    return number.cast<uint64_t>();
}

/// generate()'s chunk size: 0 is the bake's own (the range is checked by countArgument()).
size_t chunkOrDefault(size_t chunk) { return chunk ? chunk : kTriangleChunk; }

/// `penumbra.generate(scene)`: the scene's triangles, chunk by chunk, as a bake streams them.
class GenerateIterator {
public:
    GenerateIterator(std::shared_ptr<PyScene> scene, size_t chunk, bool flags)
        : scene_(std::move(scene)), chunk_(chunkOrDefault(chunk)), flags_(flags) {
        source_ = translateErrors([&] { return openSceneGeometry(scene_->desc); });
    }
    py::object next() {
        size_t n = 0;
        translateErrors([&] {
            py::gil_scoped_release release;  // a Python source takes it back for its own calls
            n = source_->read(buffer_);
        });
        if (n == 0) throw py::stop_iteration();
        py::tuple arrays = chunkArrays(buffer_, n);
        return flags_ ? py::object(arrays) : arrays[0];
    }
    ~GenerateIterator() {
        py::gil_scoped_release release;
        source_.reset();
    }

private:
    std::shared_ptr<PyScene> scene_;
    size_t chunk_;
    bool flags_;
    TriangleSourcePtr source_;
    std::vector<Triangle> buffer_ = std::vector<Triangle>(chunk_);
};

template <class T>
py::array view(const std::vector<T>& data, std::vector<py::ssize_t> shape, py::handle owner) {
    return readOnly(py::array_t<T>(shape, data.data(), owner));
}
py::array floats(const float* data, std::vector<py::ssize_t> shape, py::handle owner) {
    return readOnly(py::array_t<float>(shape, data, owner));
}

void bindScene(py::module_& m) {
    py::class_<PyScene, std::shared_ptr<PyScene>>(m, "Scene", R"doc(A scene: geometry, lights, receivers, output, bake options.

Scene(dict, points=None, base_dir=".") takes the keys of the JSON scene format
(docs/scene-format.md) with the same validation; points=(positions, normals) gives
(N, 3) receiver arrays instead of a "receivers" entry. Raises SceneError naming the key.)doc")
        .def(py::init([](py::dict d, std::optional<py::tuple> points, std::string baseDir) {
                 return makeScene(toJson(d, "<dict>"), baseDir, points);
             }),
             py::arg("scene"), py::arg("points") = py::none(), py::arg("base_dir") = ".")
        .def_static("from_json", [](const std::string& path) { return loadPyScene(path); }, py::arg("path"),
                    "Reads a scene file; relative paths in it are relative to its folder.")
        .def("add_geometry", [](PyScene& s, const std::string& type, py::kwargs params) {
                 s.addGeometry(type, toJson(params, s.file, s.nextGeometryKey()));
             },
             py::arg("type"),
             "add_geometry(type, transform=None, closed=None, **params): a file (obj, gltf, glb, ptri, file) or a "
             "generator (grid, terrain, grass, tree, forest, flowers, scatter, boxes, colonnade) with its parameters, "
             "and the per-object controls cast_shadows, receive_shadows, receiver_offset and max_distance.")
        .def("add_source",
             [](PyScene& s, py::object source, bool alpha, std::optional<bool> closed, py::object count) {
                 s.addSource(std::move(source), alpha, closed, countArgument(count, "add_source", "count", kMaxSceneTriangles));
             },
             py::arg("source"), py::arg("alpha") = false,
             py::arg("closed") = py::none(), py::arg("count") = py::none(),
             R"doc(Streams triangles from Python.

source: a callable returning an iterable of chunks (called once per pass), a re-iterable
(iterated once per pass), or a one-shot iterator/generator (copied once to an unnamed
scratch file during the first pass and replayed from it). Each chunk is a float32 NumPy
array of shape (n, 3, 3) or (n, 9). alpha marks every triangle alpha-matte; closed marks
it part of closed solids; count (triangles per pass) gives progress a percentage.)doc")
        .def("set_points", [](PyScene& s, py::handle p, py::handle n) { s.setPoints(p, n); }, py::arg("positions"), py::arg("normals"),
             "Receivers at (N, 3) positions with (N, 3) normals, instead of the scene's receivers.")
        .def("to_dict", [](const PyScene& s) { return toPython(s.document); }, "The scene as a JSON-style dict.")
        .def_property_readonly("output", [](const PyScene& s) { return s.desc.output; })
        .def("__repr__", [](const PyScene& s) {
            return fmt::format("<penumbra.Scene {} geometry entries, {} lights, receivers {}>", s.desc.geometry.size(),
                               s.desc.lights.size(), s.desc.receivers.value("type", "?"));
        });

}

/// generate(), bake() and methods().
void bindFunctions(py::module_& m) {
    py::class_<GenerateIterator, std::shared_ptr<GenerateIterator>>(m, "_Generate")
        .def("__iter__", [](py::object self) { return self; })
        .def("__next__", &GenerateIterator::next);
    m.def("generate", [](std::shared_ptr<PyScene> scene, py::object chunk, bool flags) {
              InsideSource::refuse("penumbra.generate()");
              const uint64_t size = countArgument(chunk, "generate", "chunk", kMaxGenerateChunk).value_or(0);
              return std::make_shared<GenerateIterator>(std::move(scene), size_t(size), flags);
          },
          py::arg("scene").none(false), py::arg("chunk") = kTriangleChunk, py::arg("flags") = false,
          "Yields the scene's triangles as (n, 3, 3) float32 chunks, exactly as a bake streams them (transforms "
          "applied, scene order); with flags=True, (triangles, flags) pairs.");

    m.def("bake", &bake, py::arg("scene").none(false), py::arg("method") = "hpc", py::arg("threads") = py::none(),
          py::arg("memory_budget") = py::none(), py::arg("progress") = py::none(), py::arg("tmp_dir") = py::none(),
          py::arg("masks") = true, py::arg("output") = py::none(),
          R"doc(Bakes the scene with the CLI's pipeline and returns a Result.

method: a registered method ("hpc", "reference", "embree", ...); threads: workers (None: all
cores); memory_budget: bytes or a string such as "2G"; progress(phase, fraction, eta_s) is
called from the calling thread about ten times a second (fraction and eta_s may be None);
tmp_dir: where bucket files go; output: the output path for receiver kinds that name their
files when the bake starts (vertices: write() cannot move them), else write(path) says. The GIL is released while the bake runs; Ctrl-C
(KeyboardInterrupt) cancels it, leaving no temp file or output behind.)doc");
    m.def("methods", [] { return casterNames(); }, "The registered bake methods.");
}

void bindResult(py::module_& m) {
    py::class_<PyResult, std::shared_ptr<PyResult>>(m, "Result", "The results of penumbra.bake().")
        .def_property_readonly("visibility", [](py::object self) {
            auto& r = self.cast<PyResult&>();
            return view(r.capture->results.visibility, {py::ssize_t(r.size())}, self);
        }, "(N,) float32: unblocked light samples / all samples, all lights together.")
        .def_property_readonly("irradiance", [](py::object self) {
            auto& r = self.cast<PyResult&>();
            return floats(&r.capture->results.irradiance.data()->x, {py::ssize_t(r.size()), 3}, self);
        }, "(N, 3) float32 RGB irradiance, all lights summed.")
        .def_property_readonly("light_visibility", [](py::object self) { return self.cast<PyResult&>().lightVisibility(self); },
                               "(N, lights) float32, each light's visible fraction.")
        .def_property_readonly("light_irradiance", [](py::object self) { return self.cast<PyResult&>().lightIrradiance(self); },
                               "(N, lights, 3) float32, each light's irradiance.")
        .def_property_readonly("masks", &PyResult::masks,
                               "(N, ceil(K/64)) uint64: bit k%64 of word k/64 set when light sample k is blocked (masks.npy).")
        .def_property_readonly("positions", [](py::object self) {
            auto& r = self.cast<PyResult&>();
            return floats(&r.capture->receivers.position.data()->x, {py::ssize_t(r.size()), 3}, self);
        }, "(N, 3) float32 receiver positions.")
        .def_property_readonly("normals", [](py::object self) {
            auto& r = self.cast<PyResult&>();
            return floats(&r.capture->receivers.normal.data()->x, {py::ssize_t(r.size()), 3}, self);
        }, "(N, 3) float32 receiver normals.")
        .def_property_readonly("pixels", [](py::object self) {
            auto& r = self.cast<PyResult&>();
            return view(r.capture->receivers.pixel, {py::ssize_t(r.capture->receivers.pixel.size())}, self);
        }, "(N,) uint32 pixel index y * width + x of camera receivers (empty otherwise).")
        .def_property_readonly("image_shape", &PyResult::imageShape, "(H, W) of a camera, else None.")
        .def("image", &PyResult::image, py::arg("values") = "visibility",
             "A camera's (H, W) visibility or (H, W, 3) irradiance (values='irradiance') of the nearest surface, "
             "as the EXR holds them: an antialiased pixel is the mean of its sub-pixel receivers; NaN where no "
             "surface is seen.")
        .def_property_readonly("stats", [](const PyResult& r) { return toPython(r.stats); }, "The bake's stats, as --stats writes them.")
        .def_property_readonly("samples", [](const PyResult& r) { return r.capture->samples.sampleCount; }, "Light samples K.")
        .def("write", &PyResult::write, py::arg("path"),
             "Writes the outputs the CLI writes for this scene to path (EXR + PNG for a camera, .npy for points, "
             "lightmap glTF, ...), byte for byte; all or none.")
        .def("__len__", [](const PyResult& r) { return r.size(); });  // a reference: Result.__len__(None) is a TypeError

}

}  // namespace


PYBIND11_MODULE(_penumbra, m) {
    m.doc() = "Out-of-core soft-shadow baking (penumbra), driven from Python.";
    registerFileSourceTypes();
    registerProceduralGenerators();
    registerPythonSources();
    registerExceptions(m);

    bindScene(m);
    bindResult(m);
    bindFunctions(m);
}
