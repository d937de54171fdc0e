//! The conformance suite: every codec in `animcodec::registry()` passes the same checks
//! (round trip, feeding, threads, random access, parameters, registry). The checks live in
//! `conformance_tests::suite`; each reports every failing codec by name. `ANIMCODEC_CODECS=NAME`
//! restricts them to some codecs (`conformance_tests::codecs_under_test`).

use conformance_tests::{codecs_under_test, suite};

/// Suite item 1: at default params and both ends of the rate ladder, on several animations,
/// the decoded frames equal the encoder's reconstruction bit for bit and the error is within
/// the declared bound.
#[test]
fn round_trip_matches_reconstruction_and_bound() {
    suite::round_trip_matches_reconstruction_and_bound(&codecs_under_test())
        .assert_none("round_trip_matches_reconstruction_and_bound");
}

/// Unusual animations (one frame, static, no triangles, degenerate triangles, one vertex,
/// a flat axis, far from the origin, exact repeats): encode within the bound and decode to
/// the reconstruction, or refuse with an error. Never panic.
#[test]
fn edge_case_animations_round_trip_or_error() {
    suite::edge_case_animations_round_trip_or_error(&codecs_under_test())
        .assert_none("edge_case_animations_round_trip_or_error");
}

/// 1-frame and 2-frame inputs and a single triangle: refused as the codec's entry of
/// `suite::EXPECTED_REFUSALS` says, or within the declared bound and the bound declared on the
/// long animation they were cut from.
#[test]
fn short_animations_meet_the_long_animations_bound() {
    suite::short_animations_meet_the_long_animations_bound(&codecs_under_test())
        .assert_none("short_animations_meet_the_long_animations_bound");
}

/// Suite item 2: the bytes do not depend on how frames are fed (1 at a time, odd blocks, all
/// at once) nor on whether the reconstruction was requested.
#[test]
fn feeding_pattern_does_not_change_bytes() {
    suite::feeding_pattern_does_not_change_bytes(&codecs_under_test())
        .assert_none("feeding_pattern_does_not_change_bytes");
}

/// Suite item 3: identical bytes whether encoding runs in a 1-thread or a 4-thread rayon
/// pool, and identical frames when decoding in either.
#[test]
fn bytes_do_not_depend_on_thread_count() {
    suite::bytes_do_not_depend_on_thread_count(&codecs_under_test()).assert_none("bytes_do_not_depend_on_thread_count");
}

/// Suite item 6: `decode_frame` on a seekable stream returns the same frame as the full
/// decode, for every frame (first, middle and last included), bit for bit.
#[test]
fn random_access_matches_full_decode() {
    suite::random_access_matches_full_decode(&codecs_under_test()).assert_none("random_access_matches_full_decode");
}

/// Suite item 7: for every `ParamSpec`, values just outside its range are rejected by
/// `ParamSet::set` with a message naming the codec, the parameter and the range; values of
/// the wrong kind and unknown names are rejected too.
#[test]
fn out_of_range_parameters_are_rejected_with_the_range() {
    suite::out_of_range_parameters_are_rejected_with_the_range(&codecs_under_test())
        .assert_none("out_of_range_parameters_are_rejected_with_the_range");
}

/// Suite item 7: defaults validate; every rate-ladder step is settable and validates; a
/// parameter set made for another codec is refused.
#[test]
fn defaults_and_ladder_steps_validate() {
    suite::defaults_and_ladder_steps_validate(&codecs_under_test()).assert_none("defaults_and_ladder_steps_validate");
}

/// Suite item 7: the rate ladder's streams do not shrink from one step to the next (small →
/// large), on two synthetic animations. No tolerance: a smaller stream at a higher step is
/// reported.
#[test]
fn rate_ladder_sizes_are_non_decreasing() {
    suite::rate_ladder_sizes_are_non_decreasing(&codecs_under_test())
        .assert_none("rate_ladder_sizes_are_non_decreasing");
}

/// Suite item 10: names and FourCCs unique and well formed; `by_name` of an unknown name
/// lists the valid ones; every codec is found by its own name and FourCC.
#[test]
fn registry_names_and_fourccs_are_unique() {
    suite::registry_names_and_fourccs_are_unique(&codecs_under_test())
        .assert_none("registry_names_and_fourccs_are_unique");
}

/// Decoding needs nothing but the bitstream: a stream whose FourCC no codec has is refused by
/// name, and the default limits decode a valid stream like the tight ones do.
#[test]
fn unknown_fourcc_and_default_limits() {
    suite::unknown_fourcc_and_default_limits(&codecs_under_test()).assert_none("unknown_fourcc_and_default_limits");
}

/// Every stream of every codec whose header claims twice its vertices is
/// refused (no decoder runs past its payload).
#[test]
fn forged_vertex_count_is_refused() {
    suite::forged_vertex_count_is_refused(&codecs_under_test()).assert_none("forged_vertex_count_is_refused");
}

/// `--max-work` binds every codec: one operation below what a stream needs
/// is refused with the work-limit error, and each codec counts its own work.
#[test]
fn work_budget_is_honoured() {
    suite::work_budget_is_honoured(&codecs_under_test()).assert_none("work_budget_is_honoured");
}

/// Frame rates the file readers would refuse are refused by the container.
#[test]
fn forged_frame_rates_are_refused() {
    suite::forged_frame_rates_are_refused(&codecs_under_test()).assert_none("forged_frame_rates_are_refused");
}
