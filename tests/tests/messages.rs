//! Decoder error messages are words, never Rust `Debug` values: a user reads them, and a
//! `Some(..)` or `Err(..)` in one says nothing about the file.

/// A corrupt sac range-coded payload (checksums patched so the codec sees it) is reported in
/// words, and so is every other corrupt-payload error of every codec.
#[test]
fn corrupt_payload_errors_show_no_debug_values() {
    let registry = animcodec::registry();
    let anim = animcodec::synth::waving_flag(6, 5, 12);
    for codec in registry.iter() {
        let enc = codec_core::encode_animation(codec, &codec.default_params(), &anim).unwrap();
        let parts = conformance_tests::split(&enc).unwrap();
        let mut messages = 0;
        for e in &parts.index {
            let range = conformance_tests::payload_range(e);
            for pos in range.clone().step_by(1.max(range.len() / 24)) {
                for mask in [0x01u8, 0xFF] {
                    let mut bytes = enc.clone();
                    bytes[pos] ^= mask;
                    conformance_tests::patch_packet_crc(&mut bytes, e);
                    if let Err(err) = codec_core::decode_animation(&bytes, &registry, codec_core::Limits::default()) {
                        let text = err.to_string();
                        messages += 1;
                        assert!(
                            !conformance_tests::looks_like_debug(&text),
                            "{}: Debug value in '{text}'",
                            codec.name()
                        );
                    }
                }
            }
        }
        // Some flips must be refused, or nothing was checked (a codec whose every flipped
        // payload decodes would pass vacuously).
        assert!(messages > 0, "{}: no corrupt payload was refused, so no message was checked", codec.name());
        eprintln!("{}: {messages} corrupt-payload errors checked", codec.name());
    }
}
