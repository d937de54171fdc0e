"""Rate-distortion sweeps of many animations × codecs on a Dask ``distributed`` cluster.

One task per (input, series, ladder step): each task encodes the input at that step, decodes
the stream from its bytes alone, and measures it — through the same Rust function the
command line's ``animcodec sweep`` calls per point (``harness::sweep_point``), so the rows are
identical in keys and values (timings aside) to ``animcodec sweep INPUT --json``. Results
stream back as tasks finish; rows are then put in the command line's order (series, then
ladder step) and written with its writers (JSON, CSV, SVG).

How the work divides: the scheduler hands tasks to workers as they free up (no static split),
so a slow codec step does not hold back the others. A worker process keeps the last two inputs
it loaded in memory (tasks of the same input reuse them), and inputs given by path are read by
the workers themselves: on a multi-machine cluster every worker needs the files at the same
path (shared storage) and the ``animcodec`` package installed. Inputs given as arrays are sent
to the workers once (``client.scatter``).
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

from . import _native

#: File extensions :func:`corpus_inputs` collects from a directory.
CORPUS_EXTENSIONS = (".pc2", ".mdd", ".glb", ".gltf")


@dataclass
class SweepResult:
    """What :func:`sweep` gathered.

    Attributes:
        documents: per input (in the order given), the document ``animcodec sweep INPUT --json``
            writes: ``input``, ``vertices``, ``frames``, ``eval_options``, ``rows``, ``failures``,
            ``monotone``, ``total_seconds`` (the whole sweep's wall time), ``jobs`` (``"dask"``).
        jobs: number of tasks run.
        workers: number of Dask workers (threads) the sweep ran on.
        wall_seconds: wall time from the first submission to the last result.
    """

    documents: List[Dict[str, Any]] = field(default_factory=list)
    jobs: int = 0
    workers: int = 0
    wall_seconds: float = 0.0

    @property
    def rows(self) -> List[Dict[str, Any]]:
        """Every row of every input, each with the ``input`` it belongs to first."""
        return [{"input": d["input"], **row} for d in self.documents for row in d["rows"]]

    @property
    def failures(self) -> List[Dict[str, Any]]:
        """Every failed point, each with its ``input``."""
        return [{"input": d["input"], **f} for d in self.documents for f in d["failures"]]

    def summary(self) -> Dict[str, Any]:
        """Inputs, jobs, workers, wall time and jobs per second, as a dict."""
        return {
            "inputs": [d["input"] for d in self.documents],
            "jobs": self.jobs,
            "workers": self.workers,
            "wall_seconds": self.wall_seconds,
            "jobs_per_second": self.jobs / self.wall_seconds if self.wall_seconds > 0 else None,
            "failures": len(self.failures),
        }


# ------------------------------------------------------------------------------------------
# inputs and series


def corpus_inputs(paths: Iterable[Union[str, "os.PathLike[str]"]]) -> List[str]:
    """Animation files from files and directories: a directory contributes every ``.pc2``,
    ``.mdd``, ``.glb`` and ``.gltf`` below it (sorted); ``synth:`` names and files pass as given."""
    out: List[str] = []
    for p in paths:
        p = os.fspath(p)
        if os.path.isdir(p):
            found = []
            for root, _dirs, files in os.walk(p):
                found += [os.path.join(root, f) for f in files if f.lower().endswith(CORPUS_EXTENSIONS)]
            out += sorted(found)
        else:
            out.append(p)
    return out


def _input_list(inputs: Any) -> List[Tuple[str, Any]]:
    """``[(name, animation or None)]``: paths and ``synth:`` names load on the workers; an
    :class:`~animcodec.Animation` (alone, or as ``(name, animation)``) travels as arrays."""
    from . import Animation

    if isinstance(inputs, (str, os.PathLike, Animation)) or (
        isinstance(inputs, tuple) and len(inputs) == 2 and isinstance(inputs[1], Animation)
    ):
        inputs = [inputs]
    elif not isinstance(inputs, (list, tuple)):
        inputs = [inputs]  # reported below as an input of the wrong kind
    out: List[Tuple[str, Any]] = []
    for i, item in enumerate(inputs):
        if isinstance(item, Animation):
            out.append((f"array:{i}", item))
        elif isinstance(item, tuple) and len(item) == 2 and isinstance(item[1], Animation):
            out.append((str(item[0]), item[1]))
        elif isinstance(item, (str, os.PathLike)):
            out.append((os.fspath(item), None))
        else:
            raise TypeError(f"input {i}: expected a path, 'synth:NAME', an Animation or (name, Animation); got {item!r}")
    names = [n for n, _ in out]
    if len(set(names)) != len(names):
        raise ValueError(f"inputs are given twice: {sorted({n for n in names if names.count(n) > 1})}")
    if not out:
        raise ValueError("no inputs to sweep")
    return out


def _animation_selector(animation: Optional[Union[str, int]]) -> Optional[str]:
    """A glTF animation picked by name (``str``) or index (``int``), as ``--animation`` takes it."""
    if animation is None:
        return None
    if isinstance(animation, bool) or not isinstance(animation, (str, int)):
        raise TypeError(f"animation must be a name (str) or an index (int); got {animation!r}")
    if isinstance(animation, int) and animation < 0:
        raise ValueError(f"animation index must be >= 0; got {animation}")
    return str(animation)


def _typed(codec: Dict[str, Any], key: str, text: str) -> Any:
    """A ``key=value`` string typed by the codec's parameter kind (unknown keys pass as text
    and the library names them)."""
    spec = next((p for p in codec["params"] if p["name"] == key), None)
    kind = spec["kind"] if spec else "choice"
    try:
        if kind == "int":
            return int(text)
        if kind == "float":
            return float(text)
        if kind == "bool":
            if text.strip().lower() not in ("true", "false"):
                raise ValueError
            return text.strip().lower() == "true"
    except ValueError:
        raise ValueError(f"{codec['name']}: parameter '{key}': '{text}' is not a {kind}") from None
    return text.strip()


def _pairs(codec: Dict[str, Any], pairs: Sequence[str]) -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    for pair in pairs:
        if "=" not in pair:
            raise ValueError(f"{codec['name']}: parameter '{pair}' is not of the form key=value")
        k, v = pair.split("=", 1)
        out[k.strip()] = _typed(codec, k.strip(), v)
    return out


def _series_list(codecs: Any, params: Optional[Dict[str, Any]], series: Optional[Sequence[Any]]) -> List[Tuple[str, Optional[Dict[str, Any]]]]:
    """The command line's ``-c a,b -p k=v --series codec:k=v,…`` as ``[(codec, params)]``."""
    registered = {c["name"]: c for c in _native.codecs()}
    if isinstance(codecs, str):
        codecs = [c.strip() for c in codecs.split(",") if c.strip()]
    out: List[Tuple[str, Optional[Dict[str, Any]]]] = []
    if codecs:
        plain = list(codecs)
    elif not series:
        plain = list(registered)
    else:
        plain = []
    if params and not plain:
        raise ValueError("params apply to the codecs of `codecs`; with only `series`, put the parameters in each series")
    for name in plain:
        out.append((str(name), dict(params) if params else None))
    for s in series or []:
        if isinstance(s, str):
            name, _, rest = s.partition(":")
            name = name.strip()
            codec = registered.get(name)
            pairs = [p.strip() for p in rest.split(",") if p.strip()]
            out.append((name, _pairs(codec, pairs) if codec and pairs else None))
        else:
            name, p = s
            out.append((str(name), dict(p) if p else None))
    return out


