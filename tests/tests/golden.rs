//! Golden streams: `tests/golden/` holds one small stream per codec and stream
//! version, made by that version of the codec, with the hash of its decoded frames in
//! `tests/golden/hashes.txt`. Every one must still decode to exactly those frames: a codec that
//! changes its bitstream bumps its stream version (`AnimationCodec::stream_version`) and keeps
//! decoding the versions that have golden files.
//!
//! A new codec or a new stream version gets its golden file with
//! `ANIMCODEC_WRITE_GOLDEN=1 cargo test -p conformance-tests --test golden`, which writes only
//! the missing files (existing golden files are never rewritten).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use animcodec::synth;
use codec_core::container::ContainerReader;
use codec_core::testing::shuffled_permutation;
use codec_core::{decode_animation, encode_animation, Animation, Limits, ParamValue};
use conformance_tests::registry;

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("golden")
}

/// FNV-1a (64 bit) over the frame count, vertex count, triangles and the bits of every
/// coordinate, little-endian: any change to the decoded frames changes it.
fn frames_hash(a: &Animation) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(&(a.frame_count() as u64).to_le_bytes());
    eat(&(a.vertex_count() as u64).to_le_bytes());
    for t in a.triangles() {
        for i in t {
            eat(&i.to_le_bytes());
        }
    }
    for x in a.positions() {
        eat(&x.to_bits().to_le_bytes());
    }
    format!("{h:016x}")
}

/// The animation every golden stream encodes: small, but with real motion and triangles.
fn golden_input() -> Animation {
    synth::waving_flag(8, 6, 16)
}

/// `hashes.txt`: `file frames vertices hash` per line, `#` comments.
fn read_hashes() -> BTreeMap<String, (usize, usize, String)> {
    let text = std::fs::read_to_string(golden_dir().join("hashes.txt")).unwrap_or_default();
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            assert_eq!(f.len(), 4, "hashes.txt: bad line '{l}'");
            (f[0].to_owned(), (f[1].parse().unwrap(), f[2].parse().unwrap(), f[3].to_owned()))
        })
        .collect()
}

fn file_name(codec: &str, version: u16) -> String {
    format!("{codec}-v{version}.anim")
}

#[test]
fn every_golden_stream_decodes_to_its_hash() {
    let registry = registry();
    let dir = golden_dir();
    let mut hashes = read_hashes();
    if std::env::var_os("ANIMCODEC_WRITE_GOLDEN").is_some() {
        let input = golden_input();
        for codec in registry.iter() {
            let name = file_name(codec.name(), codec.stream_version());
            if hashes.contains_key(&name) {
                continue;
            }
            let bytes = encode_animation(codec, &codec.default_params(), &input).unwrap();
            let decoded = decode_animation(&bytes, &registry, Limits::default()).unwrap();
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join(&name), &bytes).unwrap();
            eprintln!("wrote golden stream {name} ({} bytes)", bytes.len());
            hashes.insert(name, (decoded.frame_count(), decoded.vertex_count(), frames_hash(&decoded)));
        }
        let mut text = String::from(
            "# golden stream, frames, vertices, FNV-1a 64 of the decoded frames (tests/tests/golden.rs)\n",
        );
        for (file, (f, v, h)) in &hashes {
            text.push_str(&format!("{file} {f} {v} {h}\n"));
        }
        std::fs::write(dir.join("hashes.txt"), text).unwrap();
    }

    // Every registered codec has a golden stream for its current version.
    for codec in registry.iter() {
        let name = file_name(codec.name(), codec.stream_version());
        assert!(
            hashes.contains_key(&name),
            "{}: no golden stream for stream version {} ({name}); make it with ANIMCODEC_WRITE_GOLDEN=1 \
             (see tests/tests/golden.rs)",
            codec.name(),
            codec.stream_version()
        );
    }
    // Every golden stream decodes to its hash, and every file is listed.
    let files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".anim"))
        .collect();
    for f in &files {
        assert!(hashes.contains_key(f), "{f} is in tests/golden but not in hashes.txt");
    }
    for (file, (frames, vertices, hash)) in &hashes {
        let bytes = std::fs::read(dir.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        let header = ContainerReader::new(&bytes[..], Limits::default()).unwrap().header().clone();
        let codec = registry.by_fourcc(header.info.fourcc).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(file, &file_name(codec.name(), header.info.codec_version), "file name and header disagree");
        assert!(header.info.codec_version <= codec.stream_version(), "{file}: from a newer version of the codec");
        let decoded = decode_animation(&bytes, &registry, Limits::default())
            .unwrap_or_else(|e| panic!("{file} no longer decodes: {e}"));
        assert_eq!((decoded.frame_count(), decoded.vertex_count()), (*frames, *vertices), "{file}");
        assert_eq!(
            &frames_hash(&decoded),
            hash,
            "{file}: decodes to different frames than when it was made: the bitstream changed without a new \
             stream version"
        );
    }
}

