//! Core of **animcodec**: the animation data model, the [`AnimationCodec`] trait, the `.anim`
//! container, quantization and entropy helpers, the registry type, synthetic test
//! animations, and the baseline codec [`quant_delta`].
//!
//! A codec crate implements [`AnimationCodec`] (plus a [`FrameEncoder`] and a
//! [`FrameDecoder`]) and is added to the one registry list in the `animcodec` crate.
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
pub mod quant_delta;
pub mod registry;
pub mod stream;
pub mod synth;
pub mod testing;
pub mod toolkit;
pub mod traversal;

pub use animation::{Animation, Topology};
pub use codec::{
    AnimationCodec, EncodedPacket, EncoderSetup, ErrorBound, FourCc, FrameDecoder, FrameEncoder, Packet, StreamInfo,
};
pub use error::{Error, Result};
pub use limits::Limits;
pub use metadata::{SceneMetadata, UpAxis};
pub use params::{
    DeclaredParams, DistortionKind, ParamChoice, ParamKind, ParamSet, ParamSpec, ParamValue, RateLadder, SearchAxis,
    SearchSpace,
};
pub use quant::Quantizer;
pub use registry::CodecRegistry;
pub use stream::{
    decode_animation, decode_frame, encode_animation, encode_animation_fed, DecodedPacket, Encoded, StreamDecoder,
    StreamEncoder,
};
