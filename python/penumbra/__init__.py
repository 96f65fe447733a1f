"""penumbra: out-of-core soft-shadow baking, driven from Python.

Scenes come from JSON files, dicts with the same keys, built-in generators and Python triangle
sources (NumPy chunks); bake() runs the same pipeline as the `penumbra bake` command and returns
NumPy arrays; Result.write() writes the command's outputs byte for byte.
"""

from ._penumbra import (Error, Result, Scene, SceneError, bake, generate, methods)

__all__ = ["Error", "Result", "Scene", "SceneError", "bake", "generate", "methods"]