/// Random access on every golden stream (every codec and stream version, container versions
/// 2 to 5 included): every frame through the codec's one-frame hook, on a decoder kept across
/// requests, equals that frame of the full decode bit for bit
/// ([`conformance_tests::suite::frames_of_packets_match_full_decode`]).
#[test]
fn every_frame_of_every_golden_stream_decodes_alone_as_in_the_full_decode() {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "anim") {
                out.push(path);
            }
        }
    }
    let registry = registry();
    let mut files = Vec::new();
    walk(&golden_dir(), &mut files);
    files.sort();
    assert!(files.len() >= 20, "only {} golden streams found", files.len());
    let mut single = 0;
    for file in &files {
        let bytes = std::fs::read(file).unwrap();
        let full = decode_animation(&bytes, &registry, Limits::default()).unwrap();
        conformance_tests::suite::frames_of_packets_match_full_decode(&bytes, &registry, Limits::default(), &full)
            .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let header = ContainerReader::new(&bytes[..], Limits::default()).unwrap().header().clone();
        let codec = registry.by_fourcc(header.info.fourcc).unwrap();
        let decoder = codec.new_decoder(&header.info, &header.config, &Limits::default()).unwrap();
        single += usize::from(decoder.decodes_single_frames());
    }
    // pca-aoi, hosvd and laplacian streams form one frame alone.
    assert!(single >= 10, "only {single} golden streams were decoded frame by frame");
}

#[test]
fn the_frames_hash_sees_one_bit() {
    let a = golden_input();
    let (topology, mut positions, fps) = a.clone().into_parts();
    positions[7] = f32::from_bits(positions[7].to_bits() ^ 1);
    let b = Animation::new(topology, positions, fps).unwrap();
    assert_ne!(frames_hash(&a), frames_hash(&b));
    assert_eq!(frames_hash(&a), frames_hash(&a.clone()));
}

/// `a` with its vertices renumbered by a deterministic (xorshift) shuffle.
fn shuffled(a: &Animation) -> Animation {
    let n = a.vertex_count();
    renumbered(a, &shuffled_permutation(n, n.max(1), 0x9e37_79b9_7f4a_7c15))
}

/// `a` with old vertex `v` renumbered `perm[v]`.
fn renumbered(a: &Animation, perm: &[usize]) -> Animation {
    let n = a.vertex_count();
    let triangles = a.triangles().iter().map(|t| t.map(|v| perm[v as usize] as u32)).collect();
    let mut positions = vec![0.0f32; a.positions().len()];
    for (t, frame) in a.frames().enumerate() {
        for v in 0..n {
            let dst = (t * n + perm[v]) * 3;
            positions[dst..dst + 3].copy_from_slice(&frame[3 * v..3 * v + 3]);
        }
    }
    let topology = codec_core::Topology::new(n, triangles).unwrap();
    Animation::new(topology, positions, a.frame_rate()).unwrap()
}

