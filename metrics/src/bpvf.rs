//! Rate: bits per vertex per frame (bpvf) from stream byte counts.

use codec_core::{Error, Result};

use crate::common::CTX;

/// `8 · total_bytes / (vertex_count · frame_count)`: the whole stream, header and topology
/// included. Fails when either count is zero.
pub fn bpvf(total_bytes: u64, vertex_count: usize, frame_count: usize) -> Result<f64> {
    let vf = vertex_frames(vertex_count, frame_count)?;
    Ok(total_bytes as f64 * 8.0 / vf)
}

/// bpvf without the topology section: `8 · (total_bytes − topology_bytes) / (V · F)`.
/// `topology_bytes` is the container's compressed triangle list (`Header::topology_bytes`);
/// the rest of the header stays in. Fails when a count is zero or the topology is larger than
/// the stream.
pub fn geometry_bpvf(total_bytes: u64, topology_bytes: u64, vertex_count: usize, frame_count: usize) -> Result<f64> {
    let vf = vertex_frames(vertex_count, frame_count)?;
    let geometry = total_bytes.checked_sub(topology_bytes).ok_or_else(|| {
        Error::InvalidAnimation(format!(
            "{CTX}: topology section of {topology_bytes} bytes is larger than the {total_bytes}-byte stream"
        ))
    })?;
    Ok(geometry as f64 * 8.0 / vf)
}

fn vertex_frames(vertex_count: usize, frame_count: usize) -> Result<f64> {
    if vertex_count == 0 || frame_count == 0 {
        return Err(Error::InvalidAnimation(format!(
            "{CTX}: bpvf needs at least one vertex and one frame (got {vertex_count} vertices, {frame_count} frames)"
        )));
    }
    Ok(vertex_count as f64 * frame_count as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn by_hand() {
        // 1000 bytes = 8000 bits over 100 vertices × 10 frames = 8 bpvf.
        assert_eq!(bpvf(1000, 100, 10).unwrap(), 8.0);
        // Without a 250-byte topology: 750 · 8 / 1000 = 6 bpvf.
        assert_eq!(geometry_bpvf(1000, 250, 100, 10).unwrap(), 6.0);
        assert_eq!(geometry_bpvf(1000, 1000, 100, 10).unwrap(), 0.0);
    }

    #[test]
    fn bad_counts_are_errors() {
        assert!(bpvf(1, 0, 10).unwrap_err().to_string().contains("0 vertices"));
        assert!(bpvf(1, 10, 0).is_err());
        assert!(geometry_bpvf(10, 11, 1, 1).unwrap_err().to_string().contains("larger than"));
    }
}
