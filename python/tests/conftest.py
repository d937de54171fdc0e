"""Shared helpers: synthetic inputs, and the command-line binary for parity checks."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

# The Rust tests' rule (codec_core::testing::skip): a skipped test says why, and with
# ANIMCODEC_REQUIRE_ALL set to anything but 0 (CI sets it) a skip is a failure.
REQUIRE_ALL_VAR = "ANIMCODEC_REQUIRE_ALL"


def _skips_fail():
    value = os.environ.get(REQUIRE_ALL_VAR)
    return value is not None and value != "0"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.skipped and _skips_fail() and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"{item.nodeid}: would skip ({reason}), and {REQUIRE_ALL_VAR} is set: every test must run"


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    # A module-level skip (pytest.importorskip at import time) is reported at collection.
    outcome = yield
    report = outcome.get_result()
    if report.skipped and _skips_fail():
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"{report.nodeid}: would skip ({reason}), and {REQUIRE_ALL_VAR} is set: every test must run"


def _cli_binary():
    """The `animcodec` binary: $ANIMCODEC_BIN, else `animcodec` on PATH, else one already built
    in the repository's target directory (`cargo test --workspace` builds target/debug/animcodec).
    Never built here: the tests that compare with the command line skip visibly without it
    (a failure under ANIMCODEC_REQUIRE_ALL); the others use the Python API alone."""
    env = os.environ.get("ANIMCODEC_BIN")
    if env:
        return env
    on_path = shutil.which("animcodec")
    if on_path:
        return on_path
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    for profile in ("debug", "release"):
        candidate = target / profile / "animcodec"
        if candidate.is_file():
            return str(candidate)
    return None


@pytest.fixture(scope="session")
def cli():
    """Runs the command-line tool: cli(*args) -> CompletedProcess (stdout text)."""
    binary = _cli_binary()
    if binary is None:
        pytest.skip(
            "needs the animcodec command line to compare with (set ANIMCODEC_BIN, put it on PATH, or build it: "
            "cargo build -p animcodec-cli)"
        )

    def run(*args, check=True):
        return subprocess.run([binary, *map(str, args)], capture_output=True, text=True, check=check)

    return run


@pytest.fixture(scope="session")
def flag():
    import animcodec

    return animcodec.load("synth:flag")


@pytest.fixture(scope="session")
def tumble():
    import animcodec

    return animcodec.load("synth:tumble")
