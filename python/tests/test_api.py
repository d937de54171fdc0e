"""The Python API: round trips for every codec, errors as exceptions, numpy handling, file
formats, and parity with the command line (`eval --json`, `info --json`, `list --json`,
`encode --target`)."""

import json
import threading
import time

import numpy as np
import pytest

import animcodec
from animcodec import AnimcodecError, Animation

CODECS = animcodec.codec_names()


def test_every_registered_codec_is_listed_with_parameters_and_ladder(cli):
    listed = animcodec.codecs()
    assert [c["name"] for c in listed] == CODECS
    assert {"quant-delta", "pca-aoi", "hosvd", "sac", "stseg"} <= set(CODECS)
    for c in listed:
        assert c["rate_ladder"]["steps"], c["name"]
        assert c["rate_ladder"]["param"] in {p["name"] for p in c["params"]}
    # Same document as the command line's.
    assert listed == json.loads(cli("list", "--json").stdout)


def _oriented_set(faces):
    # Each triangle as its lexicographically smallest rotation (orientation kept), sorted.
    rows = np.array([min(tuple(np.roll(row, -r)) for r in range(3)) for row in np.asarray(faces, dtype=np.int64)])
    return rows[np.lexsort(rows.T[::-1])] if len(rows) else rows


@pytest.mark.parametrize("codec", CODECS)
def test_round_trip(codec, flag):
    stream = animcodec.encode(flag.positions, flag.faces, codec, fps=flag.fps)
    assert isinstance(stream, bytes)
    # Same input, same parameters: same bytes.
    assert animcodec.encode(flag.positions, flag.faces, codec, fps=flag.fps) == stream
    back = animcodec.decode(stream)
    assert back.positions.shape == flag.positions.shape and back.positions.dtype == np.float32
    assert back.positions.flags.c_contiguous
    # The stream keeps every triangle with its orientation, in canonical order (each rotated
    # so its smallest index comes first; see codec-core/FORMAT.md).
    assert np.array_equal(_oriented_set(back.faces), _oriented_set(flag.faces)) and back.faces.dtype == np.uint32
    assert back.fps == pytest.approx(flag.fps)
    report = animcodec.evaluate(flag, back)
    # Every codec's default is a usable quality (KG in percent).
    assert report["kg"] is not None and 0 <= report["kg"] < 10, report["kg"]
    assert report["max_error"] < flag.positions.std() * 3
    # Random access gives the frame the full decode gives.
    for t in (0, flag.frames // 2, flag.frames - 1):
        assert np.array_equal(animcodec.decode_frame(stream, t), back.positions[t])
    meta = animcodec.info(stream)
    assert meta["codec"] == codec and meta["bytes"] == len(stream)
    assert (meta["frames"], meta["vertices"], meta["triangles"]) == (flag.frames, flag.vertices, flag.triangles)


def test_parameters_change_the_stream(flag):
    coarse = animcodec.encode(flag.positions, flag.faces, "quant-delta", bits=6)
    fine = animcodec.encode(flag.positions, flag.faces, "quant-delta", bits=14)
    assert len(coarse) < len(fine)
    e6 = animcodec.evaluate(flag, animcodec.decode(coarse))["kg"]
    e14 = animcodec.evaluate(flag, animcodec.decode(fine))["kg"]
    assert e14 < e6


# ------------------------------------------------------------------------------------------
# errors


def test_library_errors_are_exceptions_with_the_rust_message(flag, tmp_path):
    with pytest.raises(AnimcodecError, match="unknown codec.*quant-delta"):
        animcodec.encode(flag.positions, flag.faces, "no-such-codec")
    with pytest.raises(AnimcodecError, match="quant-delta.*bits.*range"):
        animcodec.encode(flag.positions, flag.faces, "quant-delta", bits=99)
    with pytest.raises(AnimcodecError, match="quant-delta.*colour.*valid parameters"):
        animcodec.encode(flag.positions, flag.faces, "quant-delta", colour=3)
    with pytest.raises(AnimcodecError, match="bits.*integer"):
        animcodec.encode(flag.positions, flag.faces, "quant-delta", bits=7.5)
    bad = flag.positions.copy()
    bad[3, 5, 1] = np.nan
    with pytest.raises(AnimcodecError, match="finite|NaN"):
        animcodec.encode(bad, flag.faces, "quant-delta")
    with pytest.raises(AnimcodecError, match="triangle 0 .*out of range for 240 vertices"):
        animcodec.encode(flag.positions, np.array([[0, 1, flag.vertices]]), "quant-delta")
    with pytest.raises(AnimcodecError, match="no-such.pc2"):
        animcodec.load(tmp_path / "no-such.pc2")
    assert issubclass(AnimcodecError, Exception)


def test_corrupt_and_truncated_streams_raise(flag):
    stream = animcodec.encode(flag.positions, flag.faces, "quant-delta")
    for cut in (0, 10, len(stream) // 2, len(stream) - 1):
        with pytest.raises(AnimcodecError):
            animcodec.decode(stream[:cut])
    flipped = bytearray(stream)
    flipped[len(stream) // 2] ^= 0x40
    with pytest.raises(AnimcodecError, match="checksum|corrupt|malformed"):
        animcodec.decode(bytes(flipped))
    with pytest.raises(AnimcodecError, match="checksum|corrupt|malformed"):
        animcodec.info(flipped)
    with pytest.raises(AnimcodecError, match="past the end"):
        animcodec.decode_frame(stream, flag.frames)


def test_evaluate_refuses_mismatched_animations(flag, tumble):
    with pytest.raises(ValueError, match="shape"):
        animcodec.evaluate(flag.positions, flag.positions[:-1], flag.faces)
    with pytest.raises(TypeError, match="sted_radiuss"):
        animcodec.evaluate(flag, flag, sted_radiuss=2)
    with pytest.raises(AnimcodecError, match="ring_radius|radius"):
        animcodec.evaluate(flag, flag, sted_radius=0)


# ------------------------------------------------------------------------------------------
# numpy handling


def test_float64_and_noncontiguous_inputs_give_the_same_stream(flag):
    reference = animcodec.encode(flag.positions, flag.faces, "pca-aoi")
    as64 = flag.positions.astype(np.float64)
    assert animcodec.encode(as64, flag.faces, "pca-aoi") == reference
    fortran = np.asfortranarray(flag.positions)
    assert not fortran.flags.c_contiguous
    assert animcodec.encode(fortran, flag.faces, "pca-aoi") == reference
    strided = np.repeat(flag.positions, 2, axis=1)[:, ::2]  # a view with a stride of 2 vertices
    assert not strided.flags.c_contiguous
    assert animcodec.encode(strided, flag.faces, "pca-aoi") == reference
    faces64 = flag.faces.astype(np.int64)
    assert animcodec.encode(flag.positions, faces64, "pca-aoi") == reference
    assert animcodec.encode(flag.positions.tolist(), flag.faces.tolist(), "pca-aoi") == reference


def test_wrong_shapes_and_dtypes_are_clear_errors(flag):
    with pytest.raises(ValueError, match=r"positions must have shape \(frames, vertices, 3\); got \(40, 3\)"):
        animcodec.encode(np.zeros((40, 3), np.float32), flag.faces, "quant-delta")
    with pytest.raises(ValueError, match=r"got \(2, 5, 2\)"):
        animcodec.encode(np.zeros((2, 5, 2), np.float32), flag.faces, "quant-delta")
    with pytest.raises(ValueError, match=r"faces must have shape \(triangles, 3\)"):
        animcodec.encode(flag.positions, flag.faces.reshape(-1), "quant-delta")
    with pytest.raises(TypeError, match="faces must hold integer"):
        animcodec.encode(flag.positions, flag.faces.astype(np.float32), "quant-delta")
    with pytest.raises(ValueError, match="negative vertex index"):
        animcodec.encode(flag.positions, -flag.faces.astype(np.int64) - 1, "quant-delta")
    # Positions are float32 or float64, nothing else (as documented): integer coordinates are
    # refused, not silently taken as model units.
    for dtype in (np.complex64, np.int32, np.int64, np.uint16, np.float16, np.bool_):
        with pytest.raises(TypeError, match="positions must be float32 or float64"):
            animcodec.encode(flag.positions.astype(dtype), flag.faces, "quant-delta")
    assert animcodec.encode(flag.positions.astype(np.float64), flag.faces, "quant-delta") == animcodec.encode(
        flag.positions, flag.faces, "quant-delta"
    )
    with pytest.raises(ValueError, match="fps"):
        animcodec.encode(flag.positions, flag.faces, "quant-delta", fps=0)
    # The extension itself refuses what the Python layer would have converted.
    with pytest.raises(TypeError):
        animcodec._native.encode(flag.positions.astype(np.float64), flag.faces, "quant-delta", 30.0)
    # and reads any memory layout in logical order.
    reference = animcodec.encode(flag.positions, flag.faces, "quant-delta")
    fortran = np.asfortranarray(flag.positions)
    assert animcodec._native.encode(fortran, flag.faces, "quant-delta", 30.0) == reference
    unaligned = np.frombuffer(b"\0" + flag.positions.tobytes(), dtype=np.float32, offset=1).reshape(flag.positions.shape)
    assert not unaligned.flags.aligned
    with pytest.raises(AnimcodecError, match="aligned"):
        animcodec._native.encode(unaligned, flag.faces, "quant-delta", 30.0)
    assert animcodec.encode(unaligned, flag.faces, "quant-delta") == reference


def test_decoded_arrays_are_owned_by_numpy(flag):
    stream = animcodec.encode(flag.positions, flag.faces, "quant-delta")
    a = animcodec.decode(stream)
    b = animcodec.decode(stream)
    a.positions[0, 0, 0] += 1.0  # writable, and not shared with another decode
    assert a.positions[0, 0, 0] != b.positions[0, 0, 0]


def test_the_gil_is_released_while_encoding(flag):
    big = animcodec.load("synth:flag:medium")
    start = time.perf_counter()
    animcodec.encode(big.positions, big.faces, "hosvd")
    alone = time.perf_counter() - start
    gaps = []
    done = threading.Event()

    def work():
        animcodec.encode(big.positions, big.faces, "hosvd")
        done.set()

    worker = threading.Thread(target=work)
    last = time.perf_counter()
    worker.start()
    while not done.is_set():
        now = time.perf_counter()
        gaps.append(now - last)
        last = now
        time.sleep(0.001)
    worker.join()
    # While the encode runs in the other thread this loop keeps running: its longest pause is
    # far below the encode's duration (with the GIL held it would equal it).
    assert alone > 0.05, f"encode too short to tell ({alone:.3f} s)"
    assert len(gaps) > 10 and max(gaps) < alone / 2, (len(gaps), max(gaps), alone)


# ------------------------------------------------------------------------------------------
# files and the command line


def test_eval_matches_the_command_line(cli, flag, tmp_path):
    ref = tmp_path / "ref.pc2"
    animcodec.save(ref, flag)
    stream = animcodec.encode(flag.positions, flag.faces, "hosvd", fps=flag.fps, ss=0.9)
    cand = tmp_path / "cand.anim"
    cand.write_bytes(stream)
    expected = json.loads(cli("eval", ref, cand, "--json").stdout)
    got = animcodec.evaluate(str(ref), str(cand))
    assert set(got) == set(expected)
    for key in set(expected) - {"eval_seconds"}:
        assert got[key] == expected[key], key
    # Arrays give the same numbers (names are None).
    arrays = animcodec.evaluate(flag.positions, animcodec.decode(stream).positions, flag.faces, flag.fps)
    for key in set(expected) - {"eval_seconds", "reference", "candidate"}:
        assert arrays[key] == expected[key], key
    assert arrays["kg"] > 0
    # Options map to the command line's flags.
    expected = json.loads(cli("eval", ref, cand, "--json", "--no-hausdorff", "--sted-radius", "2").stdout)
    got = animcodec.evaluate(str(ref), str(cand), hausdorff=False, sted_radius=2)
    for key in set(expected) - {"eval_seconds"}:
        assert got[key] == expected[key], key
    assert got["hausdorff"] is None


def test_info_matches_the_command_line(cli, flag, tmp_path):
    stream = animcodec.encode(flag.positions, flag.faces, "stseg", fps=flag.fps)
    path = tmp_path / "s.anim"
    path.write_bytes(stream)
    assert animcodec.info(stream) == json.loads(cli("info", path, "--json").stdout)
    assert animcodec.info(path) == animcodec.info(stream)


def test_encode_to_target_finds_what_the_command_line_finds(cli, flag, tmp_path):
    found = animcodec.encode_to_target(flag.positions, flag.faces, "quant-delta", fps=flag.fps, kg=0.5)
    assert found.codec == "quant-delta" and found.reached["kg"] <= 0.5
    measured = animcodec.evaluate(flag, animcodec.decode(found.stream))["kg"]
    assert measured == found.reached["kg"]
    src = tmp_path / "flag.pc2"
    animcodec.save(src, flag)
    out = tmp_path / "t.anim"
    cli("encode", src, "-c", "quant-delta", "--target", "kg=0.5", "-o", out)
    assert out.read_bytes() == found.stream
    auto = animcodec.encode_to_target(flag.positions, flag.faces, fps=flag.fps, kg=0.5)
    assert auto.reached["kg"] <= 0.5 and len(auto.stream) <= len(found.stream)
    with pytest.raises(ValueError, match="at least one target"):
        animcodec.encode_to_target(flag.positions, flag.faces)
    # A joint target: every bound met, each one reported; the command line finds the same stream.
    joint = animcodec.encode_to_target(flag.positions, flag.faces, "quant-delta", fps=flag.fps, kg=0.5, sted=0.01)
    assert set(joint.reached) == {"kg", "sted"}
    assert joint.reached["kg"] <= 0.5 and joint.reached["sted"] <= 0.01
    assert joint.details["target"] == {"kg": 0.5, "sted": 0.01}
    out = tmp_path / "joint.anim"
    cli("encode", src, "-c", "quant-delta", "--target", "kg=0.5,sted=0.01", "--refine", "0", "-o", out)
    assert out.read_bytes() == joint.stream
    with pytest.raises(AnimcodecError, match="no rate-ladder point meets|no codec meets"):
        animcodec.encode_to_target(flag.positions, flag.faces, "quant-delta", max_error=0.0)


@pytest.mark.parametrize("name", ["a.pc2", "a.mdd", "seq/", "frames.obj"])
def test_save_and_load_round_trip_exactly(flag, tmp_path, name):
    path = str(tmp_path / name) + ("/" if name.endswith("/") else "")
    written = animcodec.save(path, flag)
    assert written
    back = animcodec.load(path if not name.endswith(".obj") else tmp_path / "frames_*.obj", fps=flag.fps)
    assert back.fps == flag.fps
    assert np.array_equal(back.positions, flag.positions)
    assert np.array_equal(back.faces, flag.faces)


def test_glb_round_trip_and_anim_load(flag, tmp_path):
    path = tmp_path / "a.glb"
    animcodec.save(path, flag)
    back = animcodec.load(path, fps=flag.fps)
    assert back.positions.shape == flag.positions.shape
    assert animcodec.evaluate(flag, back)["kg"] < 0.1  # glTF export meets KG 0.05 % by default
    stream_path = tmp_path / "a.anim"
    stream_path.write_bytes(animcodec.encode(flag.positions, flag.faces, "quant-delta"))
    assert animcodec.load(stream_path).positions.shape == flag.positions.shape


def test_save_refuses_to_overwrite_without_force(flag, tmp_path):
    path = tmp_path / "a.pc2"
    animcodec.save(path, flag)
    before = path.read_bytes()
    moved = Animation(flag.positions + 1.0, flag.faces, flag.fps)
    with pytest.raises(AnimcodecError, match="exists|-f|force"):
        animcodec.save(path, moved)
    assert path.read_bytes() == before
    animcodec.save(path, moved, force=True)
    assert np.array_equal(animcodec.load(path).positions, moved.positions)
