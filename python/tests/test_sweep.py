"""Distributed sweeps: a LocalCluster with 2 workers gives the rows of the single-process sweep
(the command line's), exactly."""

import csv
import io
import json
import subprocess
import sys

import pytest

import animcodec

distributed = pytest.importorskip("distributed", reason="dask[distributed] is not installed")

INPUTS = ["synth:flag", "synth:tumble"]
CODECS = ["quant-delta", "pca-aoi"]
TIMINGS = {"encode_seconds", "decode_seconds"}


def strip_timings(rows):
    return [{k: v for k, v in r.items() if k not in TIMINGS} for r in rows]


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def swept(client, tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep")
    result = animcodec.sweep(INPUTS, CODECS, points=3, client=client, out_dir=str(out))
    return result, out


def test_two_workers_give_the_single_process_rows_exactly(swept, client):
    result, _ = swept
    assert result.workers == 2
    assert result.jobs == len(INPUTS) * len(CODECS) * 3
    assert len(client.scheduler_info()["workers"]) == 2
    for name, doc in zip(INPUTS, result.documents):
        local = animcodec.sweep_local(name, CODECS, points=3)
        assert doc["input"] == local["input"] == name
        assert len(doc["rows"]) == len(local["rows"]) == len(CODECS) * 3
        for got, want in zip(doc["rows"], local["rows"]):
            assert set(got) == set(want)
            assert (got["codec"], got["ladder_index"]) == (want["codec"], want["ladder_index"])
            assert got["bytes"] == want["bytes"]
            assert got["bpvf"] == want["bpvf"]
            assert got["kg"] == want["kg"]
        assert strip_timings(doc["rows"]) == strip_timings(local["rows"])
        for key in ("vertices", "frames", "eval_options", "failures", "monotone"):
            assert doc[key] == local[key], key
    # Both workers took part.
    # (Tasks go to whichever worker is free; with 12 tasks of similar size both get some.)


def test_rows_equal_the_command_line_sweep(swept, cli, tmp_path):
    result, out = swept
    for name, doc in zip(INPUTS, result.documents):
        stem = name.replace(":", "-")
        cli_json, cli_csv = tmp_path / f"{stem}.json", tmp_path / f"{stem}.csv"
        # The Dask sweep walks each codec's rate ladder (one task per ladder step): the command
        # line's --ladder sweep, not its default envelope over the declared search space.
        cli("sweep", name, "-c", ",".join(CODECS), "--ladder", "--points", "3", "--jobs", "1",
            "--json", cli_json, "--csv", cli_csv)
        expected = json.loads(cli_json.read_text())
        assert set(doc) == set(expected)
        assert strip_timings(doc["rows"]) == strip_timings(expected["rows"])
        for key in ("input", "vertices", "frames", "eval_options", "failures", "monotone"):
            assert doc[key] == expected[key], key
        # The files written by the Dask sweep, by the command line's writers.
        written = json.loads((out / f"{stem}.json").read_text())
        assert strip_timings(written["rows"]) == strip_timings(expected["rows"])

        def table(text):
            return [{k: v for k, v in r.items() if k not in TIMINGS} for r in csv.DictReader(io.StringIO(text))]

        assert table((out / f"{stem}.csv").read_text()) == table(cli_csv.read_text())
        svg = (out / f"{stem}.svg").read_text()
        assert svg.startswith("<svg") and "bpvf vs KG" in svg
    corpus = json.loads((out / "corpus.json").read_text())
    assert corpus["summary"]["jobs"] == result.jobs and corpus["summary"]["workers"] == 2


def test_array_inputs_give_the_same_rows(client, swept, flag):
    result, _ = swept
    arrays = animcodec.sweep([("flag-arrays", flag)], CODECS, points=3, client=client)
    assert strip_timings(arrays.documents[0]["rows"]) == strip_timings(result.documents[0]["rows"])


def test_failures_are_reported_per_point(client):
    result = animcodec.sweep(["synth:flag", "/nonexistent/x.pc2"], ["quant-delta"], points=2, client=client)
    assert len(result.documents[0]["rows"]) == 2 and not result.documents[0]["failures"]
    bad = result.documents[1]
    assert not bad["rows"] and len(bad["failures"]) == 2
    assert "/nonexistent/x.pc2" in bad["failures"][0]["error"]


def test_bad_series_fail_before_any_work(client):
    with pytest.raises(animcodec.AnimcodecError, match="walks"):
        animcodec.sweep(["synth:flag"], ["quant-delta"], params={"bits": 8}, client=client)
    with pytest.raises(animcodec.AnimcodecError, match="unknown codec"):
        animcodec.sweep(["synth:flag"], ["nope"], client=client)


def test_outputs_are_not_overwritten_without_force(client, tmp_path):
    target = tmp_path / "r.json"
    target.write_text("keep")
    with pytest.raises(animcodec.AnimcodecError, match="exists|force"):
        animcodec.sweep("synth:flag", ["quant-delta"], points=2, client=client, json=str(target))
    assert target.read_text() == "keep"


def test_module_entry_point_runs_a_corpus(client, tmp_path):
    corpus = tmp_path / "corpus"
    corpus.mkdir()
    flag = animcodec.load("synth:flag")
    animcodec.save(corpus / "flag.pc2", flag)
    address = client.scheduler.address
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "animcodec.sweep", str(corpus), "-c", "quant-delta", "--points", "2",
         "--scheduler", address, "--out", str(out), "--no-progress"],
        capture_output=True, text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert "2 jobs on 2 workers" in proc.stdout
    doc = json.loads((out / "flag.json").read_text())
    local = animcodec.sweep_local(str(corpus / "flag.pc2"), ["quant-delta"], points=2)
    assert strip_timings(doc["rows"]) == strip_timings(local["rows"])


