"""Bad input raises the CLI's messages as Python exceptions naming the key or the chunk; Ctrl-C
cancels leaving nothing behind; threads in sources and callbacks never deadlock."""
import _thread
import faulthandler
import json
import os
import pathlib
import signal
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import penumbra
from test_bake import grid_scene, without_geometry

faulthandler.dump_traceback_later(600, exit=True)  # a deadlock fails the run instead of hanging it


def test_bad_key_raises_scene_error_naming_it():
    scene = grid_scene()
    scene["lights"][0]["samplez"] = 3
    with pytest.raises(penumbra.SceneError, match=r"lights\[0\]\.samplez"):
        penumbra.Scene(scene)
    with pytest.raises(penumbra.SceneError, match="receivers"):
        penumbra.Scene({"geometry": [], "lights": grid_scene()["lights"]})
    with pytest.raises(ValueError):  # SceneError is a ValueError too
        penumbra.Scene(dict(scene, lights=[]))


def test_a_value_json_cannot_hold_is_named_by_its_key():
    # json.dumps wrote NaN as a bare word, refused at a column of a text the caller never saw.
    for value in (float("nan"), float("inf"), -float("inf")):
        scene = grid_scene()
        scene["lights"][0]["radiance"] = [1, value, 1]
        with pytest.raises(penumbra.SceneError, match=r"<dict>: lights\[0\]\.radiance\[1\]: -?(nan|inf) is not a finite number"):
            penumbra.Scene(scene)
    # Named as the entry's key, as a bad parameter of the same entry in a dict is (docs/python.md).
    with pytest.raises(penumbra.SceneError, match=r"<dict>: geometry\[0\]\.size: nan is not a finite number"):
        penumbra.Scene(without_geometry(grid_scene())).add_geometry("grid", size=float("nan"))
    # NumPy scalars and arrays are their Python values.
    scene = grid_scene()
    scene["lights"][0]["samples"] = np.int64(16)
    scene["lights"][0]["center"] = np.array(scene["lights"][0]["center"], np.float64)
    made = penumbra.Scene(scene)
    assert made.to_dict()["lights"][0]["samples"] == 16
    made.add_geometry("grid", cells=np.int32(4), size=np.float32(2))


def test_a_dict_that_holds_itself_or_nests_deep_is_a_scene_error():
    # Each overflowed the C stack converting to JSON: a segfault, not an exception.
    scene = grid_scene()
    scene["self"] = scene
    with pytest.raises(penumbra.SceneError, match=r"<dict>: self\.self.*nests deeper than 64 levels"):
        penumbra.Scene(scene)
    loop = []
    loop.append(loop)
    with pytest.raises(penumbra.SceneError, match="nests deeper than 64 levels"):
        penumbra.Scene(dict(grid_scene(), lights=loop))
    deep = inner = {}
    for _ in range(30_000):
        inner["a"] = {}
        inner = inner["a"]
    with pytest.raises(penumbra.SceneError, match="nests deeper than 64 levels"):
        penumbra.Scene(without_geometry(grid_scene())).add_geometry("grid", transform=deep)
    with pytest.raises(penumbra.SceneError, match="a value of type 'set' is not a JSON value"):
        penumbra.Scene(dict(grid_scene(), extra={1, 2}))


def test_sources_and_points_of_the_wrong_kind_name_what_is_wrong():
    scene = penumbra.Scene(without_geometry(grid_scene()))
    scene.add_source(lambda: 5)
    with pytest.raises(TypeError, match=r"geometry\[0\] \(add_source\): the source gave an object of type 'int'"):
        penumbra.bake(scene, threads=1)
    scene = penumbra.Scene(without_geometry(grid_scene()))
    scene.add_source([np.zeros(450, np.float32)])
    with pytest.raises(ValueError, match=r"got \(450,\)"):
        penumbra.bake(scene, threads=1)
    # Complex values lost their imaginary part and booleans became 0 and 1.
    for dtype in (np.complex64, bool):
        with pytest.raises(TypeError, match="points: positions must hold real numbers"):
            penumbra.Scene(grid_scene(), points=(np.zeros((2, 3), dtype), np.ones((2, 3))))


