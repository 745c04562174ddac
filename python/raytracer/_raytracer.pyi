"""Type stubs of the extension module ``raytracer._raytracer`` (re-exported by
``raytracer``). The docstrings, with every default, are the functions' own."""

import os
from typing import Any, Callable, Dict, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt
from typing_extensions import TypedDict, Unpack

from ._image import Image

StrPath = Union[str, "os.PathLike[str]"]
Vector = Union[Sequence[float], npt.NDArray[np.floating]]
Mode = Literal["full", "depth", "normal", "path"]
ToneMap = Literal["standard", "khronos-neutral", "agx", "aces"]
Progress = Union[bool, None, Callable[[int, int], Any]]
#: With ``aovs=`` a render returns a dict: ``color`` and each output asked for.
Aov = Literal["depth", "normal", "albedo", "alpha", "object_id", "material_id"]

__version__: str
#: The keyword options every render call takes, in documentation order.
OPTIONS: Tuple[str, ...]

class SceneError(OSError): ...
class RaytracerWarning(UserWarning): ...

#: The keyword options of a render, as ``raytracer::options::OPTIONS`` defines them
#: (tests/options_table.rs holds these classes to it).
class RenderKeywords(TypedDict, total=False):
    width: Optional[int]
    height: Optional[int]
    fov: Optional[float]
    look_from: Optional[Vector]
    look_to: Optional[Vector]
    up: Optional[Vector]
    camera_to_world: Optional[npt.ArrayLike]
    intrinsics: Optional[Tuple[float, float, float, float]]
    depth: Optional[int]
    mode: Optional[Literal["full", "depth", "normal", "path"]]
    spp: Optional[int]
    exposure: Optional[float]
    tonemap: Optional[Literal["standard", "khronos-neutral", "agx", "aces"]]
    aperture_radius: Optional[float]
    focus_distance: Optional[float]
    seed: Optional[int]
    default_light: Optional[bool]

#: The keyword options of the scene: its environment and background.
class SceneKeywords(TypedDict, total=False):
    env: Union[StrPath, Vector, None]
    env_strength: Optional[float]
    env_rotation: Optional[float]
    background: Optional[Vector]

class Keywords(RenderKeywords, SceneKeywords, total=False): ...

class Scene:
    def __init__(
        self, path: StrPath, *, confined_to: Optional[StrPath] = None, **environment: Unpack[SceneKeywords]
    ) -> None: ...
    @staticmethod
    def from_mesh(vertices: npt.ArrayLike, faces: npt.ArrayLike) -> "Scene": ...
    @staticmethod
    def from_arrays(
        meshes: Optional[Sequence[Dict[str, Any]]] = None,
        lights: Optional[Sequence[Dict[str, Any]]] = None,
        environment: Optional[Dict[str, Any]] = None,
    ) -> "Scene": ...
    @staticmethod
    def from_trimesh(mesh: Any) -> "Scene": ...
    @property
    def object_names(self) -> list[str]: ...
    @property
    def counts(self) -> Dict[str, int]: ...
    def camera_rays(self, **options: Unpack[RenderKeywords]) -> Dict[str, npt.NDArray[np.float32]]: ...
    @property
    def path(self) -> Optional[str]: ...
    @property
    def warnings(self) -> list[str]: ...
    def render(
        self,
        *,
        tile: Optional[Tuple[int, int, int, int]] = None,
        progress: Progress = None,
        aovs: Optional[Sequence[Aov]] = None,
        denoise: bool = False,
        **options: Unpack[RenderKeywords],
    ) -> Union[Image, Dict[str, np.ndarray]]: ...
    def options(self, **options: Unpack[RenderKeywords]) -> Dict[str, Any]: ...
    def intersect(self, origins: npt.ArrayLike, directions: npt.ArrayLike) -> Dict[str, np.ndarray]: ...
    def occluded(
        self, origins: npt.ArrayLike, directions: npt.ArrayLike, t_max: Union[float, npt.ArrayLike, None] = None
    ) -> npt.NDArray[np.bool_]: ...

def render(
    scene: Union[StrPath, Scene],
    *,
    tile: Optional[Tuple[int, int, int, int]] = None,
    progress: Progress = None,
    aovs: Optional[Sequence[Aov]] = None,
    denoise: bool = False,
    **options: Unpack[Keywords],
) -> Union[Image, Dict[str, np.ndarray]]: ...
def postprocess(
    linear: npt.ArrayLike, mode: Mode = "full", exposure: float = 0.0, tonemap: Optional[ToneMap] = None
) -> npt.NDArray[np.uint8]: ...
def write_image(
    linear: npt.ArrayLike, path: StrPath, mode: Mode = "full", exposure: float = 0.0, tonemap: Optional[ToneMap] = None
) -> None: ...
def write_png(rgb: npt.NDArray[np.uint8], path: StrPath) -> None: ...
def check_output(path: StrPath) -> Literal["png", "exr"]: ...
def _png(linear: npt.ArrayLike, mode: str = "full", exposure: float = 0.0, tonemap: Optional[str] = None) -> bytes: ...
def _committed(path: StrPath) -> bool: ...
def _scene_files(path: StrPath, confined: bool) -> Dict[str, Any]: ...