/// Container version 2 (compact topology coding) next to the version 1 goldens: the
/// committed version 2 streams decode to their input's triangles, and so does every golden
/// (container 1 ones in the input's order). `ANIMCODEC_WRITE_GOLDEN=1` writes
/// `container-v2/quant-delta-v1.anim` when missing (only a build that writes version 2 for
/// the golden input can: its list coding stays the smallest there).
#[test]
fn container_versions_keep_the_triangles() {
    let registry = registry();
    let input = golden_input();
    let dir = golden_dir().join("container-v2");
    let path = dir.join("quant-delta-v1.anim");
    if std::env::var_os("ANIMCODEC_WRITE_GOLDEN").is_some() && !path.exists() {
        let codec = registry.by_name("quant-delta").unwrap();
        let bytes = encode_animation(codec, &codec.default_params(), &input).unwrap();
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(&path, bytes).unwrap();
    }
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let header = ContainerReader::new(&bytes[..], Limits::default()).unwrap().header().clone();
    assert_eq!(header.container_version, 2);
    let decoded = decode_animation(&bytes, &registry, Limits::default()).unwrap();
    let hashes = read_hashes();
    assert_eq!(frames_hash(&decoded), hashes["quant-delta-v1.anim"].2, "same frames as the container 1 golden");
    assert!(codec_core::connectivity::same_triangles(decoded.topology(), input.topology()));
    // A mesh whose list coding zstd cannot shrink (regular numberings compress to almost
    // nothing): the flag with its vertices renumbered by a fixed shuffle. The connectivity
    // coding (method 1) is chosen.
    let larger = shuffled(&synth::waving_flag(24, 16, 3));
    let path = dir.join("quant-delta-v1-connectivity.anim");
    let codec = registry.by_name("quant-delta").unwrap();
    let fresh = encode_animation(codec, &codec.default_params(), &larger).unwrap();
    if std::env::var_os("ANIMCODEC_WRITE_GOLDEN").is_some() && !path.exists() {
        std::fs::write(&path, &fresh).unwrap();
    }
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let config_len = u32::from_le_bytes(bytes[32..36].try_into().unwrap()) as usize;
    assert_eq!(bytes[40 + config_len], 1, "topology coded with the connectivity method");
    let decoded = decode_animation(&bytes, &registry, Limits::default()).unwrap();
    assert!(codec_core::connectivity::same_triangles(decoded.topology(), larger.topology()));
    let now = decode_animation(&fresh, &registry, Limits::default()).unwrap();
    assert_eq!(decoded.positions(), now.positions(), "same frames as this build writes");
    for file in hashes.keys() {
        let bytes = std::fs::read(golden_dir().join(file)).unwrap();
        let header = ContainerReader::new(&bytes[..], Limits::default()).unwrap().header().clone();
        match header.container_version {
            1 => assert_eq!(header.info.topology, *input.topology(), "{file}: container 1 keeps the input's order"),
            2 | 3 => {
                assert!(codec_core::connectivity::same_triangles(&header.info.topology, input.topology()), "{file}")
            }
            v => panic!("{file}: container version {v}"),
        }
    }
}

