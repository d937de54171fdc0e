//! Untrusted input to every registered decoder (suite items 4 and 5): truncations, byte
//! flips the container must catch, and corruptions with the checksums patched (or the stream
//! rebuilt) so that the codec's own parser sees them. Never a panic, never a large allocation.

use conformance_tests::{codecs_under_test, suite};

/// Suite item 4: every truncation of a valid stream is an error from `decode_animation` and
/// `decode_frame` — never a panic, never a large allocation; so is trailing junk.
#[test]
fn every_truncation_is_an_error() {
    suite::every_truncation_is_an_error(&codecs_under_test()).assert_none("every_truncation_is_an_error");
}

/// Suite item 5, container level: random single- and multi-byte changes anywhere (header,
/// packets, index, trailer) and every byte of header, packet framing and index flipped. All
/// bytes are covered by a checksum or a checked tag, so every one must be an error;
/// `decode_frame` (which reads only the packets it needs) may succeed but must return a
/// frame of the right size.
#[test]
fn byte_flips_are_detected() {
    suite::byte_flips_are_detected(&codecs_under_test()).assert_none("byte_flips_are_detected");
}

/// Suite item 5, codec level: bytes flipped inside packet payloads with the packet CRC
/// recomputed, so the codec's parser sees them. Err or a finite animation of the right size;
/// never a panic or a large allocation.
#[test]
fn payload_flips_with_valid_crc_never_panic() {
    suite::payload_flips_with_valid_crc_never_panic(&codecs_under_test())
        .assert_none("payload_flips_with_valid_crc_never_panic");
}

/// Suite item 5, codec level: the codec configuration in the header corrupted (each byte
/// flipped, truncated, extended, emptied) with the header CRC valid, and unsupported stream
/// versions. The configuration reaches `new_decoder` as untrusted bytes.
#[test]
fn corrupt_config_and_version_never_panic() {
    suite::corrupt_config_and_version_never_panic(&codecs_under_test())
        .assert_none("corrupt_config_and_version_never_panic");
}

/// Suite item 5, codec level: rebuilt streams (all checksums and the index consistent) with
/// payloads cut, extended, replaced, swapped, frame ranges moved, keyframe flags toggled,
/// header vertex counts changed, and packets or configuration taken from other streams.
/// `decode_animation` and `decode_frame` must give Err or the right shape; never panic.
#[test]
fn structural_mutations_never_panic() {
    suite::structural_mutations_never_panic(&codecs_under_test()).assert_none("structural_mutations_never_panic");
}