def test_none_for_a_scene_is_a_type_error():
    # A scene-building helper that forgot its return: bake(None) and generate(None) segfaulted.
    with pytest.raises(TypeError):
        penumbra.bake(None)
    with pytest.raises(TypeError):
        penumbra.generate(None)
    with pytest.raises(TypeError):
        penumbra.Result.__len__(None)


def test_bad_geometry_parameter_names_the_entry():
    scene = penumbra.Scene(without_geometry(grid_scene()))
    with pytest.raises(penumbra.SceneError, match=r"geometry\[0\]"):
        scene.add_geometry("grid", sizee=3)
    with pytest.raises(penumbra.SceneError, match="unknown"):
        scene.add_geometry("no-such-generator")
    scene.add_geometry("grid", size=2, cells=4, transform={"translate": [0, 0.1, 0]})
    assert len(scene.to_dict()["geometry"]) == 1


def bake_chunks(chunks):
    scene = penumbra.Scene(without_geometry(grid_scene()))
    scene.add_source(lambda: iter(chunks))
    return penumbra.bake(scene, threads=1)


def good():
    return np.array([[[-1, 0, -1], [1, 0, -1], [0, 0, 1]]], np.float32)


def test_wrong_dtype_or_shape_names_the_chunk():
    # The source is named by its scene entry (the first geometry entry here), not an internal id.
    with pytest.raises(TypeError, match=r"<dict>: geometry\[0\] \(add_source\) chunk 1: expected dtype float32, got float64"):
        bake_chunks([good(), good().astype(np.float64)])
    with pytest.raises(ValueError, match=r"chunk 2: expected shape \(n, 3, 3\) or \(n, 9\), got \(1, 4\)"):
        bake_chunks([good(), good(), np.zeros((1, 4), np.float32)])
    with pytest.raises(TypeError, match=r"chunk 0: expected a NumPy float32 array"):
        bake_chunks([[1, 2, 3]])
    with pytest.raises(TypeError):
        penumbra.Scene(grid_scene()).add_source(42)


def test_bad_budget_or_chunk_is_named_before_any_work():
    scene = penumbra.Scene(grid_scene())
    for budget in (-5, 1.5, True, [1], 2**70):
        with pytest.raises(ValueError, match=r"memory_budget: expected bytes as a non-negative int or a size such as '512M'"):
            penumbra.bake(scene, memory_budget=budget)
    # A wrong method or thread count is a ValueError named as the argument (it was a
    # penumbra.Error naming the CLI's --method and --threads).
    with pytest.raises(ValueError, match=r'^method: unknown method "foo" \(known: hpc'):
        penumbra.bake(scene, method="foo")
    for threads in (-3, 100000):
        with pytest.raises(ValueError, match=r"^threads: must be in 0\.\.4096"):
            penumbra.bake(scene, threads=threads)
    for budget in ("12Q", "lots"):  # a malformed size string too (it was a penumbra.Error)
        with pytest.raises(ValueError, match=r"memory_budget"):
            penumbra.bake(scene, memory_budget=budget)
    with pytest.raises(ValueError, match=r"generate\(\): chunk must be in 0..16777216, got 1099511627776"):
        penumbra.generate(scene, chunk=2**40)
    # pybind's own conversion answered these with a dump of every signature.
    with pytest.raises(ValueError, match=r"generate\(\): chunk must be in 0..16777216, got -1"):
        penumbra.generate(scene, chunk=-1)
    for count, error, text in ((-1, ValueError, r"count must be in 0..1099511627776, got -1"),
                               (2**62, ValueError, r"count must be in 0..1099511627776"),
                               (1.5, TypeError, r"count must be an integer, got float")):
        with pytest.raises(error, match=r"add_source\(\): " + text):
            scene.add_source(lambda: [good()], count=count)


