"""Every dict the Python package returns uses only the keys documented in docs/json.md (the
command line's documents are checked by cli/tests/json_keys.rs): one spelling per quantity,
whichever door a user comes in by."""

import re

import animcodec
from animcodec import _native
from conftest import REPO


def _documented_keys():
    text = (REPO / "docs" / "json.md").read_text()
    keys = {m.group(1) for m in re.finditer(r"^\| `([^`]+)`", text, flags=re.M)}
    assert len(keys) > 50, f"docs/json.md lists only {len(keys)} keys"
    return keys


def _parameter_names():
    return {p["name"] for c in animcodec.codecs() for p in c["params"]}


def _undocumented(value, path, keys, params, out):
    if isinstance(value, dict):
        for key, inner in value.items():
            here = f"{path}.{key}"
            if key not in keys:
                out.append(here)
            if key == "params" and isinstance(inner, dict):
                out.extend(f"{here}.{k}" for k in inner if k not in params)
            else:
                _undocumented(inner, here, keys, params, out)
    elif isinstance(value, list):
        for item in value:
            _undocumented(item, f"{path}[]", keys, params, out)


def test_every_dict_key_is_documented(flag, tmp_path):
    stream = animcodec.encode(flag.positions, flag.faces, "quant-delta", fps=flag.fps, bits=8)
    seen = []
    found = animcodec.encode_to_target(
        flag.positions, flag.faces, "quant-delta", flag.fps, kg=1.0, progress=seen.append
    )
    sweep = animcodec.sweep_local("synth:flag", ["quant-delta"], points=2)
    job = _native.sweep_point(
        {
            "input": "synth:flag",
            "codec": "quant-delta",
            "params": None,
            "step": 0,
            "eval": None,
            "topology": None,
            "fps": None,
            "animation": None,
            "arrays": None,
        }
    )
    documents = {
        "codecs()": animcodec.codecs(),
        "info()": animcodec.info(stream),
        "evaluate()": animcodec.evaluate(flag, animcodec.decode(stream)),
        "encode_to_target().details": found.details,
        "encode_to_target(progress=)": seen,
        "sweep_local()": sweep,
        "sweep_point": job,
        "sweep_plan": _native.sweep_plan([("quant-delta", None)], 2),
        "blocks.block_plan()": animcodec.blocks.block_plan("hosvd", 240, 40, memory="1G", block=9),
    }
    keys, params = _documented_keys(), _parameter_names()
    missing = []
    for name, value in documents.items():
        _undocumented(value, name, keys, params, missing)
    assert not missing, "keys missing from docs/json.md:\n" + "\n".join(sorted(set(missing)))