/// Container version 3 (the traversal coding of the triangles, topology method 2). Real
/// meshes number their vertices locally but not regularly; a flag whose vertices are shuffled
/// within windows of 8 has that, and its stream as this build writes it is version 5 with
/// method 3 (see `container_v5_predicted_golden`), smaller in topology than methods 0 to 2. The
/// committed version 3 stream (`container-v3/quant-delta-v1-traversal.anim`, written by
/// `ANIMCODEC_WRITE_GOLDEN=1` when missing) still decodes to the same frames and triangles.
#[test]
fn container_v3_traversal_golden() {
    let registry = registry();
    let input = shuffled_within(&synth::waving_flag(24, 16, 3), 8);
    let codec = registry.by_name("quant-delta").unwrap();
    let fresh = encode_animation(codec, &codec.default_params(), &input).unwrap();
    let path = golden_dir().join("container-v3").join("quant-delta-v1-traversal.anim");
    if std::env::var_os("ANIMCODEC_WRITE_GOLDEN").is_some() && !path.exists() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &fresh).unwrap();
    }
    let topology_method = |bytes: &[u8]| {
        let config_len = u32::from_le_bytes(bytes[32..36].try_into().unwrap()) as usize;
        bytes[40 + config_len]
    };
    let fresh_header = ContainerReader::new(&fresh[..], Limits::default()).unwrap().header().clone();
    assert_eq!((fresh_header.container_version, topology_method(&fresh)), (5, 3), "this build's stream");
    let canonical = codec_core::connectivity::canonical_order(input.topology());
    let method_1 = codec_core::connectivity::encode(&canonical).unwrap().len();
    let method_2 = codec_core::traversal::encode(&canonical).unwrap().len();
    let list = codec_core::container::encode_topology_list(&canonical).len();
    assert!(
        fresh_header.topology_bytes <= method_1.min(list).min(method_2),
        "{} vs {method_1}, {method_2} and {list}",
        fresh_header.topology_bytes
    );
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let header = ContainerReader::new(&bytes[..], Limits::default()).unwrap().header().clone();
    assert_eq!((header.container_version, topology_method(&bytes)), (3, 2));
    let decoded = decode_animation(&bytes, &registry, Limits::default()).unwrap();
    assert!(codec_core::connectivity::same_triangles(decoded.topology(), input.topology()));
    let now = decode_animation(&fresh, &registry, Limits::default()).unwrap();
    assert_eq!(decoded.positions(), now.positions(), "same frames as this build writes");
    // Method 2 in a container that says version 2 is refused (an older reader's view).
    let mut relabelled = bytes.clone();
    relabelled[8..10].copy_from_slice(&2u16.to_le_bytes());
    let crc_at = header.header_bytes - 4;
    let crc = crc32fast::hash(&relabelled[..crc_at]);
    relabelled[crc_at..crc_at + 4].copy_from_slice(&crc.to_le_bytes());
    let e = ContainerReader::new(&relabelled[..], Limits::default()).map(|_| ()).expect_err("refused").to_string();
    assert!(e.contains("unknown topology coding method 2"), "{e}");
}

/// Container version 5 (topology method 3: the traversal with new vertices named by candidate
/// kinds). The flag of `container_v3_traversal_golden`, shuffled within windows of 8, is written
/// as version 5 with method 3 (an empty metadata block). The committed stream
/// (`container-v5/quant-delta-v1-predicted.anim`, written by `ANIMCODEC_WRITE_GOLDEN=1` when
/// missing) decodes to the same frames and triangles, this build writes it byte for byte, and
/// a reader of version 4 refuses its method 3.
#[test]
fn container_v5_predicted_golden() {
    let registry = registry();
    let input = shuffled_within(&synth::waving_flag(24, 16, 3), 8);
    let codec = registry.by_name("quant-delta").unwrap();
    let fresh = encode_animation(codec, &codec.default_params(), &input).unwrap();
    let path = golden_dir().join("container-v5").join("quant-delta-v1-predicted.anim");
    if std::env::var_os("ANIMCODEC_WRITE_GOLDEN").is_some() && !path.exists() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &fresh).unwrap();
    }
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(bytes, fresh, "this build writes the committed version 5 stream byte for byte");
    let header = ContainerReader::new(&bytes[..], Limits::default()).unwrap().header().clone();
    let config_len = u32::from_le_bytes(bytes[32..36].try_into().unwrap()) as usize;
    assert_eq!((header.container_version, bytes[40 + config_len]), (5, 3));
    assert!(header.metadata.is_empty());
    let decoded = decode_animation(&bytes, &registry, Limits::default()).unwrap();
    assert!(codec_core::connectivity::same_triangles(decoded.topology(), input.topology()));
    // Method 3 in a container that says version 4 is refused (an older reader's view).
    let mut relabelled = bytes.clone();
    relabelled[8..10].copy_from_slice(&4u16.to_le_bytes());
    let crc_at = header.header_bytes - 4;
    let crc = crc32fast::hash(&relabelled[..crc_at]);
    relabelled[crc_at..crc_at + 4].copy_from_slice(&crc.to_le_bytes());
    let e = ContainerReader::new(&relabelled[..], Limits::default()).map(|_| ()).expect_err("refused").to_string();
    assert!(e.contains("unknown topology coding method 3"), "{e}");
}

