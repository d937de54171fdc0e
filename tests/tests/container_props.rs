//! Suite item 9: property tests of the `.anim` container with arbitrary packets (random
//! payloads, frame splits, keyframe flags, configuration bytes, small topologies), and of the
//! quantizer's serialization and clamping (codec-core covers its error bound and monotonicity).

use std::io::Cursor;

use codec_core::bytes::{ByteReader, ByteWriter};
use codec_core::container::{read_index, read_packet_at, seek_packets, ContainerReader, ContainerWriter, Section};
use codec_core::{FourCc, Limits, Packet, Quantizer, Topology};
use proptest::prelude::*;

/// A topology of 1..=24 vertices with up to 12 triangles (degenerate ones allowed).
fn topology() -> impl Strategy<Value = Topology> {
    (1usize..=24).prop_flat_map(|v| {
        proptest::collection::vec(proptest::array::uniform3(0..v as u32), 0..12)
            .prop_map(move |t| Topology::new(v, t).expect("indices below the vertex count"))
    })
}

/// Packets covering consecutive frame ranges from 0: `(frame_count, keyframe, payload)`.
fn packets() -> impl Strategy<Value = Vec<Packet>> {
    proptest::collection::vec((1u32..=6, any::<bool>(), proptest::collection::vec(any::<u8>(), 0..300)), 1..8).prop_map(
        |raw| {
            let mut first = 0;
            raw.into_iter()
                .map(|(n, key, data)| {
                    let p = Packet { first_frame: first, frame_count: n, keyframe: key, data };
                    first += n;
                    p
                })
                .collect()
        },
    )
}

#[derive(Debug)]
struct Stream {
    bytes: Vec<u8>,
    fourcc: FourCc,
    version: u16,
    topology: Topology,
    rate: f32,
    config: Vec<u8>,
    packets: Vec<Packet>,
}

fn stream() -> impl Strategy<Value = Stream> {
    (
        proptest::array::uniform4(any::<u8>()),
        1u16..=u16::MAX,
        topology(),
        0.001f32..1000.0,
        proptest::collection::vec(any::<u8>(), 0..40),
        packets(),
    )
        .prop_map(|(fourcc, version, topology, rate, config, packets)| {
            let frames: usize = packets.iter().map(|p| p.frame_count as usize).sum();
            let mut w = ContainerWriter::new(Vec::new(), FourCc(fourcc), version, &topology, frames, rate, &config)
                .expect("header");
            for p in &packets {
                w.write_packet(p).expect("packet");
            }
            let bytes = w.finish().expect("finish");
            Stream { bytes, fourcc: FourCc(fourcc), version, topology, rate, config, packets }
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn container_round_trips_sequentially_and_by_index(s in stream()) {
        let frames: usize = s.packets.iter().map(|p| p.frame_count as usize).sum();
        let mut r = ContainerReader::new(&s.bytes[..], Limits::default()).unwrap();
        let h = r.header().clone();
        prop_assert_eq!(h.info.fourcc, s.fourcc);
        prop_assert_eq!(h.info.codec_version, s.version);
        prop_assert_eq!(&h.info.topology, &s.topology);
        prop_assert_eq!(h.info.frame_count, frames);
        prop_assert_eq!(h.info.frame_rate.to_bits(), s.rate.to_bits());
        prop_assert_eq!(&h.config, &s.config);
        let mut got = Vec::new();
        let mut index = None;
        while let Some(sec) = r.next_section() {
            match sec.unwrap() {
                Section::Packet(p) => got.push(p),
                Section::End(i) => index = Some(i),
            }
        }
        prop_assert_eq!(&got, &s.packets);
        let index = index.expect("index read at the end");
        let mut cur = Cursor::new(&s.bytes);
        let (h2, index2) = read_index(&mut cur, Limits::default()).unwrap();
        prop_assert_eq!(&index2, &index);
        prop_assert_eq!(h2.header_bytes, h.header_bytes);
        // Read packets back in reverse order, to exercise seeking.
        for (e, p) in index2.iter().zip(&s.packets).rev() {
            prop_assert_eq!(&read_packet_at(&mut cur, e, &h2, Limits::default()).unwrap(), p);
        }
        for t in 0..frames {
            let (start, target) = seek_packets(&index2, t).expect("frame in range");
            let e = index2[target];
            prop_assert!((e.first_frame as usize..(e.first_frame + e.frame_count) as usize).contains(&t));
            prop_assert!(start <= target);
            prop_assert!(index2[start].keyframe || start == 0);
            prop_assert!(index2[start + 1..=target].iter().all(|e| !e.keyframe));
        }
        prop_assert!(seek_packets(&index2, frames).is_none());
    }

    #[test]
    fn container_rejects_any_truncation_or_flip(s in stream(), cut in any::<prop::sample::Index>(),
                                               pos in any::<prop::sample::Index>(), mask in 1u8..=255) {
        let read_all = |b: &[u8]| -> codec_core::Result<()> {
            let mut r = ContainerReader::new(b, Limits::default())?;
            while let Some(sec) = r.next_section() {
                sec?;
            }
            Ok(())
        };
        let cut = cut.index(s.bytes.len());
        prop_assert!(read_all(&s.bytes[..cut]).is_err());
        prop_assert!(read_index(&mut Cursor::new(&s.bytes[..cut]), Limits::default()).is_err());
        let mut b = s.bytes.clone();
        let at = pos.index(b.len());
        b[at] ^= mask;
        prop_assert!(read_all(&b).is_err());
    }

    #[test]
    fn quantizer_serialization_round_trips(lo in -1.0e6f32..1.0e6, width in 0.0f32..1.0e6, bits in 1u8..=32) {
        let q = Quantizer::new(lo, lo + width, bits).unwrap();
        let mut w = ByteWriter::new();
        q.write(&mut w);
        let bytes = w.into_vec();
        let back = Quantizer::read(&mut ByteReader::new(&bytes, "test"), "q").unwrap();
        prop_assert_eq!(back, q);
        for cut in 0..bytes.len() {
            prop_assert!(Quantizer::read(&mut ByteReader::new(&bytes[..cut], "test"), "q").is_err());
        }
    }

    #[test]
    fn quantizer_read_of_arbitrary_bytes_is_valid_or_err(bytes in proptest::collection::vec(any::<u8>(), 0..12)) {
        if let Ok(q) = Quantizer::read(&mut ByteReader::new(&bytes, "test"), "q") {
            prop_assert!((1..=32).contains(&q.bits()));
            prop_assert!(q.min().is_finite() && q.max().is_finite() && q.min() <= q.max());
        }
    }

    #[test]
    fn quantizer_clamps_out_of_range_values(lo in -100.0f32..100.0, width in 0.0f32..100.0, bits in 1u8..=24,
                                            x in -1.0e30f32..1.0e30) {
        let q = Quantizer::new(lo, lo + width, bits).unwrap();
        let c = q.quantize(x);
        prop_assert!(c <= q.max_code());
        let y = q.dequantize(c);
        prop_assert!(y >= q.min() && y <= q.max(), "{} outside [{}, {}]", y, q.min(), q.max());
        // Codes past the top are clamped too.
        prop_assert_eq!(q.dequantize(u32::MAX), q.dequantize(q.max_code()));
    }
}
