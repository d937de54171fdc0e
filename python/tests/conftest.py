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
    """The `animcodec` binary: $ANIMCODEC_BIN, else one built in the repository's target
    directory (`cargo test --workspace` builds target/debug/animcodec), else built now with
    cargo. None when neither exists (the parity tests then skip with a message)."""
    env = os.environ.get("ANIMCODEC_BIN")
    if env:
        return env
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    for profile in ("debug", "release"):
        candidate = target / profile / "animcodec"
        if candidate.is_file():
            return str(candidate)
    if shutil.which("cargo") and (REPO / "Cargo.toml").is_file():
        subprocess.run(["cargo", "build", "-q", "-p", "animcodec-cli", "--bin", "animcodec"], cwd=REPO, check=True)
        candidate = target / "debug" / "animcodec"
        if candidate.is_file():
            return str(candidate)
    return None


@pytest.fixture(scope="session")
def cli():
    """Runs the command-line tool: cli(*args) -> CompletedProcess (stdout text)."""
    binary = _cli_binary()
    if binary is None:
        pytest.skip("no animcodec binary (set ANIMCODEC_BIN or build it with `cargo build -p animcodec-cli`)")

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
