"""Type stubs of the Rust extension ``animcodec._native`` (python/src/lib.rs).

These functions expect arrays already checked by the Python layer: positions float32
C-contiguous ``(F, V, 3)``, faces uint32 C-contiguous ``(T, 3)``. Use the functions of
``animcodec`` instead; they convert and check.
"""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

class AnimcodecError(Exception):
    """An error of the animcodec library; the message is the Rust library's."""

_F32 = npt.NDArray[np.float32]
_U32 = npt.NDArray[np.uint32]
_Path = Union[str, PathLike[str]]

def codecs() -> List[Dict[str, Any]]: ...
def encode(positions: _F32, faces: _U32, codec: str, fps: float, params: Optional[Dict[str, Any]] = None) -> bytes: ...
class TargetSearch(TypedDict):
    """What ``encode_to_target`` searches for (every key present)."""

    target: str
    refine: int
    params: Optional[Dict[str, Any]]
    ladder: bool
    progress: Optional[Callable[[Dict[str, Any]], None]]

def encode_to_target(
    positions: _F32, faces: _U32, codec: str, fps: float, search: TargetSearch
) -> Tuple[bytes, Dict[str, Any]]: ...
DEFAULT_MAX_MEMORY: int
DEFAULT_MAX_WORK: int

def decode(
    data: Union[bytes, str], max_memory: Optional[int] = None, max_work: Optional[int] = None
) -> Tuple[Tuple[_F32, _U32, float], str]: ...
def decode_frame(
    data: Union[bytes, str], t: int, max_memory: Optional[int] = None, max_work: Optional[int] = None
) -> _F32: ...
def info(data: Union[bytes, str], max_memory: Optional[int] = None, max_work: Optional[int] = None) -> Dict[str, Any]: ...
def evaluate(
    reference: _F32, candidate: _F32, faces: _U32, fps: float, options: Optional[Dict[str, Any]] = None
) -> Dict[str, Any]: ...
def load(
    path: str,
    topology: Optional[_Path] = None,
    fps: Optional[float] = None,
    animation: Optional[str] = None,
    max_memory: Optional[int] = None,
    max_work: Optional[int] = None,
) -> Tuple[_F32, _U32, float]: ...
def save(
    path: _Path, positions: _F32, faces: _U32, fps: float, force: bool = False, topology_obj: bool = True
) -> List[str]: ...
def sweep_plan(series: List[Tuple[str, Optional[Dict[str, Any]]]], points: Optional[int] = None) -> List[Dict[str, Any]]: ...
class SweepJob(TypedDict):
    """One sweep job (every key present)."""

    input: str
    codec: str
    params: Optional[Dict[str, Any]]
    step: int
    eval: Optional[Dict[str, Any]]
    topology: Optional[_Path]
    fps: Optional[float]
    animation: Optional[str]
    arrays: Optional[Tuple[_F32, _U32, float]]

def sweep_point(job: SweepJob) -> Dict[str, Any]: ...

class LocalSweep(TypedDict):
    """A single-process sweep of one input (every key present)."""

    input: str
    arrays: Optional[Tuple[_F32, _U32, float]]
    animation: Optional[str]
    series: List[Tuple[str, Optional[Dict[str, Any]]]]
    points: Optional[int]
    eval: Optional[Dict[str, Any]]
    jobs: Optional[int]
    topology: Optional[_Path]
    fps: Optional[float]
    progress: Optional[Any]

def sweep_local(sweep: LocalSweep) -> Dict[str, Any]: ...
def check_outputs(outputs: List[_Path], inputs: List[_Path], force: bool = False) -> None: ...
class GatheredSweep(TypedDict):
    """Gathered rows of one input and the files to write (every key present)."""

    input: str
    vertices: int
    frames: int
    rows: List[Dict[str, Any]]
    failures: List[Dict[str, Any]]
    eval: Optional[Dict[str, Any]]
    total_seconds: Optional[float]
    jobs: Any
    json: Optional[_Path]
    csv: Optional[_Path]
    plot: Optional[_Path]

def sweep_document(gathered: GatheredSweep) -> Dict[str, Any]: ...

# Issue 30: one animation encoded by independent temporal blocks (animcodec.blocks).
_Packet = Tuple[int, int, bool, bytes]
def block_plan(
    codec: str, vertices: int, frames: int, params: Optional[Dict[str, Any]] = None, memory: Optional[int] = None
) -> Dict[str, Any]: ...
def encode_block(
    positions: npt.NDArray[np.float32],
    faces: npt.NDArray[np.uint32],
    codec: str,
    fps: float,
    params: Dict[str, Any],
    frames: int,
    index: int,
) -> List[_Packet]: ...
def encode_block_file(
    path: _Path,
    codec: str,
    params: Dict[str, Any],
    index: int,
    topology: Optional[_Path] = None,
    fps: Optional[float] = None,
) -> List[_Packet]: ...
def cache_header(
    path: _Path, topology: Optional[_Path] = None, fps: Optional[float] = None
) -> Tuple[int, int, float, npt.NDArray[np.uint32]]: ...
def assemble_blocks(
    faces: npt.NDArray[np.uint32],
    vertices: int,
    codec: str,
    fps: float,
    params: Dict[str, Any],
    frames: int,
    packets: List[_Packet],
) -> bytes: ...
