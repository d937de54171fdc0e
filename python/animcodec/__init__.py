"""animcodec: compression of 3D mesh animations from Python.

A mesh animation here is a vertex cache: one triangle list ``faces[T, 3]`` and vertex
positions ``positions[F, V, 3]`` that change every frame. This package wraps the Rust library
behind the ``animcodec`` command line (the same codecs, container, metrics, file formats and
sweep harness), so every number it returns is the one the command line prints.

>>> import animcodec
>>> anim = animcodec.load("samba/samba.pc2")                 # Animation(positions, faces, fps)
>>> stream = animcodec.encode(anim.positions, anim.faces, "hosvd", fps=anim.fps, ss=0.95)
>>> back = animcodec.decode(stream)
>>> animcodec.evaluate(anim, back)["kg"]

Arrays: positions may be float32 or float64 (converted to float32), faces any integer type
(converted to uint32); non-contiguous arrays are copied once. Errors of the library raise
:class:`AnimcodecError` with the Rust message; bad shapes or dtypes raise ``ValueError`` /
``TypeError`` before anything runs. Encoding, decoding and evaluation release the GIL.

:func:`sweep` runs rate-distortion sweeps of many animations × codecs on a Dask cluster
(``python -m animcodec.sweep CORPUS_DIR --scheduler tcp://host:8786``).
"""

from __future__ import annotations

import numbers
import os
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native
from ._native import AnimcodecError

__all__ = [
    "AnimcodecError",
    "Animation",
    "TargetEncoding",
    "codecs",
    "codec_names",
    "encode",
    "encode_to_target",
    "DEFAULT_TARGET",
    "decode",
    "decode_frame",
    "DEFAULT_MAX_MEMORY",
    "DEFAULT_MAX_WORK",
    "info",
    "evaluate",
    "load",
    "save",
    "sweep",
    "sweep_local",
    "SweepResult",
    "encode_distributed",
]

PathLike = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True)
class Animation:
    """A decoded or loaded animation.

    Attributes:
        positions: ``float32`` array of shape ``(frames, vertices, 3)``.
        faces: ``uint32`` array of shape ``(triangles, 3)`` (vertex indices).
        fps: frame rate.
    """

    positions: np.ndarray
    faces: np.ndarray
    fps: float

    @property
    def frames(self) -> int:
        """Number of frames."""
        return int(self.positions.shape[0])

    @property
    def vertices(self) -> int:
        """Vertices per frame."""
        return int(self.positions.shape[1])

    @property
    def triangles(self) -> int:
        """Number of triangles."""
        return int(self.faces.shape[0])

    def __repr__(self) -> str:
        return (
            f"Animation({self.frames} frames × {self.vertices} vertices, "
            f"{self.triangles} triangles, {self.fps:g} fps)"
        )


@dataclass(frozen=True)
class TargetEncoding:
    """What :func:`encode_to_target` found: the smallest stream meeting the target.

    Attributes:
        stream: the ``.anim`` container bytes.
        codec: the codec chosen.
        params: its parameters.
        reached: each bounded metric's value on the decoded stream (``{"kg": 0.43, "sted": 0.031}``).
        bpvf: bits per vertex per frame of the whole container.
        details: every point tried and the other codecs' best (as ``encode --target --json``).
    """

    stream: bytes
    codec: str
    params: Dict[str, Any]
    reached: Dict[str, Optional[float]]
    bpvf: float
    details: Dict[str, Any]


# ------------------------------------------------------------------------------------------
# array checks: clear errors before anything reaches Rust


def _positions(positions: Any, name: str = "positions") -> np.ndarray:
    """``positions`` as a C-contiguous float32 array of shape (F, V, 3), copying only if needed."""
    arr = np.asarray(positions)
    # Only the two float types the docs promise: integer coordinates (a quantized cache read
    # raw, an index array passed by mistake) would be taken as model units without a word.
    if arr.dtype not in (np.float32, np.float64):
        raise TypeError(f"{name} must be float32 or float64; got dtype {arr.dtype} (convert explicitly, e.g. .astype(np.float32))")
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"{name} must have shape (frames, vertices, 3); got {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"{name} must hold at least one frame and one vertex; got {arr.shape}")
    return np.require(arr, dtype=np.float32, requirements=["C_CONTIGUOUS", "ALIGNED"])