def test_a_source_must_replay_what_it_gave_and_what_its_count_says():
    # A re-iterable that gave nothing in the scan pass and a roof in the bucket pass baked shadows
    # of a roof no camera pixel saw, without a word.
    class Changing:
        def __init__(self):
            self.calls = 0

        def __iter__(self):
            self.calls += 1
            return iter([] if self.calls == 1 else [good()])

    scene = penumbra.Scene(grid_scene())
    scene.add_source(Changing())
    with pytest.raises(penumbra.Error, match=r"gave 1 triangles on a later pass and 0 on the first"):
        penumbra.bake(scene, threads=1)
    counted = penumbra.Scene(grid_scene())
    counted.add_source(lambda: [good(), good()], count=5)
    with pytest.raises(penumbra.Error, match=r"gave 2 triangles in a pass, but its count is 5"):
        penumbra.bake(counted, threads=1)


def test_a_one_shot_iterator_read_by_an_earlier_bake_is_an_error():
    # The second bake (say embree after hpc) saw an exhausted generator: fewer triangles, exit 0.
    scene = penumbra.Scene(grid_scene())
    scene.add_source(c for c in [good(), good()])
    first = penumbra.bake(scene, threads=1)
    assert first.stats["stream"]["triangles"] > 2
    with pytest.raises(penumbra.Error, match=r"geometry\[1\] \(add_source\): is a one-shot iterator that an earlier bake"):
        penumbra.bake(scene, threads=1)
    with pytest.raises(penumbra.Error, match="one-shot iterator"):
        list(penumbra.generate(scene))


def test_nan_vertex_raises_as_the_cli_does():
    bad = good()
    bad[0, 1, 2] = np.nan
    with pytest.raises(penumbra.Error, match=r"<dict>: geometry\[0\] \(python\): triangle 1 has a non-finite \(NaN or infinite\) vertex"):
        bake_chunks([good(), bad])


def test_a_source_that_raises_passes_its_exception_through():
    def source():
        yield good()
        raise LookupError("from the generator")

    scene = penumbra.Scene(without_geometry(grid_scene()))
    scene.add_source(source)
    with pytest.raises(LookupError, match="from the generator"):
        penumbra.bake(scene)


def slow_scene(count=10_000):
    """A floor under many tiny blockers, produced slowly enough to be interrupted."""
    def source():
        yield np.array([[[-5, 0, -5], [5, 0, -5], [0, 0, 5]]], np.float32)
        rng = np.random.default_rng(1)
        for _ in range(count):
            time.sleep(0.002)
            yield (rng.random((64, 3, 3), dtype=np.float32) + [0, 1, 0]).astype(np.float32)
    scene = penumbra.Scene(without_geometry(grid_scene()))
    scene.add_source(source)
    return scene