def test_sweep_local_reports_progress_per_point():
    events = []
    doc = animcodec.sweep_local("synth:flag", ["quant-delta", "pca-aoi"], points=2, jobs=None, progress=events.append)
    total = len(doc["rows"]) + len(doc.get("failures", []))
    started = [e for e in events if e["event"] == "started"]
    finished = [e for e in events if e["event"] == "finished"]
    assert len(started) == len(finished) == total == 4
    assert all(e["total"] == total for e in events)
    assert sorted(e["done"] for e in finished) == list(range(1, total + 1))
    assert {e["series"] for e in started} == {"quant-delta", "pca-aoi"}
    # A callback that raises stops the sweep, and its exception reaches the caller (issue 41:
    # it used to be printed and swallowed).
    def boom(_):
        raise RuntimeError("callback failure")
    with pytest.raises(RuntimeError, match="callback failure"):
        animcodec.sweep_local("synth:flag", ["quant-delta"], points=2, progress=boom)


def test_sweep_local_takes_an_animation_like_its_file(tmp_path, flag):
    # The same animation as arrays, as (name, arrays) and as a file: the same rows; the
    # document's input is the name given.
    path = tmp_path / "flag.pc2"
    animcodec.save(str(path), flag)
    from_file = animcodec.sweep_local(str(path), ["quant-delta", "pca-aoi"], points=2)
    bare = animcodec.sweep_local(flag, ["quant-delta", "pca-aoi"], points=2)
    named = animcodec.sweep_local(("my-flag", flag), ["quant-delta", "pca-aoi"], points=2)
    assert strip_timings(bare["rows"]) == strip_timings(from_file["rows"]) == strip_timings(named["rows"])
    assert (bare["input"], named["input"]) == ("array:0", "my-flag")
    assert (named["vertices"], named["frames"]) == (flag.positions.shape[1], flag.positions.shape[0])
    with pytest.raises(ValueError, match="apply to a file input"):
        animcodec.sweep_local(flag, ["quant-delta"], points=2, fps=10)
    with pytest.raises(ValueError, match="one input"):
        animcodec.sweep_local([flag, flag], ["quant-delta"], points=2)
    with pytest.raises(TypeError, match="expected a path"):
        animcodec.sweep_local(42, ["quant-delta"], points=2)