def _faces(faces: Any) -> np.ndarray:
    """``faces`` as a C-contiguous uint32 array of shape (T, 3)."""
    arr = np.asarray(faces)
    if arr.size == 0 and arr.ndim <= 2:
        return np.zeros((0, 3), dtype=np.uint32)
    if arr.dtype.kind not in "iu":
        raise TypeError(f"faces must hold integer vertex indices; got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"faces must have shape (triangles, 3); got {arr.shape}")
    if arr.dtype.kind == "i" and arr.size and int(arr.min()) < 0:
        raise ValueError(f"faces hold a negative vertex index ({int(arr.min())})")
    if arr.size and int(arr.max()) > np.iinfo(np.uint32).max:
        raise ValueError(f"faces hold a vertex index above 2^32 − 1 ({int(arr.max())})")
    return np.require(arr, dtype=np.uint32, requirements=["C_CONTIGUOUS", "ALIGNED"])


def _fps(fps: Any) -> float:
    value = float(fps)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"fps must be a finite positive number; got {fps!r}")
    return value


DEFAULT_MAX_MEMORY: int = _native.DEFAULT_MAX_MEMORY
"""Most bytes a decode may hold in total by default (1 GiB): the command line's ``--max-memory``
default. Streams needing more are refused before allocating."""

DEFAULT_MAX_WORK: int = _native.DEFAULT_MAX_WORK
"""Most arithmetic operations a decode may spend by default: the command line's ``--max-work``
default. Streams needing more are refused before computing."""


