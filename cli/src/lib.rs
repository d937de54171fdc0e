//! The `animcodec` library behind the command-line tool: the codec registry list and the
//! file formats (OBJ sequences, PC2, MDD, glTF/GLB morph-target animations).

pub mod formats;

use codec_core::{quant_delta::QuantDelta, CodecRegistry};

/// Every codec, one line each. This is the only place codecs are registered.
pub fn registry() -> CodecRegistry {
    CodecRegistry::new(vec![
        Box::new(QuantDelta),
    ])
    .expect("codec names and FourCCs in the registry list are unique")
}
