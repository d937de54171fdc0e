"""Type stubs of the Rust extension ``animcodec._native`` (python/src/lib.rs).

These functions expect arrays already checked by the Python layer: positions float32
C-contiguous ``(F, V, 3)``, faces uint32 C-contiguous ``(T, 3)``. Use the functions of
``animcodec`` instead; they convert and check.
"""

from os import PathLike
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

class AnimcodecError(Exception):
    """An error of the animcodec library; the message is the Rust library's."""

_F32 = npt.NDArray[np.float32]
_U32 = npt.NDArray[np.uint32]
_Path = Union[str, PathLike[str]]

def codecs() -> List[Dict[str, Any]]: ...
def encode(positions: _F32, faces: _U32, codec: str, fps: float, params: Optional[Dict[str, Any]] = None) -> bytes: ...
def encode_to_target(
    positions: _F32,
    faces: _U32,
    codec: str,
    fps: float,
    target: str,
    refine: int = 0,
    params: Optional[Dict[str, Any]] = None,
) -> Tuple[bytes, Dict[str, Any]]: ...
def decode(data: bytes) -> Tuple[Tuple[_F32, _U32, float], str]: ...
def decode_frame(data: bytes, t: int) -> _F32: ...
def info(data: bytes) -> Dict[str, Any]: ...
def evaluate(
    reference: _F32, candidate: _F32, faces: _U32, fps: float, options: Optional[Dict[str, Any]] = None
) -> Dict[str, Any]: ...
def load(
    path: str, topology: Optional[_Path] = None, fps: Optional[float] = None, animation: Optional[str] = None
) -> Tuple[_F32, _U32, float]: ...
def save(
    path: _Path, positions: _F32, faces: _U32, fps: float, force: bool = False, topology_obj: bool = True
) -> List[str]: ...
def sweep_plan(series: List[Tuple[str, Optional[Dict[str, Any]]]], points: Optional[int] = None) -> List[Dict[str, Any]]: ...
def sweep_point(
    input: str,
    codec: str,
    params: Optional[Dict[str, Any]],
    step: int,
    eval: Optional[Dict[str, Any]] = None,
    topology: Optional[_Path] = None,
    fps: Optional[float] = None,
    arrays: Optional[Tuple[_F32, _U32, float]] = None,
) -> Dict[str, Any]: ...
def sweep_local(
    input: str,
    series: List[Tuple[str, Optional[Dict[str, Any]]]],
    points: Optional[int] = None,
    eval: Optional[Dict[str, Any]] = None,
    jobs: Optional[int] = 1,
    topology: Optional[_Path] = None,
    fps: Optional[float] = None,
) -> Dict[str, Any]: ...
def check_outputs(outputs: List[_Path], inputs: List[_Path], force: bool = False) -> None: ...
def sweep_document(
    input: str,
    vertices: int,
    frames: int,
    rows: List[Dict[str, Any]],
    failures: List[Dict[str, Any]],
    eval: Optional[Dict[str, Any]] = None,
    total_seconds: Optional[float] = None,
    jobs: Any = None,
    json: Optional[_Path] = None,
    csv: Optional[_Path] = None,
    plot: Optional[_Path] = None,
) -> Dict[str, Any]: ...
