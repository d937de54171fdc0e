//! Scene metadata a stream carries from the file it was encoded from to the files it is
//! decoded to: the up axis, the length unit and the time line of the source.
//!
//! None of it changes a position: the codecs code the coordinates as the source stored them.
//! Writers that can state the metadata do (USD's `upAxis`, `metersPerUnit`,
//! `timeCodesPerSecond`, `startTimeCode`; Alembic's time sampling start); writers whose format
//! fixes a convention the source does not follow convert on the way out and say so (glTF is +Y
//! up in metres; Alembic caches are read by DCCs as +Y up).
//!
//! In the container (version 4 and later) the metadata is a block of tagged entries after the
//! topology: `u8 tag, u8 length, length bytes`, little-endian. A reader skips tags it does not
//! know (metadata never changes how positions decode), and refuses a known tag whose length or
//! value is wrong. An animation without metadata writes no block, so its stream keeps the
//! container version it had before metadata existed.

use crate::bytes::{ByteReader, ByteWriter};
use crate::error::{Error, Result};

/// Which axis points up in the source's coordinates (USD's `upAxis`; `X` is not allowed there
/// either).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpAxis {
    /// +Y up: glTF, Alembic, Maya and Houdini by default, USD's default.
    Y,
    /// +Z up: Blender, 3ds Max, many USD pipelines.
    Z,
}

impl UpAxis {
    /// The axis' name as USD spells it.
    pub fn name(self) -> &'static str {
        match self {
            UpAxis::Y => "Y",
            UpAxis::Z => "Z",
        }
    }

    /// Parses USD's token (`"Y"`, `"Z"`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "Y" => Some(UpAxis::Y),
            "Z" => Some(UpAxis::Z),
            _ => None,
        }
    }
}

/// What the source file said about its scene, each field `None` when it said nothing.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SceneMetadata {
    /// The up axis.
    pub up_axis: Option<UpAxis>,
    /// Length of one coordinate unit in metres (USD's `metersPerUnit`: 0.01 for centimetres).
    pub meters_per_unit: Option<f64>,
    /// The source's time codes per second (USD's `timeCodesPerSecond`); a frame is
    /// `time_codes_per_second / frame_rate` time codes long.
    pub time_codes_per_second: Option<f64>,
    /// The time code of frame 0 (USD's time code, or Alembic's start time × the frame rate when
    /// [`SceneMetadata::time_codes_per_second`] is absent).
    pub start_time_code: Option<f64>,
}

/// Entry tags of the container's metadata block.
const TAG_UP_AXIS: u8 = 1;
const TAG_METERS_PER_UNIT: u8 = 2;
const TAG_TIME_CODES_PER_SECOND: u8 = 3;
const TAG_START_TIME_CODE: u8 = 4;

/// Largest metadata block a reader accepts: a few entries of a few bytes each; anything larger is
/// not metadata this format defines.
pub const MAX_METADATA_BYTES: usize = 4096;

const CTX: &str = "container metadata";

impl SceneMetadata {
    /// True when the source said nothing (no block is written).
    pub fn is_empty(&self) -> bool {
        *self == SceneMetadata::default()
    }

    /// Checks every present field: finite, and positive where a scale or a rate.
    pub fn validate(&self) -> Result<()> {
        let positive = |name: &str, v: Option<f64>| match v {
            Some(x) if !(x.is_finite() && x > 0.0) => {
                Err(Error::InvalidAnimation(format!("scene metadata: {name} {x} is not a finite positive number")))
            }
            _ => Ok(()),
        };
        positive("metersPerUnit", self.meters_per_unit)?;
        positive("timeCodesPerSecond", self.time_codes_per_second)?;
        if let Some(s) = self.start_time_code.filter(|s| !s.is_finite()) {
            return Err(Error::InvalidAnimation(format!("scene metadata: start time code {s} is not finite")));
        }
        Ok(())
    }

    /// Time codes per frame at `frame_rate`: `time_codes_per_second / frame_rate`, or 1 when the
    /// source gave no time codes per second (time codes are frames).
    pub fn time_codes_per_frame(&self, frame_rate: f32) -> f64 {
        self.time_codes_per_second.map_or(1.0, |tcps| tcps / frame_rate as f64)
    }

    /// The source time of frame 0 in seconds (0 when the source gave no start).
    pub fn start_seconds(&self, frame_rate: f32) -> f64 {
        let tcps = self.time_codes_per_second.unwrap_or(frame_rate as f64);
        self.start_time_code.map_or(0.0, |s| s / tcps)
    }