/// Container version 4 carries the source's scene metadata after the topology. The committed
/// stream (`container-v4/quant-delta-v1-metadata.anim`, written by `ANIMCODEC_WRITE_GOLDEN=1`
/// when missing) still reads with the same metadata and decodes to the same frames, and this
/// build writes it byte for byte (a change to the block would need a new container version).
#[test]
fn container_v4_metadata_golden() {
    let registry = registry();
    let metadata = codec_core::SceneMetadata {
        up_axis: Some(codec_core::UpAxis::Z),
        meters_per_unit: Some(0.01),
        time_codes_per_second: Some(48.0),
        start_time_code: Some(101.0),
    };
    let input = synth::waving_flag(12, 8, 3).with_metadata(metadata).unwrap();
    let codec = registry.by_name("quant-delta").unwrap();
    let fresh = encode_animation(codec, &codec.default_params(), &input).unwrap();
    let path = golden_dir().join("container-v4").join("quant-delta-v1-metadata.anim");
    if std::env::var_os("ANIMCODEC_WRITE_GOLDEN").is_some() && !path.exists() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &fresh).unwrap();
    }
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(bytes, fresh, "this build writes the committed version 4 stream byte for byte");
    let header = ContainerReader::new(&bytes[..], Limits::default()).unwrap().header().clone();
    assert_eq!((header.container_version, header.metadata), (4, metadata));
    let decoded = decode_animation(&bytes, &registry, Limits::default()).unwrap();
    assert_eq!(*decoded.metadata(), metadata);
    assert!(codec_core::connectivity::same_triangles(decoded.topology(), input.topology()));
    // Without metadata the same input keeps the version the topology needs (2 or 3).
    let plain = encode_animation(codec, &codec.default_params(), &synth::waving_flag(12, 8, 3)).unwrap();
    let plain_header = ContainerReader::new(&plain[..], Limits::default()).unwrap().header().clone();
    assert!(plain_header.container_version < 4 && plain_header.metadata.is_empty());
    let plain_decoded = decode_animation(&plain, &registry, Limits::default()).unwrap();
    assert_eq!(plain_decoded.positions(), decoded.positions(), "metadata changes no coded position");
}

/// `a` with each run of `window` consecutive vertex indices shuffled among themselves
/// (deterministic xorshift): a local, irregular numbering.
fn shuffled_within(a: &Animation, window: usize) -> Animation {
    renumbered(a, &shuffled_permutation(a.vertex_count(), window, 0x2545_f491_4f6c_dd1d))
}

/// hosvd stream version 4's column modes (regression on the leading `U1` columns,
/// parallelogram): the default golden input is too small for the encoder to pick them, so a
/// larger flag with fine quantization pins the regression decoder's arithmetic.
/// `ANIMCODEC_WRITE_GOLDEN=1` writes `hosvd-v4-modes/hosvd-v4.anim` and its hash when missing
/// (only a build whose hosvd writes version 4 can).
#[test]
fn hosvd_v4_column_modes_golden() {
    hosvd_column_modes_golden(4);
}