def _eval_dict(sted: bool, hausdorff: bool, sted_options: Optional[Dict[str, Any]]) -> Dict[str, Any]:
    return {"sted": bool(sted), "hausdorff": bool(hausdorff), **(sted_options or {})}


# ------------------------------------------------------------------------------------------
# the task


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
) -> Dict[str, Any]:
    """One sweep task (runs on a worker): ``{"row", "vertices", "frames"}``, or ``{"error"}``
    with the library's message when the point (or loading the input) fails. ``animation`` is
    an :class:`~animcodec.Animation` given as arrays (or ``None``: load ``input_name``);
    ``gltf_animation`` picks a glTF file's animation by name or index."""
    from ._native import AnimcodecError

    from . import _faces, _positions

    # Arrays arrive deserialized by Dask (possibly read-only or with other strides): the
    # Python layer's checks make them what the extension takes, copying only if needed.
    arrays = None
    if animation is not None:
        arrays = (_positions(animation.positions), _faces(animation.faces), float(animation.fps))
    try:
        job = {
            "input": input_name,
            "codec": codec,
            "params": params,
            "step": int(step),
            "eval": eval_options,
            "topology": topology,
            "fps": fps,
            "animation": gltf_animation,
            "arrays": arrays,
        }
        return _native.sweep_point(job)
    except AnimcodecError as e:
        return {"error": str(e)}


