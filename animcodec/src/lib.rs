//! `animcodec`: compression of 3D mesh animations (fixed-connectivity vertex caches) with
//! research codecs, the metrics the field uses, and rate-distortion comparisons.
//!
//! This is the facade crate applications depend on (the command-line tool, the Python package,
//! the conformance suite and the fuzz targets do): it owns the list of codecs ([`registry`]) and
//! re-exports the crates below it, so one dependency gives the whole library.
//!
//! | module | crate | what |
//! |---|---|---|
//! | [`core`] | `codec-core` | the codec contract, `.anim` container, streams, limits, coding toolkit |
//! | [`synth`] | `animcodec-synth` | synthetic animations (the `synth:` inputs) |
//! | [`metrics`] | `metrics` | KG error, STED, Hausdorff, … |
//! | [`formats`], [`output`] | `animcodec-io` | file formats in and out; safe output files |
//! | [`harness`], [`plot`], [`describe`], [`params`] | `animcodec-eval` | measured points, sweeps, target search, the rate-distortion plot; codec and stream descriptions; parameters as JSON |
//! | [`stseg`] | `codec-stseg` | the stseg segmentation, for tools that show it |
//! | [`front`] | this crate | the front door of the command line and the Python package: inputs, parameters, metric options, limits |
//!
//! ```no_run
//! use animcodec::core::{encode_animation, Limits, StreamDecoder};
//! use animcodec::synth;
//! let registry = animcodec::registry();
//! let hosvd = registry.by_name("hosvd").unwrap();
//! let animation = synth::tumbling_body_sized(64, 32, 30);
//! let bytes = encode_animation(hosvd, &hosvd.default_params(), &animation).unwrap();
//! let decoded = StreamDecoder::new(bytes.as_slice(), &registry, Limits::default()).unwrap().decode_all().unwrap();
//! assert_eq!(decoded.frame_count(), animation.frame_count());
//! ```

pub use animcodec_eval::{describe, harness, params, plot};
pub use animcodec_io::{formats, output};
pub use animcodec_synth as synth;
pub use codec_core as core;
pub use metrics;

pub mod front;
pub mod tables;

/// The stseg codec's segmentation, for tools that show it (`animcodec inspect`): the analysis
/// the encoder runs, its parameters and its result.
pub mod stseg {
    pub use codec_stseg::{segment_animation, BlockKind, Segment, Segmentation, StsegParams, MAX_GROUPS};
}

use codec_core::CodecRegistry;

/// Every codec, one entry each (a comment saying what it is, then the codec). This list is where
/// codecs are registered (a new codec crate is also a dependency in this crate's `Cargo.toml` and
/// a workspace member: `cargo xtask new-codec` writes all three; README "Adding a codec");
/// streams name their codec by FourCC, so the order here is only the order of listings and
/// sweeps.
pub fn registry() -> CodecRegistry {
    CodecRegistry::new(vec![
        // baseline: uniform quantization, temporal delta, zstd
        Box::new(codec_quant_delta::QuantDelta),
        // block PCA with adaptive orthogonal iterations: Lalos et al. 2017, The Visual Computer
        Box::new(codec_pca_aoi::PcaAoi),
        // HO-SVD / Tucker with rigid-motion removal: Romaszewski, Gawron & Opozda
        Box::new(codec_hosvd::Hosvd),
        // spectral deformation-gradient compression: Spectral animation compression, JCST
        Box::new(codec_sac::Sac),
        // spatio-temporal segmentation + PCA: Luo et al. 2020, ACM TOMM
        Box::new(codec_stseg::Stseg),
        // laplacian: trajectory PCA, coefficient fields in the cotangent-Laplacian domain of the
        // average mesh with anchors (Váša et al. 2014; codec-laplacian/README.md)
        Box::new(codec_laplacian::Laplacian),
        // cargo xtask new-codec inserts above this line
    ])
    .expect("codec names and FourCCs in the registry list are unique")
}
