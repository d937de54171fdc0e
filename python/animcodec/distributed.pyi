"""Type stubs of ``animcodec.distributed`` (Dask sweeps)."""

from os import PathLike
from typing import Any, Callable, Dict, Iterable, List, Optional, Sequence, Union

CORPUS_EXTENSIONS: tuple

class SweepResult:
    documents: List[Dict[str, Any]]
    jobs: int
    workers: int
    wall_seconds: float
    @property
    def rows(self) -> List[Dict[str, Any]]: ...
    @property
    def failures(self) -> List[Dict[str, Any]]: ...
    def summary(self) -> Dict[str, Any]: ...

def corpus_inputs(paths: Iterable[Union[str, PathLike[str]]]) -> List[str]: ...
def run_job(
    input_name: str,
    codec: str,
    params: Optional[Dict[str, Any]],
    step: int,
    eval_options: Dict[str, Any],
    topology: Optional[str] = None,
    fps: Optional[float] = None,
    animation: Any = None,
    gltf_animation: Optional[str] = None,
) -> Dict[str, Any]: ...
def sweep(
    inputs: Any,
    codecs: Any = None,
    *,
    points: Optional[int] = None,
    params: Optional[Dict[str, Any]] = None,
    series: Optional[Sequence[Any]] = None,
    client: Any = None,
    n_workers: Optional[int] = None,
    threads_per_worker: int = 1,
    sted: bool = True,
    hausdorff: bool = True,
    sted_options: Optional[Dict[str, Any]] = None,
    topology: Optional[str] = None,
    fps: Optional[float] = None,
    animation: Optional[Union[str, int]] = None,
    json: Optional[str] = None,
    csv: Optional[str] = None,
    plot: Optional[str] = None,
    out_dir: Optional[str] = None,
    force: bool = False,
    progress: Optional[bool] = None,
) -> SweepResult: ...
def sweep_local(
    input: Any,
    codecs: Any = None,
    *,
    points: Optional[int] = None,
    params: Optional[Dict[str, Any]] = None,
    series: Optional[Sequence[Any]] = None,
    jobs: Optional[int] = 1,
    sted: bool = True,
    hausdorff: bool = True,
    sted_options: Optional[Dict[str, Any]] = None,
    topology: Optional[str] = None,
    fps: Optional[float] = None,
    animation: Optional[Union[str, int]] = None,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
) -> Dict[str, Any]: ...
def main(argv: Optional[Sequence[str]] = None) -> int: ...