    /// The container's metadata block (empty when [`SceneMetadata::is_empty`]).
    pub fn to_block(&self) -> Vec<u8> {
        let mut w = ByteWriter::new();
        if let Some(axis) = self.up_axis {
            w.u8(TAG_UP_AXIS);
            w.u8(1);
            w.u8(axis.name().as_bytes()[0]);
        }
        for (tag, value) in [
            (TAG_METERS_PER_UNIT, self.meters_per_unit),
            (TAG_TIME_CODES_PER_SECOND, self.time_codes_per_second),
            (TAG_START_TIME_CODE, self.start_time_code),
        ] {
            if let Some(v) = value {
                w.u8(tag);
                w.u8(8);
                w.f64(v);
            }
        }
        w.as_slice().to_vec()
    }

    /// Parses a metadata block ([`SceneMetadata::to_block`]'s layout); unknown tags are skipped.
    pub fn from_block(block: &[u8]) -> Result<Self> {
        if block.len() > MAX_METADATA_BYTES {
            return Err(Error::malformed(
                CTX,
                "length",
                format!("{} bytes (at most {MAX_METADATA_BYTES})", block.len()),
            ));
        }
        let mut r = ByteReader::new(block, CTX);
        let mut meta = SceneMetadata::default();
        while r.remaining() > 0 {
            let tag = r.u8("tag")?;
            let len = r.u8("entry length")? as usize;
            let value = r.take(len, "entry")?;
            let f64_of = |what: &'static str| -> Result<f64> {
                let bytes: [u8; 8] =
                    value.try_into().map_err(|_| Error::malformed(CTX, what, format!("{len} bytes, expected 8")))?;
                Ok(f64::from_le_bytes(bytes))
            };
            match tag {
                TAG_UP_AXIS => {
                    let axis = match value {
                        [c] => UpAxis::from_name(&(*c as char).to_string()),
                        _ => None,
                    };
                    meta.up_axis = Some(axis.ok_or_else(|| Error::malformed(CTX, "up axis", "not Y or Z"))?);
                }
                TAG_METERS_PER_UNIT => meta.meters_per_unit = Some(f64_of("meters per unit")?),
                TAG_TIME_CODES_PER_SECOND => meta.time_codes_per_second = Some(f64_of("time codes per second")?),
                TAG_START_TIME_CODE => meta.start_time_code = Some(f64_of("start time code")?),
                _ => {}
            }
        }
        meta.validate().map_err(|e| Error::malformed(CTX, "value", e.to_string()))?;
        Ok(meta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_round_trips_and_empty_is_empty() {
        assert!(SceneMetadata::default().to_block().is_empty());
        let m = SceneMetadata {
            up_axis: Some(UpAxis::Z),
            meters_per_unit: Some(0.01),
            time_codes_per_second: Some(48.0),
            start_time_code: Some(-12.5),
        };
        assert_eq!(SceneMetadata::from_block(&m.to_block()).unwrap(), m);
        let only_axis = SceneMetadata { up_axis: Some(UpAxis::Y), ..Default::default() };
        assert_eq!(SceneMetadata::from_block(&only_axis.to_block()).unwrap(), only_axis);
    }

    #[test]
    fn unknown_tags_are_skipped_and_bad_values_refused() {
        let mut block = vec![200, 3, 1, 2, 3];
        block.extend(SceneMetadata { up_axis: Some(UpAxis::Z), ..Default::default() }.to_block());
        assert_eq!(SceneMetadata::from_block(&block).unwrap().up_axis, Some(UpAxis::Z));
        // A known tag with the wrong length, a wrong axis, a non-positive unit, a truncated entry.
        assert!(SceneMetadata::from_block(&[TAG_METERS_PER_UNIT, 4, 0, 0, 0, 0]).is_err());
        assert!(SceneMetadata::from_block(&[TAG_UP_AXIS, 1, b'X']).is_err());
        let mut zero = vec![TAG_METERS_PER_UNIT, 8];
        zero.extend(0f64.to_le_bytes());
        assert!(SceneMetadata::from_block(&zero).is_err());
        assert!(SceneMetadata::from_block(&[TAG_START_TIME_CODE, 8, 0]).is_err());
        assert!(SceneMetadata::from_block(&vec![0u8; MAX_METADATA_BYTES + 2]).is_err());
    }

    #[test]
    fn time_line() {
        let m = SceneMetadata { time_codes_per_second: Some(48.0), start_time_code: Some(24.0), ..Default::default() };
        assert_eq!(m.time_codes_per_frame(24.0), 2.0);
        assert_eq!(m.start_seconds(24.0), 0.5);
        let frames = SceneMetadata { start_time_code: Some(12.0), ..Default::default() };
        assert_eq!(frames.time_codes_per_frame(24.0), 1.0);
        assert_eq!(frames.start_seconds(24.0), 0.5);
    }
}