def _limit(value: Any, name: str) -> int:
    """A positive integer limit (``max_memory`` bytes, ``max_work`` operations)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an int; got {type(value).__name__}")
    if int(value) < 1:
        raise ValueError(f"{name} must be at least 1; got {value}")
    return int(value)


def _stream(data: Any) -> Union[bytes, str]:
    """Container bytes from bytes-like data, or the path of an ``.anim`` file as a string: a
    file is read by the decoder as it goes, within its limits (never read whole first: a path
    such as ``/dev/zero`` is refused at its first bytes)."""
    if isinstance(data, (str, os.PathLike)):
        path = os.fspath(data)
        return path if isinstance(path, str) else os.fsdecode(path)
    if isinstance(data, bytes):
        return data
    if isinstance(data, (bytearray, memoryview)):
        return bytes(data)
    raise TypeError(f"expected .anim bytes or a path; got {type(data).__name__}")


def _split(animation_or_positions: Any, faces: Any, fps: Any) -> Tuple[np.ndarray, np.ndarray, float]:
    if isinstance(animation_or_positions, Animation):
        a = animation_or_positions
        return a.positions, a.faces if faces is None else _faces(faces), a.fps if fps is None else _fps(fps)
    if faces is None:
        raise TypeError("faces are required when positions are given as an array")
    return _positions(animation_or_positions), _faces(faces), _fps(30.0 if fps is None else fps)


def _animation(result: Tuple[np.ndarray, np.ndarray, float]) -> Animation:
    positions, faces, fps = result
    return Animation(positions, faces, float(fps))


# ------------------------------------------------------------------------------------------
# the API


def codecs() -> List[Dict[str, Any]]:
    """Every registered codec, as ``animcodec list --json`` prints it.

    Each entry: ``name``, ``fourcc``, ``stream_version``, ``summary``, ``params`` (each with
    ``name``, ``kind`` (int/float/bool/choice), ``default``, ``min``/``max`` or ``choices``,
    ``doc``) and ``rate_ladder`` (``param`` and its ``steps``, smallest stream first).
    """
    return _native.codecs()


def codec_names() -> List[str]:
    """Names of the registered codecs, in registry order."""
    return [c["name"] for c in _native.codecs()]


DEFAULT_TARGET = "kg=0.5"
"""The quality :func:`encode` aims at when given no parameters (``animcodec encode`` without
``-p``): KG ≤ 0.5 %."""


def encode(
    positions: Any,
    faces: Any,
    codec: str,
    fps: float = 30.0,
    *,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    **params: Any,
) -> bytes:
    """Encodes an animation into ``.anim`` container bytes.

    Without parameters, aims at the default quality (:data:`DEFAULT_TARGET`): the smallest
    stream meeting it over the codec's declared parameter space (``codec="auto"``: every
    codec's), as ``animcodec encode INPUT -c CODEC`` does. With parameters, exactly those.

    Args:
        positions: ``(frames, vertices, 3)`` array (float32 or float64).
        faces: ``(triangles, 3)`` integer array.
        codec: a name from :func:`codec_names` (``quant-delta``, ``pca-aoi``, ``hosvd``, ...)
            or ``"auto"`` (without parameters).
        fps: frame rate stored in the stream.
        progress: called during the search with each measured point, a dict
            ``{codec, params, bytes, bpvf, kg}`` (possibly from another thread). An exception
            it raises stops the search and is raised by ``encode``.
        **params: codec parameters (``bits=12``, ``ss=0.95``, ...); the rest take their defaults.

    Raises:
        AnimcodecError: unknown codec or parameter, value out of range, non-finite coordinates.
    """
    return _native.encode(_positions(positions), _faces(faces), str(codec), _fps(fps), params or None, progress)


_TARGET_METRICS = ("kg", "sted", "hausdorff", "max_error", "rmse")


def encode_to_target(
    positions: Any,
    faces: Any,
    codec: str = "auto",
    fps: float = 30.0,
    *,
    kg: Optional[float] = None,
    sted: Optional[float] = None,
    hausdorff: Optional[float] = None,
    max_error: Optional[float] = None,
    rmse: Optional[float] = None,
    refine: int = 0,
    ladder: bool = False,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    **params: Any,
) -> TargetEncoding:
    """The smallest stream whose decoded error meets a target: one bound (``kg=0.5``) or several
    at once (``kg=0.5, sted=0.05``: a joint target, every bound met).

    Searches the codec's declared parameter space (its rate ladder on every configuration of
    its secondary parameters; those given in ``params`` stay fixed) as
    ``animcodec encode -c CODEC --target kg=0.5`` does; ``ladder=True`` walks the rate ladder
    alone (``--ladder``). ``codec="auto"`` searches every codec and keeps the smallest
    stream; ``refine`` bisects the ladder parameter further; ``progress`` is called with
    every measured point (a dict, possibly from another thread; an exception it raises stops
    the search and is raised here).

    Raises:
        AnimcodecError: no point meets the target (the message gives the best reached).
    """
    given = {k: v for k, v in zip(_TARGET_METRICS, (kg, sted, hausdorff, max_error, rmse)) if v is not None}
    if not given:
        raise ValueError(f"give at least one target among {', '.join(_TARGET_METRICS)}")
    if int(refine) < 0:
        raise ValueError(f"refine must be ≥ 0; got {refine}")
    search = {
        "target": ",".join(f"{metric}={float(value)!r}" for metric, value in given.items()),
        "refine": int(refine),
        "params": params or None,
        "ladder": bool(ladder),
        "progress": progress,
    }
    stream, summary = _native.encode_to_target(_positions(positions), _faces(faces), str(codec), _fps(fps), search)
    return TargetEncoding(stream, summary["codec"], summary["params"], summary["reached"], summary["bpvf"], summary)


def decode(data: Any, *, max_memory: int = DEFAULT_MAX_MEMORY, max_work: int = DEFAULT_MAX_WORK) -> Animation:
    """Decodes ``.anim`` container bytes (or the file at a path) into an :class:`Animation`.

    The decoder needs nothing but the bytes; every byte is checked (corrupt or truncated
    streams raise :class:`AnimcodecError`, never crash). ``max_memory`` (bytes held in total)
    and ``max_work`` (arithmetic operations) bound the decode as the command line's
    ``--max-memory`` and ``--max-work`` do, with the same defaults: a stream needing more is
    refused before allocating or computing. A file is read as the decoder goes, never whole
    first.
    """
    result, _codec = _native.decode(_stream(data), _limit(max_memory, "max_memory"), _limit(max_work, "max_work"))
    return _animation(result)


def _frame_index(t: Any) -> int:
    """A frame number: an int (or numpy integer), never a float or a bool."""
    if isinstance(t, bool) or not isinstance(t, numbers.Integral):
        raise TypeError(f"frame index must be an int; got {type(t).__name__} {t!r}")
    if int(t) < 0:
        raise ValueError(f"frame index must be ≥ 0; got {t}")
    return int(t)


def decode_frame(
    data: Any, t: int, *, max_memory: int = DEFAULT_MAX_MEMORY, max_work: int = DEFAULT_MAX_WORK
) -> np.ndarray:
    """Frame ``t`` alone, ``(vertices, 3)`` float32, decoded from the nearest keyframe (limits
    as :func:`decode`). ``t`` must be an int: ``1.5`` raises ``TypeError``."""
    return _native.decode_frame(
        _stream(data), _frame_index(t), _limit(max_memory, "max_memory"), _limit(max_work, "max_work")
    )


def info(data: Any, *, max_memory: int = DEFAULT_MAX_MEMORY, max_work: int = DEFAULT_MAX_WORK) -> Dict[str, Any]:
    """What a container holds, as ``animcodec info --json`` prints it (every checksum verified;
    limits as :func:`decode`)."""
    return _native.info(_stream(data), _limit(max_memory, "max_memory"), _limit(max_work, "max_work"))


def _eval_dict(sted: bool, hausdorff: bool, sted_options: Dict[str, Any]) -> Dict[str, Any]:
    allowed = {"sted_radius", "sted_dt", "sted_window", "sted_c", "sted_absolute"}
    unknown = set(sted_options) - allowed
    if unknown:
        raise TypeError(f"unknown metric options {sorted(unknown)}; allowed: {sorted(allowed)}")
    return {"sted": bool(sted), "hausdorff": bool(hausdorff), **sted_options}


def evaluate(
    reference: Any,
    candidate: Any,
    faces: Any = None,
    fps: Optional[float] = None,
    *,
    sted: bool = True,
    hausdorff: bool = True,
    **sted_options: Any,
) -> Dict[str, Any]:
    """Every metric of ``candidate`` against ``reference``: the keys of ``animcodec eval --json``.

    ``reference`` and ``candidate`` are each a ``(frames, vertices, 3)`` array (then ``faces``
    is required), an :class:`Animation`, or a path (any format :func:`load` reads, ``.anim``
    streams decoded; the path is reported under ``reference``/``candidate`` as the command
    line does, arrays report ``None``). ``sted=False`` / ``hausdorff=False`` skip those metrics;
    ``sted_radius``, ``sted_dt``, ``sted_window``, ``sted_c``, ``sted_absolute`` set STED's
    parameters (defaults: the metric author's tool's).

    Returns a dict with ``kg``, ``sted``, ``sted_spatial``, ``sted_temporal``, ``hausdorff``,
    ``hausdorff_mean``, ``hausdorff_relative``, ..., ``mse``, ``rmse``, ``max_error``,
    ``sted_params``, ``bbox_diagonal``, ``vertices``, ``frames``, ``notes``,
    ``reference``, ``candidate``, ``eval_seconds``. Undefined metrics are ``None``.
    """
    names = []
    loaded = []
    for x in (reference, candidate):
        if isinstance(x, (str, os.PathLike)):
            names.append(os.fspath(x))
            loaded.append(load(x))
        else:
            names.append(None)
            loaded.append(x)
    ref, cand = loaded
    ref_pos, ref_faces, ref_fps = _split(ref, faces, fps)
    cand_pos, _, _ = _split(cand, ref_faces, ref_fps)
    if ref_pos.shape != cand_pos.shape:
        raise ValueError(
            f"reference and candidate differ in shape: {ref_pos.shape} vs {cand_pos.shape} (frames, vertices, 3)"
        )
    report = _native.evaluate(ref_pos, cand_pos, ref_faces, ref_fps, _eval_dict(sted, hausdorff, sted_options))
    report["reference"], report["candidate"] = names
    return report


def load(
    path: PathLike,
    topology: Optional[PathLike] = None,
    fps: Optional[float] = None,
    animation: Optional[str] = None,
    *,
    max_memory: int = DEFAULT_MAX_MEMORY,
    max_work: int = DEFAULT_MAX_WORK,
) -> Animation:
    """Reads an animation: an OBJ sequence (directory or ``*`` pattern), ``.obj``, ``.pc2``,
    ``.mdd``, ``.gltf``/``.glb`` (morph targets, node animation and skins: the whole scene
    sampled into one vertex cache; ``animation`` picks one by name or index, default the
    first), an ``.anim`` stream (decoded), or
    ``synth:NAME[:SIZE]`` (flag, cylinder, tumble, phases). A PC2/MDD cache takes its triangles
    from ``topology`` or the ``.obj`` of the same stem beside it; ``fps`` overrides the file's rate.
    ``max_memory`` and ``max_work`` bound the decode of an ``.anim`` stream as in :func:`decode`.
    """
    return _animation(
        _native.load(
            os.fspath(path),
            None if topology is None else os.fspath(topology),
            None if fps is None else _fps(fps),
            None if animation is None else str(animation),
            _limit(max_memory, "max_memory"),
            _limit(max_work, "max_work"),
        )
    )


def save(path: PathLike, animation: Animation, *, force: bool = False, topology_obj: bool = True) -> List[str]:
    """Writes ``animation`` to ``path``: ``.pc2``, ``.mdd`` (with ``STEM.obj`` beside it unless
    ``topology_obj=False``), ``.glb``/``.gltf``, ``name.obj`` (an OBJ sequence) or a directory.

    Files are written atomically; an existing file is replaced only with ``force=True``.
    Returns the files written.
    """
    if not isinstance(animation, Animation):
        raise TypeError(f"save expects an Animation; got {type(animation).__name__}")
    written = _native.save(
        os.fspath(path), _positions(animation.positions), _faces(animation.faces), _fps(animation.fps),
        bool(force), bool(topology_obj),
    )
    return [os.fspath(p) for p in written]


from .distributed import SweepResult, sweep, sweep_local  # noqa: E402  (needs the names above)
from .blocks import encode_distributed  # noqa: E402  (issue 30: one animation across a cluster)
