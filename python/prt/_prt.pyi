"""Type stubs of the native module prt._prt (re-exported by the prt package)."""

import os
import pathlib
from typing import Callable, Dict, Literal, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

PathLike = Union[str, "os.PathLike[str]"]
Colour = Union[float, Tuple[float, float, float], Sequence[float]]
Image = npt.NDArray[np.float32]
ProgressCallback = Callable[["ProgressEvent"], Optional[bool]]

class ProgressEvent:
    """One thing a long call reports; the progress callback receives these."""

    kind: Literal["start", "advance", "restored", "finish", "note", "warning"]
    """`start` (a stage of `total` steps begins), `advance` (`steps` more are done),
    `restored` (`steps` done by an earlier, interrupted run), `finish`, `note`, `warning`."""
    stage: Optional[str]
    """The current stage ("tracing", "rendering", ...); None outside one."""
    total: int
    """Steps of the current stage (0 outside one)."""
    done: int
    """Steps of the current stage done so far, this event's included."""
    steps: int
    """Steps this event adds (`advance`, `restored`)."""
    text: Optional[str]
    """The note's or warning's text."""

class Param:
    """One parameter of a material."""

    name: Literal["kd", "ks", "shininess", "alpha"]
    value: Union[float, Tuple[float, float, float]]
    """The current value: (r, g, b) for a colour, a float for a lobe parameter."""
    range: Tuple[float, float]
    """(min, max) of the values `set` accepts (per channel for a colour; max may be inf)."""
    sampled: Optional[Tuple[float, float]]
    """The lobe parameter's range the bake sampled; outside it a value is rendered clamped."""
    clamped: bool
    """Whether the current value lies outside `sampled` and is rendered clamped."""

class Material:
    """A material of the bake."""

    name: str
    family: Literal["diffuse", "blinn-phong", "ggx"]
    editable: bool
    textured: bool
    params: Dict[str, Param]

class Camera:
    """A pinhole camera looking from `eye` at `target`, vertical field of view `fov`
    degrees, +Y up (the frame `relight --camera` makes)."""

    def __init__(
        self, eye: Sequence[float], target: Sequence[float], fov: float
    ) -> None: ...
    @property
    def eye(self) -> Tuple[float, float, float]: ...
    @property
    def forward(self) -> Tuple[float, float, float]: ...
    @property
    def right(self) -> Tuple[float, float, float]: ...
    @property
    def up(self) -> Tuple[float, float, float]: ...
    @property
    def fov(self) -> float:
        """The vertical field of view in degrees."""
    def orbited(self, degrees: float) -> "Camera":
        """This camera turned `degrees` about the world's +Y axis through the origin."""

class Relighter:
    """An opened bake of either kind (`open` gives a PixelRelighter or a VertexRelighter)."""

    @property
    def kind(self) -> Literal["pixel", "vertex"]: ...
    @property
    def path(self) -> "pathlib.Path":
        """The bake file."""
    @property
    def materials(self) -> list[Material]:
        """Every material, in the bake's order, with its current parameters and ranges."""
    def set(
        self,
        material: str,
        *,
        kd: Colour = ...,
        ks: Colour = ...,
        shininess: float = ...,
        alpha: float = ...,
    ) -> None:
        """Sets parameters of an editable material, all or none (ParameterError on a
        refused value, changing nothing)."""
    @property
    def size(self) -> Tuple[int, int]:
        """(width, height) of the images rendered now."""
    def render(self, out: Optional[Image] = None) -> Image:
        """The image for the current settings: float32, shape (height, width, 3), linear
        RGB, top row first, written in place (into `out` when given) with the GIL released."""

class PixelRelighter(Relighter):
    """A per-pixel bake: camera, light and size frozen; materials edited."""

    @property
    def has_compressed(self) -> bool: ...
    @property
    def variant(self) -> Literal["full", "compressed"]: ...
    @variant.setter
    def variant(self, variant: Literal["full", "compressed"]) -> None: ...

class VertexRelighter(Relighter):
    """A per-vertex bake: environment, camera, size and materials edited."""

    @property
    def environment(self) -> Image:
        """The environment map as set (before its intensity), a copy; set it to a map file
        or a (height, width, 3) float array."""
    @environment.setter
    def environment(self, source: Union[PathLike, npt.ArrayLike]) -> None: ...
    def set_environment(self, source: Union[PathLike, npt.ArrayLike]) -> int:
        """Lights the scene with a map file or array; returns the texels clamped to 0."""
    @property
    def environment_rotation(self) -> float: ...
    @environment_rotation.setter
    def environment_rotation(self, degrees: float) -> None: ...
    @property
    def environment_intensity(self) -> float: ...
    @environment_intensity.setter
    def environment_intensity(self, intensity: float) -> None: ...
    @property
    def compact_lights(self) -> bool:
        """Whether the map's compact lights (a sun, a lamp) are reflected per pixel through
        the true lobe (the default) or left to the shading basis."""
    @compact_lights.setter
    def compact_lights(self, on: bool) -> None: ...
    @property
    def antialias(self) -> bool:
        """Whether silhouettes and creases are sampled 16 times per pixel (the default) or
        shaded at each pixel's centre alone."""
    @antialias.setter
    def antialias(self, on: bool) -> None: ...
    @property
    def camera(self) -> Camera: ...
    @camera.setter
    def camera(self, camera: Camera) -> None: ...
    @property
    def default_camera(self) -> Camera: ...
    @property
    def size(self) -> Tuple[int, int]: ...
    @size.setter
    def size(self, size: Tuple[int, int]) -> None: ...

class Comparison:
    """How an image differs from a reference."""

    relative_l2: float
    mean_difference: Tuple[float, float, float]
    standard_error: Tuple[float, float, float]
    z: Tuple[float, float, float]
    z_mean: float
    """The channel averages' mean difference in standard errors (beyond ~4: not noise)."""

def open(path: PathLike) -> Union[PixelRelighter, VertexRelighter]:
    """Opens a bake file of either kind (FileError when missing, corrupt or no bake)."""

def bake(
    config: PathLike,
    out: Optional[PathLike] = None,
    *,
    progress: Optional[ProgressCallback] = None,
    spp: Optional[int] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
    precision: Optional[Literal["f32", "f16"]] = None,
    compress_rank: Optional[int] = None,
    basis_count: Optional[int] = None,
    max_memory: Optional[int] = None,
    checkpoint: bool = True,
    resume: bool = False,
) -> Dict[str, object]:
    """Bakes a config, scene folder or glTF as the `bake` command does; returns its figures
    (`output`, `file_bytes`, `seconds`, ...). Ctrl-C or the callback returning False or
    raising stops it, writing nothing (a per-vertex bake keeps its checkpoint)."""

def reference(
    config: PathLike,
    *,
    like: Optional[Relighter] = None,
    spp: Optional[int] = None,
    seed: Optional[int] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
    set: Optional[Mapping[str, Mapping[str, Colour]]] = None,
    env: Union[PathLike, npt.ArrayLike, None] = None,
    env_intensity: Optional[float] = None,
    env_rotation: Optional[float] = None,
    camera: Optional[Camera] = None,
    progress: Optional[ProgressCallback] = None,
) -> Image:
    """The ground truth (true BRDFs, path traced) for `like`'s settings or those given."""

def compare(image: npt.ArrayLike, reference: npt.ArrayLike) -> Comparison:
    """Relative L2 error and mean difference in standard errors of `image` against
    `reference`."""

def write_image(path: PathLike, image: npt.ArrayLike, exposure: float = 1.0) -> None:
    """Writes .exr (float) or .png (tone-mapped sRGB) by the extension, atomically."""
