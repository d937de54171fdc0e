"""Issue 41, adversarial round 4, the Python package's part (docs/notes/issue-41-cli.md):
decode/info/decode_frame take the command line's limits and apply them before reading (a path
is read by the decoder as it goes, never whole first), progress callbacks that raise stop the
work and the exception reaches the caller, and frame numbers are integers."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import animcodec
from animcodec import AnimcodecError


def _run_limited(code, address_space=3 << 30):
    """Runs `code` in a fresh interpreter whose address space is capped (so a read without
    bound ends in MemoryError instead of taking the machine): returns (exit code, stdout)."""
    script = "import resource\nresource.setrlimit(resource.RLIMIT_AS, (%d, %d))\n" % (address_space, address_space)
    script += textwrap.dedent(code)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    return done.returncode, done.stdout + done.stderr


@pytest.mark.parametrize("call", ["decode('/dev/zero')", "info('/dev/zero')", "decode_frame('/dev/zero', 0)"])
def test_a_device_path_is_refused_at_its_first_bytes(call):
    # Before: the whole "file" was read with f.read() first (killed by the kernel at 23 GB).
    code, out = _run_limited(
        f"""
        import animcodec
        try:
            animcodec.{call}
        except animcodec.AnimcodecError as e:
            print("refused:", e)
        except MemoryError:
            print("MemoryError")
        """
    )
    assert code == 0 and "refused:" in out and "MemoryError" not in out, out
    assert "/dev/zero" in out, out


def test_the_limits_are_the_command_lines(cli, flag, tmp_path):
    assert animcodec.DEFAULT_MAX_MEMORY == 1 << 30
    assert animcodec.DEFAULT_MAX_WORK == 200_000_000_000
    stream = animcodec.encode(flag.positions, flag.faces, "quant-delta", fps=flag.fps, bits=10)
    path = tmp_path / "f.anim"
    path.write_bytes(stream)
    # The decode holds about 12 bytes a coordinate: 64 KiB is far too little, for bytes and
    # for a path alike, and the command line refuses it the same way.
    for data in (stream, path, str(path)):
        with pytest.raises(AnimcodecError, match="memory"):
            animcodec.decode(data, max_memory=64 << 10)
        with pytest.raises(AnimcodecError, match="memory"):
            animcodec.load(str(path), max_memory=64 << 10)
    refused = cli("--max-memory", "64K", "decode", path, "-o", tmp_path / "x.pc2", check=False)
    assert refused.returncode == 1 and "memory" in refused.stderr
    # A work budget of one operation refuses the decode before it computes.
    with pytest.raises(AnimcodecError, match="work|operations"):
        animcodec.decode(path, max_work=1)
    # With room, the path decodes to what the bytes decode to, frame by frame too.
    whole = animcodec.decode(path, max_memory=256 << 20)
    assert np.array_equal(whole.positions, animcodec.decode(stream).positions)
    assert np.array_equal(animcodec.decode_frame(str(path), 3), whole.positions[3])
    assert animcodec.info(path)["bytes"] == len(stream)
    for bad in (0, -1):
        with pytest.raises(ValueError):
            animcodec.decode(stream, max_memory=bad)
    for bad in (1.5, "1G", True):
        with pytest.raises(TypeError):
            animcodec.decode(stream, max_work=bad)
    with pytest.raises(AnimcodecError, match="directory"):
        animcodec.decode(tmp_path)


def test_frame_numbers_are_integers(flag):
    stream = animcodec.encode(flag.positions, flag.faces, "quant-delta", fps=flag.fps, bits=10)
    for bad in (1.5, 1.0, "1", True, None):
        with pytest.raises(TypeError, match="frame index"):
            animcodec.decode_frame(stream, bad)
    assert np.array_equal(animcodec.decode_frame(stream, np.int64(2)), animcodec.decode_frame(stream, 2))
    with pytest.raises(ValueError):
        animcodec.decode_frame(stream, -1)


class Stop(Exception):
    pass


def _raiser(calls):
    def progress(point):
        calls.append(point)
        raise Stop("enough")

    return progress


def test_an_exception_in_a_progress_callback_stops_encode_and_is_raised(flag):
    # Before: printed as "unraisable" and the search went on to the end.
    calls = []
    with pytest.raises(Stop, match="enough"):
        animcodec.encode(flag.positions, flag.faces, "quant-delta", fps=flag.fps, progress=_raiser(calls))
    points = []
    animcodec.encode(flag.positions, flag.faces, "quant-delta", fps=flag.fps, progress=points.append)
    # Stopped at once: calls already under way on other threads may finish, no new one starts.
    assert 1 <= len(calls) < len(points), (len(calls), len(points))


def test_an_exception_in_a_progress_callback_stops_encode_to_target_and_is_raised(flag):
    calls = []
    with pytest.raises(Stop):
        animcodec.encode_to_target(flag.positions, flag.faces, "auto", fps=flag.fps, kg=0.5, progress=_raiser(calls))
    points = []
    animcodec.encode_to_target(flag.positions, flag.faces, "auto", fps=flag.fps, kg=0.5, progress=points.append)
    assert 1 <= len(calls) < len(points), (len(calls), len(points))


@pytest.mark.parametrize("jobs", [1, None])
def test_an_exception_in_a_progress_callback_stops_sweep_local_and_is_raised(jobs):
    calls = []
    with pytest.raises(Stop):
        animcodec.sweep_local("synth:flag", codecs=["quant-delta"], points=6, jobs=jobs, progress=_raiser(calls))
    events = []
    animcodec.sweep_local("synth:flag", codecs=["quant-delta"], points=6, jobs=jobs, progress=events.append)
    assert len(events) == 12
    assert 1 <= len(calls) < len(events), (len(calls), len(events))
    # The package still works after an aborted call.
    assert animcodec.sweep_local("synth:flag", codecs=["quant-delta"], points=2, jobs=jobs)["rows"]