# ------------------------------------------------------------------------------------------
# progress


class _Progress:
    """A one-line progress bar on stderr: done/total, elapsed, rate, last finished point."""

    def __init__(self, total: int, enabled: bool, stream=None):
        self.total, self.enabled, self.done = total, enabled, 0
        self.stream = stream or sys.stderr
        self.start = time.perf_counter()
        self._draw("")

    def _draw(self, last: str) -> None:
        if not self.enabled:
            return
        width = 30
        filled = int(width * self.done / self.total) if self.total else width
        elapsed = time.perf_counter() - self.start
        rate = self.done / elapsed if elapsed > 0 else 0.0
        line = f"\r[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} jobs {elapsed:6.1f} s {rate:5.2f}/s {last}"
        self.stream.write(line[:160].ljust(100))
        self.stream.flush()

    def step(self, last: str) -> None:
        self.done += 1
        self._draw(last)

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()


# ------------------------------------------------------------------------------------------
# the sweep


def _client_for(client: Any, n_workers: Optional[int], threads_per_worker: int):
    """``(client, cleanup)``: the given Client, a Client on a scheduler address, or a new
    LocalCluster (process workers) that ``cleanup`` closes."""
    from distributed import Client, LocalCluster

    if client is None:
        n = n_workers or os.cpu_count() or 1
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=threads_per_worker, processes=True, dashboard_address=None
        )
        c = Client(cluster)

        def cleanup() -> None:
            c.close()
            cluster.close()

        return c, cleanup
    if isinstance(client, str):
        c = Client(client)
        return c, c.close
    return client, lambda: None


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
) -> SweepResult:
    """Sweeps every input × series × ladder step on a Dask cluster.

    Args:
        inputs: a path, ``synth:NAME[:SIZE]``, an :class:`~animcodec.Animation`,
            ``(name, Animation)``, or a list of these.
        codecs: codec names (list or ``"a,b"``); default every registered codec (unless
            ``series`` is given), as ``animcodec sweep -c``.
        points: ladder points per series, spread evenly with both ends (default: every step),
            as ``--points``.
        params: parameters for every codec of ``codecs`` (as ``-p``); the ladder's own
            parameter may not be set.
        series: extra curves, ``"codec:k=v,…"`` strings or ``(codec, {k: v})`` (as ``--series``).
        client: a ``distributed.Client``, a scheduler address (``"tcp://host:8786"``), or
            ``None`` for a new ``LocalCluster`` with ``n_workers`` process workers (default: the
            number of cores) of ``threads_per_worker`` threads, closed at the end.
        sted, hausdorff, sted_options: metrics to compute and STED's parameters (as ``eval``).
        topology, fps: as ``--topology``, ``--fps`` for every path input.
        animation: a glTF input's animation, by name or index (as ``--animation``; default the
            first); for every path input (files without animations ignore it, as the command
            line does).
        json, csv, plot: with one input, the files ``animcodec sweep --json/--csv/--plot``
            writes (same writers). With several inputs use ``out_dir``.
        out_dir: one ``NAME.json``, ``NAME.csv``, ``NAME.svg`` per input (``NAME`` from the
            file name) and ``corpus.json`` (every document and the run's summary).
        force: replace existing output files (otherwise they are refused before the sweep).
        progress: show a progress bar on stderr (default: when stderr is a terminal).

    Returns:
        A :class:`SweepResult`; its ``documents`` hold, per input, what
        ``animcodec sweep INPUT --json`` writes (rows in the same order, same values).
    """
    from . import AnimcodecError

    items = _input_list(inputs)
    gltf_animation = _animation_selector(animation)
    plan_series = _series_list(codecs, params, series)
    # Validates every series (codec, parameters, the walked one left out) before any work.
    plan = _native.sweep_plan(plan_series, points)
    eval_options = _eval_dict(sted, hausdorff, sted_options)

    outputs: List[Tuple[int, Optional[str], Optional[str], Optional[str]]] = []
    if len(items) > 1 and (json or csv or plot):
        raise ValueError("json/csv/plot name one input's files; with several inputs use out_dir")
    if json or csv or plot:
        outputs.append((0, json, csv, plot))
    corpus_json = None
    if out_dir:
        os.makedirs(out_dir, exist_ok=True)
        stems = _output_stems([n for n, _ in items])
        for i, stem in enumerate(stems):
            base = os.path.join(out_dir, stem)
            outputs.append((i, base + ".json", base + ".csv", base + ".svg"))
        corpus_json = os.path.join(out_dir, "corpus.json")
    paths = [p for o in outputs for p in o[1:] if p] + ([corpus_json] if corpus_json else [])
    _native.check_outputs(paths, [n for n, a in items if a is None and not n.startswith("synth:")], force)

    dask_client, cleanup = _client_for(client, n_workers, threads_per_worker)
    try:
        workers = sum(dask_client.nthreads().values())
        scattered = {}
        for i, (name, animation) in enumerate(items):
            if animation is not None:
                scattered[i] = dask_client.scatter(animation, broadcast=False)
        tasks = []
        for i, (name, animation) in enumerate(items):
            for s, entry in enumerate(plan):
                codec, base = plan_series[s]
                for step in entry["steps"]:
                    tasks.append((i, s, step, codec, base))
        bar = _Progress(len(tasks), sys.stderr.isatty() if progress is None else progress)
        start = time.perf_counter()
        futures = {}
        for i, s, step, codec, base in tasks:
            name = items[i][0]
            future = dask_client.submit(
                run_job, name, codec, base, step, eval_options, topology, fps, scattered.get(i),
                gltf_animation, pure=False, key=f"animcodec-{i}-{s}-{step}-{time.monotonic_ns()}",
            )
            futures[future] = (i, s, step)
        from distributed import as_completed

        results: Dict[Tuple[int, int, int], Dict[str, Any]] = {}
        for future, result in as_completed(list(futures), with_results=True):
            i, s, step = futures[future]
            results[(i, s, step)] = result
            label = plan[s]["series"]
            if "row" in result:
                r = result["row"]
                last = f"{label} {r['ladder_param']}={r['params'].get(r['ladder_param'])}: {r['bpvf']:.3f} bpvf"
            else:
                last = f"{label} step {step}: FAILED"
            bar.step(last)
        wall = time.perf_counter() - start
        bar.close()
    finally:
        cleanup()

    documents = []
    for i, (name, _animation) in enumerate(items):
        rows, failures, dims = [], [], None
        for s, entry in enumerate(plan):
            for step in entry["steps"]:
                r = results[(i, s, step)]
                if "row" in r:
                    rows.append(r["row"])
                    dims = (r["vertices"], r["frames"])
                else:
                    failures.append(
                        {"codec": entry["codec"], "series": entry["series"], "ladder_index": step, "error": r["error"]}
                    )
        if dims is None and items[i][1] is not None:
            dims = (items[i][1].vertices, items[i][1].frames)
        files = next(((j, c, p) for k, j, c, p in outputs if k == i), (None, None, None))
        json_path, csv_path, plot_path = files
        doc = _native.sweep_document(
            {
                "input": name,
                "vertices": dims[0] if dims else 0,
                "frames": dims[1] if dims else 0,
                "rows": rows,
                "failures": failures,
                "eval": eval_options,
                "total_seconds": wall,
                "jobs": "dask",
                "json": json_path,
                "csv": csv_path,
                "plot": plot_path,
            }
        )
        if dims is None:
            doc["vertices"] = doc["frames"] = None
        documents.append(doc)
    result = SweepResult(documents=documents, jobs=len(tasks), workers=workers, wall_seconds=wall)
    if corpus_json:
        import json as _json

        text = _json.dumps({"summary": result.summary(), "documents": documents}, indent=2) + "\n"
        tmp = corpus_json + ".tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, corpus_json)
    return result


