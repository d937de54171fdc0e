//! The checked-in header `capi/include/animcodec.h` is what cbindgen generates from the source
//! now (`capi/cbindgen.toml`). Needs the `cbindgen` binary (`cargo install cbindgen --locked`);
//! without it the test skips (`codec_core::testing::skip`).

mod common;

use std::process::Command;

use codec_core::testing::skip;

#[test]
fn the_checked_in_header_is_what_cbindgen_generates() {
    let test = "the_checked_in_header_is_what_cbindgen_generates";
    if Command::new("cbindgen").arg("--version").output().is_err() {
        return skip(test, "no `cbindgen` on PATH (cargo install cbindgen --locked)");
    }
    let root = common::workspace();
    let out = Command::new("cbindgen")
        .current_dir(&root)
        .args(["--config", "capi/cbindgen.toml", "--crate", "animcodec-capi", "--quiet"])
        .output()
        .expect("cbindgen");
    assert!(out.status.success(), "cbindgen: {}", String::from_utf8_lossy(&out.stderr));
    let generated = String::from_utf8(out.stdout).expect("utf-8");
    let checked_in = std::fs::read_to_string(root.join("capi/include/animcodec.h")).expect("header");
    assert!(
        generated == checked_in,
        "capi/include/animcodec.h is stale: run `cbindgen --config capi/cbindgen.toml --crate animcodec-capi \
         --output capi/include/animcodec.h` in the workspace root"
    );
}