/// Version 5's guarded regression, on the same input as version 4's: pins the
/// absolute ridge and the clamp of the prediction.
#[test]
fn hosvd_v5_column_modes_golden() {
    hosvd_column_modes_golden(5);
}

fn hosvd_column_modes_golden(version: u16) {
    let data = hosvd_packet_golden(version, &format!("hosvd-v{version}-modes"), &[], "column modes");
    // The packet's last v bytes are the column modes (flag bit 4): both new modes occur.
    assert_eq!(data[0] & 16, 16, "column modes flag");
    let v = data[1] as usize; // varint, < 128 here
    let modes = &data[data.len() - v..];
    assert!(modes.contains(&1) && modes.contains(&2), "modes {modes:?}");
}

/// The golden hosvd stream of `version` in `dir` on the column-modes input (`rigid=false`,
/// `ss=0.6`, `quant=0.05`, then `extra`), written by `ANIMCODEC_WRITE_GOLDEN=1` when missing
/// (only by a build whose hosvd writes `version`): checks its version and that it decodes to its
/// hash, and returns its first packet's data for the caller's checks of the layout.
fn hosvd_packet_golden(version: u16, dir: &str, extra: &[(&str, ParamValue)], what: &str) -> Vec<u8> {
    use codec_core::container::Section;
    let registry = registry();
    let codec = registry.by_name("hosvd").unwrap();
    let dir = golden_dir().join(dir);
    let (path, hash_path) = (dir.join(format!("hosvd-v{version}.anim")), dir.join("hash.txt"));
    let input = synth::waving_flag(16, 12, 24);
    let specs = codec.param_specs();
    let base = [("rigid", ParamValue::Bool(false)), ("ss", ParamValue::Float(0.6)), ("quant", ParamValue::Float(0.05))];
    let params = base
        .iter()
        .chain(extra)
        .try_fold(codec.default_params(), |p, (name, value)| p.with(&specs, name, value.clone()))
        .unwrap();
    if std::env::var_os("ANIMCODEC_WRITE_GOLDEN").is_some() && !path.exists() && codec.stream_version() == version {
        let bytes = encode_animation(codec, &params, &input).unwrap();
        let decoded = decode_animation(&bytes, &registry, Limits::default()).unwrap();
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(&path, &bytes).unwrap();
        std::fs::write(&hash_path, format!("{}\n", frames_hash(&decoded))).unwrap();
    }
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let hash = std::fs::read_to_string(&hash_path).unwrap_or_else(|e| panic!("{}: {e}", hash_path.display()));
    let mut reader = ContainerReader::new(&bytes[..], Limits::default()).unwrap();
    assert_eq!(reader.header().info.codec_version, version);
    let Some(Ok(Section::Packet(packet))) = reader.next_section() else { panic!("no packet") };
    let decoded = decode_animation(&bytes, &registry, Limits::default()).unwrap();
    assert_eq!(frames_hash(&decoded), hash.trim(), "hosvd v{version} {what} decode to their golden frames");
    packet.data.to_vec()
}

/// hosvd stream version 7's per-vertex step scales (`relstep`; the default golden input's even
/// edges leave them off): the column-modes input with `relstep=1` pins the scales'
/// arithmetic (embedding of the decoded leads, edge lengths, clamp, RMS normalisation).
/// `ANIMCODEC_WRITE_GOLDEN=1` writes `hosvd-v7-relstep/hosvd-v7.anim` and its hash when missing
/// (only a build whose hosvd writes version 7 can).
#[test]
fn hosvd_v7_relstep_golden() {
    let extra = [("relstep", ParamValue::Float(1.0)), ("relstep_auto", ParamValue::Bool(false))];
    let data = hosvd_packet_golden(7, "hosvd-v7-relstep", &extra, "step scales");
    // Flag bit 6, and the strength byte (4) before the three gains (f32) and the centre.
    assert_eq!(data[0] & 64, 64, "step scales flag");
    assert_eq!(data[data.len() - 25], 4, "strength byte");
}
