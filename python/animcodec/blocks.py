"""One animation encoded across a Dask cluster, block by block (issue 30).

Codecs whose packets are coded from independent temporal blocks — ``quant-delta`` (its
``block`` frames per packet), ``hosvd`` (its ``block``, or the budget's blocks with
``memory``) and ``pca-aoi`` with ``mode="svd"`` — can code each block on another worker. The
split depends on the parameters alone (:func:`block_plan`); every worker codes its block
with the encoder the whole encode would make and runs the encoder's self-check on it (decoded,
finite, within the bound the codec declares for those frames); the client writes the header,
the packets in frame order and the index. The result equals, byte for byte, the local encode
with the same parameters (``animcodec.encode(..., **plan["params"])``, or
``animcodec encode INPUT -c CODEC -p ... --memory M`` for a cache file).

Inputs: an :class:`~animcodec.Animation` (each block's frames are sent to its task), or the
path of a ``.pc2``/``.mdd`` cache that every worker reads at the same path (shared storage):
a worker reads only its block's frames, so the client never holds the animation.
"""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

from . import _native

PathLike = Union[str, "os.PathLike[str]"]

_UNITS = {"": 0, "b": 0, "k": 10, "kb": 10, "kib": 10, "m": 20, "mb": 20, "mib": 20, "g": 30, "gb": 30,
          "gib": 30, "t": 40, "tb": 40, "tib": 40}


def parse_memory(memory: Union[int, str, None]) -> Optional[int]:
    """A byte count as ``animcodec encode --memory`` reads it: an int, or ``"512M"``, ``"4G"``
    (binary units K, M, G, T)."""
    if memory is None:
        return None
    if isinstance(memory, bool):
        raise TypeError("memory must be a byte count (int) or a string like '4G'")
    if isinstance(memory, int):
        if memory <= 0:
            raise ValueError(f"memory must be positive; got {memory}")
        return memory
    text = str(memory).strip()
    digits = len(text) - len(text.lstrip("0123456789"))
    number, unit = text[:digits], text[digits:].strip().lower()
    if not number or unit not in _UNITS:
        raise ValueError(f"'{memory}' is not a byte count like 512M or 4G")
    value = int(number) << _UNITS[unit]
    if value <= 0:
        raise ValueError(f"'{memory}' is out of range")
    return value


def block_plan(codec: str, vertices: int, frames: int, *, memory: Union[int, str, None] = None,
               **params: Any) -> Dict[str, Any]:
    """How ``codec`` at ``params`` (the rest at their defaults; fitted to ``memory`` as
    ``encode --memory`` does) splits ``frames`` × ``vertices`` into independently coded blocks:
    ``{"params": {...} (complete), "block": frames per block, "blocks": count}``.

    Raises:
        AnimcodecError: a codec (or mode) whose packets depend on earlier frames, e.g. ``sac``,
            ``stseg``, ``pca-aoi`` with ``mode`` baoi/qaoi.
    """
    return _native.block_plan(str(codec), int(vertices), int(frames), params or None, parse_memory(memory))


def _encode_array_block(positions: np.ndarray, faces: np.ndarray, codec: str, fps: float,
                        params: Dict[str, Any], frames: int, index: int) -> List[Tuple[int, int, bool, bytes]]:
    from . import _faces, _positions

    # Arrays deserialized by Dask may be unaligned: both helpers copy those (only those).
    return _native.encode_block(_positions(positions), _faces(faces), codec, fps, params, frames, index)


def _encode_file_block(path: str, codec: str, params: Dict[str, Any], index: int, topology: Optional[str],
                       fps: Optional[float]) -> List[Tuple[int, int, bool, bytes]]:
    return _native.encode_block_file(path, codec, params, index, topology, fps)


def encode_distributed(
    source: Any,
    codec: str,
    *,
    client: Any = None,
    memory: Union[int, str, None] = None,
    topology: Optional[PathLike] = None,
    fps: Optional[float] = None,
    **params: Any,
) -> bytes:
    """Encodes one animation by independent temporal blocks on a Dask cluster and returns the
    ``.anim`` bytes — equal to the local encode with the same (fitted) parameters.

    Args:
        source: an :class:`~animcodec.Animation`, or the path of a ``.pc2``/``.mdd`` cache
            that every worker can read at that path.
        codec: ``quant-delta``, ``hosvd`` or ``pca-aoi`` (with ``mode="svd"``).
        client: a ``distributed.Client`` (a ``LocalCluster``'s, or one connected to a
            scheduler address); ``None`` codes the blocks one after another in this process.
        memory: the budget ``encode --memory`` takes (``"4G"`` or bytes): hosvd with
            ``block=0`` then codes blocks that fit it, as the local encode does.
        topology: for a cache path, the OBJ giving its triangles (default: beside the cache).
        fps: frame rate (a cache path: as ``animcodec encode --fps``; an Animation: overrides
            its own).
        **params: codec parameters; the rest take their defaults (no quality search).

    Raises:
        AnimcodecError: a codec whose blocks are not independent, bad parameters, a block
            whose self-check fails (nothing is returned then).
    """
    from . import Animation, _faces, _fps

    codec = str(codec)
    if isinstance(source, Animation):
        positions, faces = source.positions, _faces(source.faces)
        rate = _fps(source.fps if fps is None else fps)
        vertices, frames = int(positions.shape[1]), int(positions.shape[0])
        path = None
    elif isinstance(source, (str, os.PathLike)):
        path = os.fspath(source)
        topo = None if topology is None else os.fspath(topology)
        vertices, frames, rate, faces = _native.cache_header(path, topo, None if fps is None else _fps(fps))
    else:
        raise TypeError(f"source must be an Animation or a .pc2/.mdd path; got {type(source).__name__}")

    plan = block_plan(codec, vertices, frames, memory=memory, **params)
    full = plan["params"]
    block = plan["block"]
    if path is None:
        jobs = [(_encode_array_block, positions[i * block:(i + 1) * block], faces, codec, rate, full, frames, i)
                for i in range(plan["blocks"])]
    else:
        jobs = [(_encode_file_block, path, codec, full, i, topo, None if fps is None else float(rate))
                for i in range(plan["blocks"])]
    if client is None:
        results = [job[0](*job[1:]) for job in jobs]
    else:
        if path is None:
            # The topology travels once to every worker, not once per task.
            shared = client.scatter(faces, broadcast=True)
            jobs = [(f, pos, shared, *rest) for (f, pos, _faces_arg, *rest) in jobs]
        # pure=False: identical blocks (a still animation) are still separate tasks.
        futures = [client.submit(job[0], *job[1:], pure=False) for job in jobs]
        results = client.gather(futures)
    packets = [p for block_packets in results for p in block_packets]
    return _native.assemble_blocks(faces, vertices, codec, rate, full, frames, packets)