def test_ctrl_c_cancels_and_leaves_no_temp_files(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    # A shell starts background jobs with SIGINT ignored, and then interrupt_main() does nothing:
    # Ctrl-C's own handler, for this test, whatever started the suite.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        timer = threading.Timer(0.5, _thread.interrupt_main)
        timer.start()
        started = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            penumbra.bake(slow_scene(), tmp_dir=str(tmp))
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert time.monotonic() - started < 15
    assert os.listdir(tmp) == []
    # The next bake is not cancelled.
    assert len(penumbra.bake(penumbra.Scene(grid_scene()), tmp_dir=str(tmp), threads=1)) > 0


def test_ctrl_c_stops_a_slow_source_between_its_items():
    # Ctrl-C was seen only once the source had filled a whole chunk: thousands more calls of a
    # source giving a triangle a few times a second.
    interrupted_at = []
    calls = []

    def source():
        yield np.array([[[-5, 0, -5], [5, 0, -5], [0, 0, 5]]], np.float32)
        for _ in range(100_000):
            calls.append(time.monotonic())
            time.sleep(0.005)
            yield np.array([[[0, 1, 0], [0.1, 1, 0], [0, 1, 0.1]]], np.float32)

    scene = penumbra.Scene(without_geometry(grid_scene()))
    scene.add_source(source)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        def interrupt():
            interrupted_at.append(time.monotonic())
            _thread.interrupt_main()
        timer = threading.Timer(0.5, interrupt)
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            penumbra.bake(scene, threads=1)
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert sum(t > interrupted_at[0] for t in calls) <= 50  # the main thread polls every 0.1 s


def test_ctrl_c_during_write_stops_it_and_leaves_no_file(tmp_path):
    # write() ran to its end (10 s for a large EXR), left both files, then raised.
    scene = grid_scene(type="camera", eye=[0, 6, 7], target=[0, 0.5, 0], up=[0, 1, 0], width=2000, height=1500)
    scene["lights"][0]["samples"] = 1
    result = penumbra.bake(penumbra.Scene(scene), threads=2)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        timer = threading.Timer(0.05, _thread.interrupt_main)  # seen by write()'s first check, 0.1 s in
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            result.write(str(tmp_path / "big.exr"))
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert os.listdir(tmp_path) == []
    result.write(str(tmp_path / "big.exr"))  # and the next write is not cancelled
    assert sorted(os.listdir(tmp_path)) == ["big.exr", "big.png"]


def test_the_interpreter_exits_cleanly_while_a_daemon_thread_bakes(examples):
    # "terminate called without an active exception", exit 134: finalization ends a daemon thread
    # as it takes the GIL back, and that unwound through a noexcept guard and a joinable thread.
    import subprocess
    from conftest import BUILD
    for delay, progress in ((0.5, "None"), (1.5, "None"), (1.5, "lambda *a: None"), (2.0, "None")):
        code = (f"import sys, threading, time; sys.path.insert(0, {str(BUILD / 'python')!r}); import penumbra; "
                f"scene = penumbra.Scene.from_json({str(examples / 'grids.json')!r}); "
                f"threading.Thread(target=lambda: penumbra.bake(scene, threads=1, progress={progress}), daemon=True).start(); "
                f"time.sleep({delay})")
        done = subprocess.run(["/usr/bin/python3", "-c", code], capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        assert "terminate" not in done.stderr


def test_a_bake_inside_a_source_is_refused_not_waited_for():
    # It waited for the bake that called the source: a hang only SIGKILL ended.
    def source():
        yield good()
        penumbra.bake(penumbra.Scene(grid_scene()), threads=1)

    scene = penumbra.Scene(without_geometry(grid_scene()))
    scene.add_source(source)
    with pytest.raises(ValueError, match=r"penumbra.bake\(\) was called from inside a source of a running bake"):
        penumbra.bake(scene, threads=1)


def test_a_raising_progress_callback_cancels(tmp_path):
    calls = []

    def progress(phase, fraction, eta):
        calls.append(phase)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        penumbra.bake(slow_scene(), progress=progress, tmp_dir=str(tmp_path))
    assert calls and os.listdir(tmp_path) == []


def test_progress_is_called_from_the_calling_thread():
    seen = []
    main = threading.get_ident()

    def progress(phase, fraction, eta):
        seen.append((phase, fraction, threading.get_ident()))

    penumbra.bake(slow_scene(300), progress=progress, threads=2)
    assert {t for _, _, t in seen} == {main}
    assert seen[-1][:2] == ("done", 1.0)
    assert any(phase == "scan" for phase, _, _ in seen)


def test_threads_in_sources_and_callbacks_do_not_deadlock():
    pool = ThreadPoolExecutor(4)

    def make(i):
        rng = np.random.default_rng(i)
        return (rng.random((256, 3, 3), dtype=np.float32) + [0, 1, 0]).astype(np.float32)

    def source():  # chunks made on other Python threads, which need the GIL too
        yield np.array([[[-5, 0, -5], [5, 0, -5], [0, 0, 5]]], np.float32)
        yield from pool.map(make, range(200))

    def progress(phase, fraction, eta):  # the callback waits for another thread
        t = threading.Thread(target=lambda: np.ones(1000).sum())
        t.start()
        t.join()

    results = []

    def background_bake():  # a bake from a worker thread: no signals there, the same machinery
        s = penumbra.Scene(without_geometry(grid_scene()))
        s.add_source(source)
        results.append(len(penumbra.bake(s, threads=2, progress=progress)))

    workers = [threading.Thread(target=background_bake) for _ in range(2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(timeout=300)
    assert not any(w.is_alive() for w in workers)
    assert len(results) == 2 and results[0] == results[1] > 0


def test_write_refuses_a_file_the_bake_read(tmp_path):
    # Result.write() over the points file (or the glTF a vertices bake copies) replaced it; the
    # CLI's -o refuses, and so does write() now, leaving the file as it was.
    points = tmp_path / "pts.npy"
    np.save(points, np.array([[0, 0, 0, 0, 1, 0], [0.5, 0, 0, 0, 1, 0]], np.float32))
    before = points.read_bytes()
    scene = penumbra.Scene({
        "geometry": [{"type": "grid", "cells": 2, "levels": 1}],
        "lights": [{"type": "rect", "center": [0, 4, 0], "u": [1, 0, 0], "v": [0, 0, 1], "samples": 16}],
        "receivers": {"type": "points", "path": "pts.npy"},
    }, base_dir=str(tmp_path))
    result = penumbra.bake(scene, threads=1)
    with pytest.raises(penumbra.Error, match=r"pts\.npy: is also an input of this bake"):
        result.write(str(points))
    assert points.read_bytes() == before
    result.write(str(tmp_path / "v.npy"))
    assert np.load(tmp_path / "v.npy").shape == (2,)


def test_a_waiting_caller_cancels_only_its_own_bake():
    # While B waits for A's bake, B's callback was called with A's phase, and B's raising
    # callback (or Ctrl-C in B) cancelled A's bake. Now B's callback starts with its own bake,
    # after A's has ended, and raising there stops B's only.
    done = {}

    def run_a():
        done["a"] = penumbra.bake(slow_scene(400), threads=1)
        done["a_end"] = time.monotonic()

    a = threading.Thread(target=run_a)
    a.start()
    time.sleep(0.3)  # A is baking
    calls = []

    def progress(phase, fraction, eta):
        calls.append(time.monotonic())
        raise RuntimeError("B gives up")

    with pytest.raises(RuntimeError, match="B gives up"):
        penumbra.bake(slow_scene(400), threads=1, progress=progress)
    a.join()
    assert "a" in done and done["a"].visibility.size > 0  # A was not cancelled
    assert calls and calls[0] >= done["a_end"]  # B's callback never saw A's bake


def test_a_large_or_broadcast_chunk_is_read_in_slices_within_the_budget(tmp_path):
    # A chunk was copied whole (to C order, then to triangles: 45-75 bytes a triangle) where no
    # memory budget counted it: 4M triangles took 165 MiB over an 83M budget, a broadcast of one
    # triangle as 10M triangles 793 MiB. It is now read in place, a slice at a time.
    import subprocess
    import sys
    code = f"""
import resource, sys
sys.path.insert(0, {str(pathlib.Path(penumbra.__file__).parents[1])!r})
import numpy as np, penumbra
from test_bake import grid_scene, without_geometry
one = np.array([[[-0.2, 1, -0.2], [0.2, 1, -0.2], [0, 1, 0.2]]], np.float32)
scene = penumbra.Scene(without_geometry(grid_scene()))
scene.add_source(lambda: iter([np.broadcast_to(one, (3_000_000, 3, 3)), np.repeat(one, 1_000_000, axis=0)]))
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
result = penumbra.bake(scene, threads=1, memory_budget="100M")
grew = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
print(result.stats["counters"]["triangles_read"], grew)
"""
    env = dict(os.environ, PYTHONPATH=str(pathlib.Path(__file__).parent))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    triangles, grew = out.stdout.split()
    assert int(triangles) >= 4_000_000
    assert float(grew) < 100  # MiB beyond the 1M-triangle array the test made itself (38 MB)



def test_messages_name_the_python_arguments_not_the_cli_options(tmp_path):
    # "--memory-budget 1 MiB is too small" was said to a caller who passed memory_budget="1M".
    scene = penumbra.Scene(grid_scene())
    with pytest.raises(penumbra.Error, match=r"^memory_budget 1 MiB is too small") as budget:
        penumbra.bake(scene, memory_budget="1M")
    with pytest.raises(penumbra.Error, match=r"^method hh: applies to lightmap receivers only") as method:
        penumbra.bake(scene, method="hh")
    with pytest.raises(penumbra.Error, match=r"^write\(\): .*x\.npy.*: camera receivers write \.exr files") as write:
        penumbra.bake(scene).write(str(tmp_path / "x.npy"))
    for raised in (budget, method, write):
        assert "--" not in str(raised.value)


def test_an_argument_of_the_wrong_type_is_a_type_error():
    # A wrong value is a ValueError (above); a wrong type is Python's TypeError, as documented.
    scene = penumbra.Scene(grid_scene())
    for kwargs in ({"method": 3}, {"method": None}, {"threads": 1.5}, {"threads": "2"}, {"threads": True}):
        with pytest.raises(TypeError):
            penumbra.bake(scene, **kwargs)


def _run_python(code, *prefix, timeout=120):
    """Runs @p code in a fresh /usr/bin/python3 that imports this build's penumbra and these tests."""
    import subprocess
    import sys
    package, tests = str(pathlib.Path(penumbra.__file__).parents[1]), str(pathlib.Path(__file__).parent)
    header = f"import sys\nsys.path.insert(0, {package!r})\nsys.path.insert(0, {tests!r})\n"
    return subprocess.run([*prefix, sys.executable, "-c", header + code], capture_output=True, text=True, timeout=timeout)


def test_an_address_space_limit_too_small_for_the_module_is_an_import_error_not_an_abort():
    # Between about 125 and 158 MiB the libraries mapped and the logging thread OpenVDB's
    # log4cplus starts as it loads did not: std::terminate, SIGABRT, from inside the import.
    for mib in (100, 140):
        out = _run_python("import penumbra", "prlimit", f"--as={mib << 20}")
        assert out.returncode == 1, out.stderr
        assert (f"ImportError: penumbra: the address-space limit (prlimit --as, ulimit -v) of {mib} MiB is too small to "
                "load the module") in out.stderr


def test_no_room_for_the_bake_thread_is_a_penumbra_error():
    # The thread bake() runs on could not get its stack: a bare RuntimeError("Resource
    # temporarily unavailable") that named neither the limit nor penumbra.
    code = """
import resource
import penumbra
from test_bake import grid_scene
scene = penumbra.Scene(grid_scene())
mapped = next(int(line.split()[1]) * 1024 for line in open("/proc/self/status") if line.startswith("VmSize:"))
resource.setrlimit(resource.RLIMIT_AS, (mapped + (4 << 20), resource.RLIM_INFINITY))
try:
    penumbra.bake(scene, threads=1)
    print("baked")
except penumbra.Error as e:
    print("Error:", e)
"""
    out = _run_python(code)
    assert out.returncode == 0, out.stderr
    assert "Error: the address-space limit (prlimit --as, ulimit -v) of " in out.stdout
    assert "leaves no room for the bake's thread and its stack" in out.stdout


def test_a_larger_address_space_limit_never_refuses_a_bake_that_a_smaller_one_ran(tmp_path):
    # The bake's own thread reserved a malloc arena (64 MiB of address space) before the plan kept
    # malloc to one, so that 270-290M baked, 300-320M were refused naming 331M, and 330M baked.
    scene = dict(grid_scene(), output=str(tmp_path / "out/s.exr"))
    scene["receivers"].update(width=320, height=240)
    (tmp_path / "s.json").write_text(json.dumps(scene))
    code = f"""
import penumbra
try:
    penumbra.bake(penumbra.Scene.from_json({str(tmp_path / "s.json")!r}), threads=2, masks=False)
    print("OK")
except penumbra.Error as e:
    print("refused:", e)
"""
    ran, results = None, []
    for mib in range(200, 460, 10):  # the module alone needs about 166M (above)
        out = _run_python(code, "prlimit", f"--as={mib << 20}")
        assert out.returncode == 0, out.stderr
        results.append((mib, out.stdout.strip()))
        if out.stdout.startswith("OK"):
            ran = ran or mib
        else:
            assert ran is None, results  # refused above a limit that ran
            assert "address-space limit" in out.stdout, results
        if ran is not None and mib >= ran + 60:
            break
    assert ran is not None, results