def _output_stems(names: Sequence[str]) -> List[str]:
    """File stems for per-input outputs: the file name without extension (``synth:flag`` →
    ``synth-flag``), numbered when two inputs share one."""
    stems = []
    for n in names:
        base = os.path.basename(n.rstrip("/\\")) or n
        stem = os.path.splitext(base)[0] if not n.startswith("synth:") else n.replace(":", "-")
        stems.append(stem.replace(":", "-") or "input")
    out = []
    for i, s in enumerate(stems):
        out.append(s if stems.count(s) == 1 else f"{s}-{i}")
    return out


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
    progress: Optional[Any] = None,
) -> Dict[str, Any]:
    """The command line's single-process sweep of one input (the same harness call as
    ``animcodec sweep INPUT --json``, in this process): the sweep document.

    ``input`` is a path, ``synth:NAME[:SIZE]``, an :class:`~animcodec.Animation` or
    ``(name, Animation)`` (the document's ``input`` is then the name, ``array:0`` for a bare
    animation), as for :func:`sweep`. ``topology``, ``fps`` and ``animation`` (a glTF file's
    animation by name or index, default the first) apply to a path, as the command line's
    ``--topology``, ``--fps``, ``--animation``. ``jobs=1`` measures the points one after another,
    ``None`` on all cores. ``progress``, if given, is called with ``{"event":
    "started"|"finished", "series", "ladder_index", "done", "total"}`` as each point starts and
    finishes (from the sweep's worker threads, the GIL taken for the call; the sweep itself runs
    with the GIL released). An exception ``progress`` raises stops the sweep and is raised
    here."""
    from . import _faces, _positions

    items = _input_list(input)
    if len(items) != 1:
        raise ValueError(f"sweep_local sweeps one input; got {len(items)} (use sweep() for several)")
    name, given = items[0]
    if given is not None and (topology is not None or fps is not None or animation is not None):
        raise ValueError("topology, fps and animation apply to a file input, not to an Animation")
    arrays = None
    if given is not None:
        arrays = (_positions(given.positions), _faces(given.faces), float(given.fps))
    return _native.sweep_local(
        {
            "input": name,
            "arrays": arrays,
            "animation": _animation_selector(animation),
            "series": _series_list(codecs, params, series),
            "points": points,
            "eval": _eval_dict(sted, hausdorff, sted_options),
            "jobs": jobs,
            "topology": topology,
            "fps": fps,
            "progress": progress,
        }
    )


