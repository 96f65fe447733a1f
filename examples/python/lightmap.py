#!/usr/bin/env python3
"""A lightmap bake driven from Python: the room example, its texels as arrays, then the CLI's files.

    python3 examples/python/lightmap.py --resolution 256 -o out/lightmap-py.exr
"""
import argparse
import pathlib

import numpy as np

import penumbra

EXAMPLES = pathlib.Path(__file__).resolve().parents[1]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=256)
    parser.add_argument("-o", "--output", default="out/lightmap-py.exr")
    args = parser.parse_args()
    scene = penumbra.Scene.from_json(str(EXAMPLES / "lightmap.json")).to_dict()
    scene["receivers"]["resolution"] = args.resolution
    # Relative paths (room.obj) resolve against base_dir, as they would against the scene file's folder.
    result = penumbra.bake(penumbra.Scene(scene, base_dir=str(EXAMPLES)), progress=lambda *p: None)
    lit = result.visibility > 0.99
    print(f"{len(result)} texels: {lit.mean():.1%} fully lit, {(result.visibility == 0).mean():.1%} in umbra, "
          f"mean irradiance {result.irradiance.mean(axis=0)}")
    print(f"stats: {result.stats['table2']['total_time_s']:.2f} s, {result.stats['light_samples']} samples")
    pathlib.Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    result.write(args.output)
    print("wrote", args.output)


if __name__ == "__main__":
    main()
