"""Type stubs of the ``animcodec`` package (the implementation's docstrings document each function)."""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from ._native import AnimcodecError as AnimcodecError
from .distributed import SweepResult as SweepResult
from .distributed import sweep as sweep
from .distributed import sweep_local as sweep_local
from .blocks import encode_distributed as encode_distributed

_Path = Union[str, PathLike[str]]
_ArrayLike = npt.ArrayLike

class Animation:
    positions: npt.NDArray[np.float32]
    faces: npt.NDArray[np.uint32]
    fps: float
    def __init__(self, positions: npt.NDArray[np.float32], faces: npt.NDArray[np.uint32], fps: float) -> None: ...
    @property
    def frames(self) -> int: ...
    @property
    def vertices(self) -> int: ...
    @property
    def triangles(self) -> int: ...

class TargetEncoding:
    stream: bytes
    codec: str
    params: Dict[str, Any]
    reached: Dict[str, Optional[float]]
    bpvf: float
    details: Dict[str, Any]

def codecs() -> List[Dict[str, Any]]: ...
def codec_names() -> List[str]: ...
def encode(positions: _ArrayLike, faces: _ArrayLike, codec: str, fps: float = 30.0, **params: Any) -> bytes: ...
def encode_to_target(
    positions: _ArrayLike,
    faces: _ArrayLike,
    codec: str = "auto",
    fps: float = 30.0,
    *,
    kg: Optional[float] = None,
    sted: Optional[float] = None,
    hausdorff: Optional[float] = None,
    max_error: Optional[float] = None,
    rmse: Optional[float] = None,
    refine: int = 0,
    **params: Any,
) -> TargetEncoding: ...
DEFAULT_MAX_MEMORY: int
DEFAULT_MAX_WORK: int

def decode(
    data: Union[bytes, bytearray, memoryview, _Path], *, max_memory: int = ..., max_work: int = ...
) -> Animation: ...
def decode_frame(
    data: Union[bytes, bytearray, memoryview, _Path], t: int, *, max_memory: int = ..., max_work: int = ...
) -> npt.NDArray[np.float32]: ...
def info(
    data: Union[bytes, bytearray, memoryview, _Path], *, max_memory: int = ..., max_work: int = ...
) -> Dict[str, Any]: ...
def evaluate(
    reference: Union[_ArrayLike, Animation, _Path],
    candidate: Union[_ArrayLike, Animation, _Path],
    faces: Optional[_ArrayLike] = None,
    fps: Optional[float] = None,
    *,
    sted: bool = True,
    hausdorff: bool = True,
    **sted_options: Any,
) -> Dict[str, Any]: ...
def load(
    path: _Path,
    topology: Optional[_Path] = None,
    fps: Optional[float] = None,
    animation: Optional[str] = None,
    *,
    max_memory: int = ...,
    max_work: int = ...,
) -> Animation: ...
def save(path: _Path, animation: Animation, *, force: bool = False, topology_obj: bool = True) -> List[str]: ...
