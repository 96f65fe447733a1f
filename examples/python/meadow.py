#!/usr/bin/env python3
"""A meadow whose grass blades are placed in NumPy and streamed into a bake chunk by chunk.

    python3 examples/python/meadow.py --blades 2000000 -o out/meadow-py.exr

Nothing is written between generation and the bake: penumbra calls blades() again for each of
its two passes, and only one chunk (CHUNK blades) exists at a time, so memory does not grow
with --blades (docs/python.md has the numbers for 20M blades, 100M triangles).
"""
import argparse
import os
import sys

import numpy as np

import penumbra

CHUNK = 65536  # blades per chunk: 327,680 triangles, 11.8 MB


def blade_triangles(rng, count, extent):
    """count blades as (count * 5, 3, 3) float32: a tapered, leaning strip of 5 triangles each."""
    base = np.stack([rng.uniform(-extent, extent, count), np.zeros(count), rng.uniform(-extent, extent, count)], 1)
    height = rng.uniform(0.25, 0.6, count)[:, None]
    angle = rng.uniform(0, 2 * np.pi, count)
    side = np.stack([np.cos(angle), np.zeros(count), np.sin(angle)], 1) * 0.015  # half width
    lean = np.stack([-np.sin(angle), np.zeros(count), np.cos(angle)], 1) * rng.uniform(0, 0.3, count)[:, None]
    up = np.array([0.0, 1.0, 0.0])
    levels = []
    for t in (0.0, 1 / 3, 2 / 3):
        centre = base + height * (t * up + t * t * lean)
        levels.append((centre - side * (1 - t), centre + side * (1 - t)))
    tip = base + height * (up + lean)
    (l0, r0), (l1, r1), (l2, r2) = levels
    tris = np.stack([np.stack(v, 1) for v in ((l0, r0, l1), (r0, r1, l1), (l1, r1, l2), (r1, r2, l2), (l2, r2, tip))], 1)
    return tris.reshape(-1, 3, 3).astype(np.float32)


def blades(count, seed=7, extent=10.0, chunk=CHUNK):
    """A callable source: each call replays the same blades, chunk by chunk."""
    def source():
        rng = np.random.default_rng(seed)
        for first in range(0, count, chunk):
            yield blade_triangles(rng, min(chunk, count - first), extent)
    return source


def meadow_scene(width=640, height=480):
    return {
        "geometry": [],
        "lights": [{"type": "rect", "center": [1, 4, -2], "u": [1.5, 0, 0], "v": [0, 0, 1.5],
                    "radiance": [40, 40, 40], "samples": 256, "sample_sets": 8}],
        "receivers": {"type": "camera", "eye": [0, 2.2, 5], "target": [0, 0.2, 0], "up": [0, 1, 0],
                      "fov_deg": 50, "width": width, "height": height},
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blades", type=int, default=1_000_000)
    parser.add_argument("-o", "--output", default="out/meadow-py.exr")
    parser.add_argument("--threads", type=int)
    args = parser.parse_args()
    scene = penumbra.Scene(meadow_scene())
    e = 10.0  # the ground under the blades: two triangles, facing up
    scene.add_source([np.float32([[[-e, 0, -e], [-e, 0, e], [e, 0, e]], [[-e, 0, -e], [e, 0, e], [e, 0, -e]]])])
    scene.add_source(blades(args.blades), count=5 * args.blades)

    def progress(phase, fraction, eta):
        if fraction is not None:
            print(f"\r[{phase}] {100 * fraction:5.1f}%", end="", file=sys.stderr, flush=True)

    result = penumbra.bake(scene, threads=args.threads, progress=progress)
    print(file=sys.stderr)
    os.makedirs(os.path.dirname(args.output) or ".", exist_ok=True)
    result.write(args.output)
    print(f"{len(result)} receivers, {result.stats['counters']['triangles_read']} triangles, "
          f"mean visibility {np.nanmean(result.image()):.3f} -> {args.output}")


if __name__ == "__main__":
    main()
