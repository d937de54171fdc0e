//! Core of **animcodec**: the contract and the toolkit. The animation data model, the codec
//! contract ([`TypedCodec`] on typed parameters, the object-safe [`AnimationCodec`] the
//! registry holds), the `.anim` container, limits, quantization and entropy helpers, and the
//! coding [`toolkit`].
//!
//! A codec crate implements [`TypedCodec`] on its parameters (declared with
//! [`declare_params!`]) plus a [`FrameEncoder`] and a [`FrameDecoder`], and is added to the one
//! registry list in the `animcodec` crate.
//! [`encode_animation`] and [`decode_animation`] drive any codec through the container.

pub mod animation;
pub mod blocks;
pub mod bytes;
pub mod codec;
pub mod connectivity;
pub mod container;
pub mod entropy;
pub mod error;
pub mod limits;
pub mod linalg;
pub mod memory;
pub mod metadata;
pub mod params;
pub mod quant;
pub mod registry;
pub mod stream;
#[cfg(any(test, feature = "testing"))]
pub mod testing;
pub mod toolkit;
pub mod traversal;

/// `codec-core/README.md`, so that its Rust examples compile and run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

pub use animation::{Animation, Topology};
pub use codec::{
    AnimationCodec, EncodedPacket, EncoderSetup, ErrorBound, FourCc, FrameDecoder, FrameEncoder, Packet, ParsedPacket,
    StreamInfo, TypedCodec,
};
pub use error::{Error, Result};
pub use limits::Limits;
pub use metadata::{SceneMetadata, UpAxis};
pub use params::{
    DeclaredParams, DistortionKind, Param, ParamChoice, ParamKind, ParamSet, ParamSpec, ParamValue, RateLadder,
    SearchAxis, SearchSpace, Setting,
};
pub use quant::Quantizer;
pub use registry::CodecRegistry;
pub use stream::{
    decode_animation, decode_frame, decode_frame_checked, decode_packet_checked, encode_animation,
    encode_animation_fed, random_access_limits, DecodedPacket, Encoded, StreamDecoder, StreamEncoder,
};