def _two_animation_glb(path):
    """A 5 × 5 grid with one morph target (a bump) and two animations: "rise" takes the bump
    from 0 to 1 over 4 keys, "fall" from 1 to 0 over 6 keys (1 key per second)."""
    import struct

    import numpy as np

    n = 5
    xs, ys = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    base = np.stack([xs.ravel(), ys.ravel(), np.zeros(n * n)], axis=1).astype(np.float32)
    bump = np.zeros_like(base)
    bump[:, 2] = np.exp(-((base[:, 0] - 0.5) ** 2 + (base[:, 1] - 0.5) ** 2) * 8).astype(np.float32)
    # Two triangles a grid cell, cells row by row.
    v = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    cells = np.stack([np.stack([v, v + 1, v + n], axis=1), np.stack([v + 1, v + n + 1, v + n], axis=1)], axis=1)
    index = cells.reshape(-1, 3).astype(np.uint32)
    rise_t = np.arange(4, dtype=np.float32)
    rise_w = np.linspace(0, 1, 4, dtype=np.float32)
    fall_t = np.arange(6, dtype=np.float32)
    fall_w = np.linspace(1, 0, 6, dtype=np.float32)
    blobs = [base, bump, index, rise_t, rise_w, fall_t, fall_w]
    views, accessors, data = [], [], b""
    kinds = [(5126, "VEC3"), (5126, "VEC3"), (5125, "SCALAR"), (5126, "SCALAR"), (5126, "SCALAR"),
             (5126, "SCALAR"), (5126, "SCALAR")]
    for blob, (component, kind) in zip(blobs, kinds):
        raw = blob.tobytes()
        views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(raw)})
        accessor = {"bufferView": len(views) - 1, "componentType": component, "type": kind,
                    "count": int(blob.size if kind == "SCALAR" else blob.shape[0])}
        if blob is base or blob is bump or kind == "SCALAR" and blob.dtype == np.float32:
            flat = blob.reshape(-1, 3) if kind == "VEC3" else blob.reshape(-1, 1)
            accessor["min"] = [float(x) for x in flat.min(axis=0)]
            accessor["max"] = [float(x) for x in flat.max(axis=0)]
        accessors.append(accessor)
        data += raw + b"\0" * (-len(raw) % 4)

    def animation(name, times, weights):
        return {"name": name, "samplers": [{"input": times, "output": weights, "interpolation": "LINEAR"}],
                "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]}

    doc = {
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "targets": [{"POSITION": 1}]}],
                    "weights": [0.0]}],
        "animations": [animation("rise", 3, 4), animation("fall", 5, 6)],
        "buffers": [{"byteLength": len(data)}], "bufferViews": views, "accessors": accessors,
    }
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(data), 0x004E4942) + data
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks)


def test_a_gltf_animation_is_picked_by_name_or_index(client, tmp_path):
    path = tmp_path / "two.glb"
    _two_animation_glb(path)
    first = animcodec.sweep_local(str(path), ["quant-delta"], points=2)
    fall = animcodec.sweep_local(str(path), ["quant-delta"], points=2, animation="fall")
    by_index = animcodec.sweep_local(str(path), ["quant-delta"], points=2, animation=1)
    assert (first["frames"], fall["frames"]) == (4, 6)
    assert strip_timings(fall["rows"]) == strip_timings(by_index["rows"])
    # The same as sweeping what load() picks.
    loaded = animcodec.sweep_local(("x", animcodec.load(str(path), animation="fall")), ["quant-delta"], points=2)
    assert strip_timings(loaded["rows"]) == strip_timings(fall["rows"])
    # On the cluster too.
    result = animcodec.sweep([str(path)], ["quant-delta"], points=2, client=client, animation="fall")
    assert strip_timings(result.documents[0]["rows"]) == strip_timings(fall["rows"])
    with pytest.raises(animcodec.AnimcodecError, match="nope"):
        animcodec.sweep_local(str(path), ["quant-delta"], points=2, animation="nope")
    with pytest.raises(TypeError, match="name .* or an index"):
        animcodec.sweep_local(str(path), ["quant-delta"], points=2, animation=1.5)
