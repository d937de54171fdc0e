//! The registry type: one list holding every codec, looked up by name or FourCC.
//!
//! The explicit list of codecs lives in one place (the `animcodec` crate's `registry()`),
//! one line per codec, in the style of Symphonia's codec registry.

use crate::codec::{AnimationCodec, FourCc};
use crate::error::{Error, Result};

/// Every available codec.
pub struct CodecRegistry {
    codecs: Vec<Box<dyn AnimationCodec>>,
}

impl std::fmt::Debug for CodecRegistry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.codecs.iter().map(|c| (c.name(), c.fourcc()))).finish()
    }
}

impl CodecRegistry {
    /// A registry holding `codecs`. Names and FourCCs must be unique: a duplicate is a
    /// programming error in the list and reported as one.
    pub fn new(codecs: Vec<Box<dyn AnimationCodec>>) -> Result<Self> {
        for (i, a) in codecs.iter().enumerate() {
            for b in &codecs[..i] {
                if a.name() == b.name() || a.fourcc() == b.fourcc() {
                    return Err(Error::Unsupported {
                        context: "registry".into(),
                        detail: format!(
                            "codecs '{}' ({}) and '{}' ({}) clash",
                            a.name(),
                            a.fourcc(),
                            b.name(),
                            b.fourcc()
                        ),
                    });
                }
            }
        }
        Ok(Self { codecs })
    }

    /// The registry with only the codecs `keep` accepts, in the same order (e.g. the conformance
    /// suite restricted to one codec while working on it).
    pub fn retain(mut self, mut keep: impl FnMut(&dyn AnimationCodec) -> bool) -> Self {
        self.codecs.retain(|c| keep(c.as_ref()));
        self
    }

    /// All codecs, in registration order.
    pub fn iter(&self) -> impl Iterator<Item = &dyn AnimationCodec> {
        self.codecs.iter().map(|c| c.as_ref())
    }

    /// Comma-separated names, for error messages.
    pub fn names(&self) -> String {
        self.codecs.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ")
    }

    /// The codec called `name`; the error lists the valid names.
    pub fn by_name(&self, name: &str) -> Result<&dyn AnimationCodec> {
        self.iter()
            .find(|c| c.name() == name)
            .ok_or_else(|| Error::UnknownCodec { requested: name.to_string(), available: self.names() })
    }

    /// The codec whose streams carry `fourcc`.
    pub fn by_fourcc(&self, fourcc: FourCc) -> Result<&dyn AnimationCodec> {
        self.iter().find(|c| c.fourcc() == fourcc).ok_or_else(|| Error::UnknownCodec {
            requested: format!("FourCC '{fourcc}'"),
            available: self.iter().map(|c| format!("{} ({})", c.name(), c.fourcc())).collect::<Vec<_>>().join(", "),
        })
    }
}
