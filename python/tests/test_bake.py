"""bake() against the CLI: the same outputs byte for byte, the same masks; NumPy sources against
the generators they copy."""
import json
import shutil
import subprocess

import numpy as np
import pytest

import penumbra

# Small versions of the examples: (scene, files it reads, receiver changes).
EXAMPLES = [
    ("grids.json", [], {"width": 96, "height": 72}),
    ("antialias.json", [], {"width": 80, "height": 60}),
    ("lightmap.json", ["room.obj", "room-blockers.obj"], {"resolution": 48}),
    ("vertices.json", ["vertices-floor.glb"], {}),
]


def small_example(examples, tmp_path, name, files, receivers):
    scene = json.loads((examples / name).read_text())
    scene["receivers"].update(receivers)
    for f in files:
        shutil.copy(examples / f, tmp_path / f)
    path = tmp_path / name
    path.write_text(json.dumps(scene))
    return path, scene


def files_of(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.mark.parametrize("name,files,receivers", EXAMPLES, ids=[e[0] for e in EXAMPLES])
def test_write_equals_cli_outputs(cli, examples, tmp_path, name, files, receivers):
    path, scene = small_example(examples, tmp_path, name, files, receivers)
    output = pathlib_name(scene["output"])
    (tmp_path / "cli").mkdir()
    (tmp_path / "py").mkdir()
    subprocess.run([str(cli), "bake", str(path), "-o", str(tmp_path / "cli" / output), "--dump", str(tmp_path / "dump"),
                    "--threads", "2", "--quiet"], check=True)
    py_output = str(tmp_path / "py" / output)
    # write() alone names the files: the vertices kind's copies went to the scene's output.
    result = penumbra.bake(penumbra.Scene.from_json(str(path)), threads=2)
    result.write(py_output)
    assert not (tmp_path / scene["output"]).exists()  # nothing at the scene's own output
    cli_files, py_files = files_of(tmp_path / "cli"), files_of(tmp_path / "py")
    assert cli_files.keys() == py_files.keys()
    for key in cli_files:
        assert cli_files[key] == py_files[key], key
    np.testing.assert_array_equal(result.masks, np.load(tmp_path / "dump" / "masks.npy"))
    assert result.stats["receivers"] == len(result)
    # A name of the wrong kind is refused as the CLI refuses it (a camera's x.png held both its
    # EXR and its PNG), and nothing is written.
    wrong = str(tmp_path / "wrong" / (output.rsplit(".", 1)[0] + ".bad"))
    with pytest.raises(penumbra.Error, match="name the output with that extension"):
        result.write(wrong)
    assert not (tmp_path / "wrong").exists()
    # A folder that does not exist is refused, as the CLI refuses it for -o, and none is made.
    with pytest.raises(penumbra.Error, match=r"write: .*: the folder .*typo/deeper does not exist \(create it first\)"):
        result.write(str(tmp_path / "typo" / "deeper" / pathlib_name(output)))
    assert not (tmp_path / "typo").exists()


def pathlib_name(output):
    return output.rsplit("/", 1)[-1]


def grid_scene(**receivers):
    return {
        "geometry": [{"type": "grid", "size": 3, "cells": 8, "bar": 0.4, "thickness": 0.05, "levels": 2,
                      "height": 1.0, "spacing": 0.5, "floor_size": 6}],
        "lights": [{"type": "rect", "center": [0, 5, 0], "u": [1.5, 0, 0], "v": [0, 0, 1.5],
                    "radiance": [10, 10, 10], "samples": 64}],
        "receivers": receivers or {"type": "camera", "eye": [0, 6, 7], "target": [0, 0.5, 0], "up": [0, 1, 0],
                                   "fov_deg": 45, "width": 64, "height": 48},
    }


def without_geometry(scene):
    return dict(scene, geometry=[])


def test_numpy_stream_of_a_generator_gives_its_masks():
    # The grid's bars are closed boxes (flags); "closed": false clears them, so plain chunks copy it.
    source = grid_scene()
    source["geometry"][0]["closed"] = False
    scene = penumbra.Scene(source)
    chunks, flags = zip(*penumbra.generate(scene, chunk=1000, flags=True))
    assert all(not f.any() for f in flags)
    expected = penumbra.bake(scene, threads=2)

    by_call = penumbra.Scene(without_geometry(grid_scene()))
    by_call.add_source(lambda: iter(chunks))
    as_list = penumbra.Scene(without_geometry(grid_scene()))
    as_list.add_source([c.reshape(-1, 9) for c in chunks])  # re-iterable, (n, 9) rows
    one_shot = penumbra.Scene(without_geometry(grid_scene()))
    one_shot.add_source(c for c in chunks)  # buffered to a scratch file for the second pass
    for copy in (by_call, as_list, one_shot):
        got = penumbra.bake(copy, threads=2)
        np.testing.assert_array_equal(got.masks, expected.masks)
        np.testing.assert_array_equal(got.visibility, expected.visibility)
        assert got.stats["counters"]["triangles_read"] == expected.stats["counters"]["triangles_read"]


def test_generate_yields_what_the_bake_reads():
    scene = penumbra.Scene(grid_scene())
    total = sum(len(c) for c in penumbra.generate(scene))
    chunk = next(iter(penumbra.generate(scene)))
    assert chunk.dtype == np.float32 and chunk.shape[1:] == (3, 3)
    assert total == penumbra.bake(scene, threads=1).stats["counters"]["triangles_read"]


def test_points_from_numpy_equal_a_points_file(cli, tmp_path):
    xs = np.linspace(-2.5, 2.5, 40, dtype=np.float32)
    positions = np.stack([xs, np.full_like(xs, 0.01), np.zeros_like(xs)], axis=1)
    normals = np.tile(np.array([0, 1, 0], np.float32), (len(xs), 1))
    np.save(tmp_path / "pts.npy", np.concatenate([positions, normals], axis=1))
    scene = grid_scene(type="points", path="pts.npy")
    scene["output"] = "v.npy"
    (tmp_path / "s.json").write_text(json.dumps(scene))
    subprocess.run([str(cli), "bake", str(tmp_path / "s.json"), "--quiet"], check=True)
    result = penumbra.bake(penumbra.Scene(grid_scene(), points=(positions, normals)))
    np.testing.assert_array_equal(result.visibility, np.load(tmp_path / "v.npy"))
    result.write(str(tmp_path / "py.npy"))
    assert (tmp_path / "py.npy").read_bytes() == (tmp_path / "v.npy").read_bytes()
    assert result.visibility.min() < result.visibility.max()  # the row crosses a shadow


def test_camera_views_and_per_light_arrays():
    scene = grid_scene()
    scene["lights"].append(dict(scene["lights"][0], center=[2, 5, 0], samples=32))
    result = penumbra.bake(penumbra.Scene(scene), threads=2)
    assert result.image_shape == (48, 64)
    image = result.image()
    assert image.shape == (48, 64)
    seen = ~np.isnan(image)
    np.testing.assert_array_equal(image[seen], result.visibility[: seen.sum()][np.argsort(result.pixels[: seen.sum()])])
    assert result.image("irradiance").shape == (48, 64, 3)
    assert result.light_visibility.shape == (len(result), 2)
    assert result.light_irradiance.shape == (len(result), 2, 3)
    np.testing.assert_allclose(result.light_irradiance.sum(axis=1), result.irradiance, rtol=1e-5, atol=1e-6)
    assert result.masks.shape == (len(result), 2)  # 96 samples: two words
    # Views of what write() reads: scaling one in place changed the files written.
    for name in ("visibility", "irradiance", "light_visibility", "light_irradiance", "masks", "positions", "normals", "pixels"):
        array = getattr(result, name)
        assert not array.flags.writeable, name
        with pytest.raises(ValueError, match="read-only"):
            array[...] = 0
    assert result.visibility.copy().flags.writeable


def test_image_holds_the_refined_pixels_and_the_nearest_layer():
    # image() mapped the first pass's pixel centres only: an antialiased pixel kept its centre's
    # value where the EXR holds the mean of its sub-pixel receivers, and a pixel whose centre saw
    # nothing stayed NaN.
    scene = grid_scene()
    scene["receivers"]["antialias"] = {"threshold": 0.1, "samples": 4}
    result = penumbra.bake(penumbra.Scene(scene), threads=2)
    pixels, visibility = result.pixels, result.visibility
    first = np.flatnonzero(np.diff(pixels.astype(np.int64)) <= 0)[0] + 1  # where pixel order restarts
    expected = np.full(48 * 64, np.nan, dtype=np.float32)
    expected[pixels[:first]] = visibility[:first]
    refined = pixels[first:]
    assert len(refined) > 0
    for p in np.unique(refined):
        expected[p] = np.float32(visibility[first:][refined == p].astype(np.float64).mean())
    np.testing.assert_array_equal(result.image().ravel(), expected)
    # A deep camera's deeper layers (pixel >= W * H) wrote past the image's end.
    deep = grid_scene()
    deep["receivers"]["layers"] = 3
    result = penumbra.bake(penumbra.Scene(deep), threads=2)
    front = result.pixels < 48 * 64
    assert (~front).any()
    image = result.image().ravel()
    np.testing.assert_array_equal(image[result.pixels[front]], result.visibility[front])