# ------------------------------------------------------------------------------------------
# command line: python -m animcodec.sweep


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m animcodec.sweep CORPUS_DIR_OR_FILES... [-c a,b] [--points N] [--scheduler ADDR]``."""
    import argparse
    import json as _json

    parser = argparse.ArgumentParser(
        prog="python -m animcodec.sweep",
        description="Rate-distortion sweep of a corpus (every .pc2/.mdd/.glb/.gltf under the given "
        "directories, or the given files / synth:NAME inputs) × codecs × ladder steps on a Dask cluster: "
        "one task per point, rows identical to `animcodec sweep INPUT --json`.",
    )
    parser.add_argument("inputs", nargs="+", help="directories, animation files or synth:NAME[:SIZE]")
    parser.add_argument("-c", "--codecs", default=None, help="comma-separated codecs (default: all)")
    parser.add_argument("-p", "--param", action="append", default=[], help="key=value for every codec of -c")
    parser.add_argument("--series", action="append", default=[], help="CODEC:key=value,... (repeatable)")
    parser.add_argument("--points", type=int, default=None, help="ladder points per series (default: all)")
    parser.add_argument("--scheduler", default=None, help="Dask scheduler address, e.g. tcp://host:8786 "
                        "(default: a LocalCluster on this machine)")
    parser.add_argument("--workers", type=int, default=None, help="LocalCluster worker processes (default: cores)")
    parser.add_argument("--threads-per-worker", type=int, default=1)
    parser.add_argument("--out", default=None, help="directory for NAME.json/.csv/.svg per input and corpus.json")
    parser.add_argument("--json", default=None, help="one input: its sweep JSON (as animcodec sweep --json)")
    parser.add_argument("--csv", default=None, help="one input: its CSV")
    parser.add_argument("--plot", default=None, help="one input: its SVG plot")
    parser.add_argument("--topology", default=None, help="OBJ giving the triangles of PC2/MDD inputs")
    parser.add_argument("--fps", type=float, default=None)
    parser.add_argument("--animation", default=None, help="glTF inputs: the animation to sweep, by name or index "
                        "(default: the first)")
    parser.add_argument("--no-sted", action="store_true")
    parser.add_argument("--no-hausdorff", action="store_true")
    parser.add_argument("-f", "--force", action="store_true", help="replace existing outputs")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)

    from . import AnimcodecError

    inputs = corpus_inputs(args.inputs)
    params = None
    if args.param:
        names = [c.strip() for c in args.codecs.split(",")] if args.codecs else [c["name"] for c in _native.codecs()]
        registered = {c["name"]: c for c in _native.codecs()}
        typed = [_pairs(registered[n], args.param) if n in registered else {} for n in names]
        if any(t != typed[0] for t in typed):
            parser.error("-p values type differently for the codecs of -c; use --series per codec")
        params = typed[0]
    try:
        result = sweep(
            inputs, args.codecs, points=args.points, params=params, series=args.series or None,
            client=args.scheduler, n_workers=args.workers, threads_per_worker=args.threads_per_worker,
            sted=not args.no_sted, hausdorff=not args.no_hausdorff, topology=args.topology, fps=args.fps,
            animation=args.animation, json=args.json, csv=args.csv, plot=args.plot, out_dir=args.out, force=args.force,
            progress=not args.no_progress,
        )
    except (AnimcodecError, ValueError, TypeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    s = result.summary()
    for d in result.documents:
        print(f"{d['input']}: {d['frames']} frames × {d['vertices']} vertices; {len(d['rows'])} points")
    print(
        f"{s['jobs']} jobs on {s['workers']} workers in {s['wall_seconds']:.2f} s "
        f"({s['jobs_per_second']:.3f} jobs/s); {s['failures']} failed"
    )
    for f in result.failures:
        print(f"  {f['input']}: {f['series']} step {f['ladder_index']}: FAILED: {f['error']}", file=sys.stderr)
    return 0 if not result.failures else 2
