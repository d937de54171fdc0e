"""Issue 30: one animation encoded by independent temporal blocks on a Dask LocalCluster equals
the local encode with the same blocking, byte for byte (arrays and a PC2 file read by the
workers; the latter against the command line's ``encode --memory``)."""

import pytest

import animcodec
from animcodec import blocks

distributed = pytest.importorskip("distributed", reason="dask[distributed] is not installed")

# hosvd's memory model (codec_hosvd::block_memory): 64 MiB of program, 2 KiB a vertex, 64 B a
# coordinate of the block. For the small flag (240 vertices × 40 frames) this budget holds 12
# frames, so hosvd's whole-sequence block becomes 4 blocks of 10.
HOSVD_BUDGET = (64 << 20) + 2048 * 240 + 64 * 240 * 3 * 12


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


CASES = [
    ("quant-delta", {"block": 7}, None),
    ("hosvd", {"block": 9}, None),
    ("hosvd", {}, HOSVD_BUDGET),
    ("pca-aoi", {"mode": "svd", "block": 8}, None),
]


@pytest.mark.parametrize("codec,params,memory", CASES)
def test_cluster_encode_equals_the_local_encode(client, flag, codec, params, memory):
    plan = blocks.block_plan(codec, flag.vertices, flag.frames, memory=memory, **params)
    assert plan["blocks"] > 1, plan
    local = animcodec.encode(flag.positions, flag.faces, codec, flag.fps, **plan["params"])
    on_cluster = blocks.encode_distributed(flag, codec, client=client, memory=memory, **params)
    assert on_cluster == local
    # The same without Dask (blocks one after another in this process).
    assert blocks.encode_distributed(flag, codec, memory=memory, **params) == local
    assert animcodec.decode(on_cluster).positions.shape == flag.positions.shape


def test_workers_read_their_blocks_of_a_pc2_like_encode_memory(client, flag, cli, tmp_path):
    path = tmp_path / "flag.pc2"
    animcodec.save(path, flag)
    on_cluster = blocks.encode_distributed(str(path), "hosvd", client=client, memory=HOSVD_BUDGET)
    out = tmp_path / "flag.anim"
    cli("encode", path, "-c", "hosvd", "-p", "ss=0.9", "--memory", HOSVD_BUDGET, "-o", out)
    assert on_cluster == out.read_bytes()
    assert blocks.block_plan("hosvd", flag.vertices, flag.frames, memory=HOSVD_BUDGET)["blocks"] > 1


def test_memory_strings_read_like_the_command_line():
    assert blocks.parse_memory("4G") == 4 << 30
    assert blocks.parse_memory("512m") == 512 << 20
    assert blocks.parse_memory(1000) == 1000
    for bad in ("4X", "", "G", 0, -3):
        with pytest.raises(ValueError):
            blocks.parse_memory(bad)


@pytest.mark.parametrize("codec,params", [("sac", {}), ("stseg", {}), ("pca-aoi", {"mode": "baoi"})])
def test_codecs_with_dependent_packets_are_refused(flag, codec, params):
    with pytest.raises(animcodec.AnimcodecError, match=codec):
        blocks.encode_distributed(flag, codec, **params)
