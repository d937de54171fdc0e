//! The `animcodec` library behind the command-line tool: the codec registry list and the
//! file formats (OBJ sequences, PC2, MDD, glTF/GLB morph-target animations).

pub mod describe;
pub mod formats;
pub mod harness;
pub mod output;
pub mod viewer;

use codec_core::{quant_delta::QuantDelta, CodecRegistry};

/// Every codec, one line each. This is the only place codecs are registered; streams name
/// their codec by FourCC, so the order here is only the order of listings and sweeps.
pub fn registry() -> CodecRegistry {
    CodecRegistry::new(vec![
        Box::new(QuantDelta),            // baseline, codec-core
        Box::new(codec_pca_aoi::PcaAoi), // issue #4, Lalos et al. 2017
        Box::new(codec_hosvd::Hosvd),    // issue #5, Romaszewski, Gawron, Opozda
        Box::new(codec_sac::Sac),        // issue #6, spectral deformation-gradient compression
        Box::new(codec_stseg::Stseg),    // issue #7, Luo et al. 2020
    ])
    .expect("codec names and FourCCs in the registry list are unique")
}
