"""Type stubs of ``animcodec.blocks`` (one animation encoded across a Dask cluster)."""

from os import PathLike
from typing import Any, Dict, Optional, Union

def parse_memory(memory: Union[int, str, None]) -> Optional[int]: ...
def block_plan(
    codec: str, vertices: int, frames: int, *, memory: Union[int, str, None] = None, **params: Any
) -> Dict[str, Any]: ...
def encode_distributed(
    source: Any,
    codec: str,
    *,
    client: Any = None,
    memory: Union[int, str, None] = None,
    topology: Optional[Union[str, PathLike[str]]] = None,
    fps: Optional[float] = None,
    **params: Any,
) -> bytes: ...
