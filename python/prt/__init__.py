"""PRT bake from Python: bake a scene, relight the bake for any material (and, per vertex,
environment, camera and image size) into numpy arrays, render the ground truth and compare.

>>> import prt
>>> prt.bake("scenes/cornell", out="/tmp/cornell.prtbake", spp=16)
>>> r = prt.open("/tmp/cornell.prtbake")
>>> r.set("bunny", kd=(0.8, 0.2, 0.2), alpha=0.3)
>>> image = r.render()                      # float32, (height, width, 3), linear RGB
>>> truth = prt.reference("scenes/cornell", like=r, spp=64)
>>> prt.compare(image, truth)

docs/python.md is the guide.
"""

from ._errors import (
    Cancelled,
    ConfigError,
    FileError,
    ParameterError,
    PrtError,
    PrtWarning,
)
from ._progress import PrintProgress, TqdmProgress
from ._prt import (
    Camera,
    Comparison,
    Material,
    Param,
    PixelRelighter,
    ProgressEvent,
    Relighter,
    VertexRelighter,
    bake,
    compare,
    open,
    reference,
    write_image,
)

__all__ = [
    "open",
    "bake",
    "reference",
    "compare",
    "write_image",
    "Relighter",
    "PixelRelighter",
    "VertexRelighter",
    "Camera",
    "Material",
    "Param",
    "Comparison",
    "ProgressEvent",
    "TqdmProgress",
    "PrintProgress",
    "PrtError",
    "FileError",
    "ConfigError",
    "ParameterError",
    "Cancelled",
    "PrtWarning",
]
