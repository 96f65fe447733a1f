"""Type stubs for penumbra (the compiled module is penumbra._penumbra)."""

from typing import Any, Callable, Iterable, Iterator, Optional, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

Chunk = npt.NDArray[np.float32]
"""(n, 3, 3) or (n, 9) float32 triangles."""
ChunkSource = Union[Callable[[], Iterable[Chunk]], Iterable[Chunk]]
Progress = Callable[[str, Optional[float], Optional[float]], Any]

class Error(RuntimeError):
    """A bake or scene problem, as the CLI reports it ("FILE: what is wrong")."""

class SceneError(Error, ValueError):
    """A scene key or value is wrong; the message names the key."""

class Scene:
    """A scene: geometry, lights, receivers, output and bake options (docs/scene-format.md)."""
    def __init__(self, scene: dict, points: Optional[Tuple[npt.ArrayLike, npt.ArrayLike]] = None,
                 base_dir: str = ".") -> None:
        """Takes the keys of the JSON format, validated as the CLI does; raises SceneError."""
    @staticmethod
    def from_json(path: str) -> "Scene":
        """Reads a scene file; its relative paths are relative to its folder."""
    def add_geometry(self, type: str, **params: Any) -> None:
        """A file (obj, gltf, glb, ptri, file) or generator (grid, terrain, grass, tree, forest,
        flowers, scatter, boxes, colonnade) with its parameters, "transform" and "closed"."""
    def add_source(self, source: ChunkSource, alpha: bool = False, closed: Optional[bool] = None,
                   count: Optional[int] = None) -> None:
        """Triangles streamed from Python; a callable is called and a re-iterable iterated once
        per pass, a one-shot iterator is copied once to an unnamed scratch file."""
    def set_points(self, positions: npt.ArrayLike, normals: npt.ArrayLike) -> None:
        """(N, 3) receiver positions and normals, replacing the scene's receivers."""
    def to_dict(self) -> dict:
        """The scene document."""
    @property
    def output(self) -> str: ...

class Result:
    """What penumbra.bake() returns; arrays share the result's memory where they can."""
    @property
    def visibility(self) -> npt.NDArray[np.float32]:
        """(N,) unblocked samples / all samples."""
    @property
    def irradiance(self) -> npt.NDArray[np.float32]:
        """(N, 3) RGB irradiance, all lights summed."""
    @property
    def light_visibility(self) -> npt.NDArray[np.float32]:
        """(N, lights)."""
    @property
    def light_irradiance(self) -> npt.NDArray[np.float32]:
        """(N, lights, 3)."""
    @property
    def masks(self) -> Optional[npt.NDArray[np.uint64]]:
        """(N, ceil(K/64)); bit k%64 of word k/64 set when sample k is blocked (None without masks)."""
    @property
    def positions(self) -> npt.NDArray[np.float32]: ...
    @property
    def normals(self) -> npt.NDArray[np.float32]: ...
    @property
    def pixels(self) -> npt.NDArray[np.uint32]:
        """Camera receivers' pixel index y * width + x."""
    @property
    def image_shape(self) -> Optional[Tuple[int, int]]:
        """(H, W) for a camera."""
    def image(self, values: str = "visibility") -> npt.NDArray[np.float32]:
        """(H, W) visibility or (H, W, 3) irradiance; NaN where no surface is seen."""
    @property
    def stats(self) -> dict:
        """The --stats document."""
    @property
    def samples(self) -> int:
        """Light samples K."""
    def write(self, path: str) -> None:
        """The CLI's outputs for this scene at path, byte for byte."""
    def __len__(self) -> int: ...

def bake(scene: Scene, method: str = "hpc", threads: Optional[int] = None,
         memory_budget: Union[int, str, None] = None, progress: Optional[Progress] = None,
         tmp_dir: Optional[str] = None, masks: bool = True, output: Optional[str] = None) -> Result:
    """Bakes with the CLI's pipeline; GIL released, Ctrl-C cancels cleanly."""

@overload
def generate(scene: Scene, chunk: int = ..., flags: bool = False) -> Iterator[npt.NDArray[np.float32]]: ...
@overload
def generate(scene: Scene, chunk: int = ..., *, flags: bool) -> Iterator[Any]: ...

def methods() -> list[str]:
    """Registered bake methods."""
