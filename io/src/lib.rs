//! File input and output of `animcodec`: the animation file formats ([`formats`]: OBJ
//! sequences, PC2, MDD, glTF/GLB morph-target and skinned animations in, PC2/MDD/OBJ/glTF out)
//! and safe output files ([`output`]: staged, validated and renamed into place together, never
//! losing a user's file).
//!
//! This crate stands beside the codecs: it depends on `codec-core` (the [`Animation`] type,
//! [`Limits`], errors) and `metrics` (the glTF export measures what a player will show), never
//! on a codec or on the evaluation harness.
//!
//! [`Animation`]: codec_core::Animation
//! [`Limits`]: codec_core::Limits

pub mod formats;
pub mod output;
