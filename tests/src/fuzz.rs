//! The bodies of the fuzz targets in `fuzz/` (cargo-fuzz / libFuzzer), shared with the corpus
//! replay test (`tests/tests/fuzz_corpus.rs`), which runs every committed corpus file through
//! the same function on every `cargo test`.
//!
//! Each function panics on a finding: a panic inside the code under test, an `Ok` result of the
//! wrong shape or with non-finite coordinates, or a peak of live memory above its budget (for
//! streams: [`peak_budget`] of the decoding [`Limits`]; for readers, a multiple of the input
//! size). Errors are the expected outcome of most inputs and are fine.
//!
//! Targets (the names of `fuzz/fuzz_targets/*.rs` and of `fuzz/corpus/*`):
//! - `container`: any bytes as an `.anim` stream: full decode, index + random access.
//! - `codec_<name>` (one per registered codec, `-` → `_`): structure-aware. The input is a
//!   list of records `[kind: u8][len: u16 LE][len bytes]`; the first is the codec config, each
//!   further one a packet of `1 + kind / 2` frames (keyframe if `kind` is odd). They are
//!   written into a valid container (right FourCC and version, the [`fuzz_topology`], frame
//!   count = the packets' sum, every checksum right), so the codec's own parser sees them.
//! - `read_pc2`, `read_mdd`, `read_obj`, `read_gltf`, `read_usd`, `read_usdc`, `read_abc`: the file
//!   readers on any bytes (`read_usd` from text layers, `read_usdc` from crate files and usdz
//!   packages; both call the one USD entry point, which tells the three apart by their first
//!   bytes).

use std::io::Cursor;
use std::path::{Path, PathBuf};

use animcodec::synth;
use codec_core::container::{self, ContainerWriter};
use codec_core::{Animation, Limits, Packet, Topology};

use crate::peak_budget;

/// Every target name, in the order of `fuzz/fuzz_targets`.
pub fn targets() -> Vec<String> {
    let mut t = vec!["container".to_owned()];
    for codec in animcodec::registry().iter() {
        t.push(format!("codec_{}", codec.name().replace('-', "_")));
    }
    t.extend(["read_pc2", "read_mdd", "read_obj", "read_gltf", "read_usd", "read_usdc", "read_abc"].map(String::from));
    t
}

/// Runs the target named `target` (see [`targets`]) on `data`.
pub fn run(target: &str, data: &[u8]) {
    match target {
        "container" => container(data),
        "read_pc2" => read_pc2(data),
        "read_mdd" => read_mdd(data),
        "read_obj" => read_obj(data),
        "read_gltf" => read_gltf(data),
        "read_usd" => read_usd(data),
        "read_abc" => read_abc(data),
        "read_usdc" => read_usdc(data),
        t => match t.strip_prefix("codec_") {
            Some(codec) => codec_stream(&codec.replace('_', "-"), data),
            None => panic!("unknown fuzz target '{t}'"),
        },
    }
}

/// Limits for fuzzed streams: small enough that a decoder sizing a buffer from an unchecked
/// field is caught by the peak check, or spending work from one is refused (so no input holds
/// a fuzzer for long), large enough for the seeds.
pub fn fuzz_limits() -> Limits {
    Limits {
        max_vertices: 1 << 16,
        max_frames: 1 << 12,
        max_triangles: 1 << 17,
        max_alloc_bytes: 8 << 20,
        max_work: FUZZ_MAX_WORK,
    }
}

/// Work budget of a fuzzed decode ([`Limits::max_work`]): about a second of decoding.
pub const FUZZ_MAX_WORK: u64 = 1 << 30;

/// Runs `f` and panics if the live memory it peaks at exceeds `budget` bytes.
fn within(what: &str, budget: u64, f: impl FnOnce()) {
    let peak = crate::measure_peak(f);
    assert!(peak <= budget, "{what}: held {peak} bytes at peak, over the budget of {budget}");
}

/// Decodes a stream fully and frame `t` by random access; `Ok` results must be finite and
/// of the declared shape.
fn decode_stream(bytes: &[u8], limits: Limits) {
    let registry = animcodec::registry();
    within("decode", peak_budget(&limits), || {
        if let Ok(a) = codec_core::decode_animation(bytes, &registry, limits) {
            assert!(a.positions().iter().all(|x| x.is_finite()), "decoded non-finite coordinates");
            assert_eq!(a.positions().len(), a.frame_count() * a.vertex_count() * 3);
        }
    });
    within("random access", peak_budget(&limits), || {
        let mut src = Cursor::new(bytes);
        if let Ok((header, index)) = container::read_index(&mut src, limits) {
            for e in &index {
                let _ = container::read_packet_at(&mut src, e, &header, limits);
            }
            let t = header.info.frame_count / 2;
            if let Ok(frame) = codec_core::decode_frame(&mut Cursor::new(bytes), &registry, limits, t) {
                assert_eq!(frame.len(), header.info.vertex_count() * 3);
                assert!(frame.iter().all(|x| x.is_finite()), "decoded non-finite coordinates");
            }
        }
    });
}

/// Target `container`.
pub fn container(data: &[u8]) {
    decode_stream(data, fuzz_limits());
}

/// The mesh every structure-aware codec input is decoded against: a 5 × 4 flag.
pub fn fuzz_topology() -> Topology {
    synth::flag_topology(5, 4)
}

/// The animation the codec seeds encode (on [`fuzz_topology`]).
pub fn fuzz_animation(frames: usize) -> Animation {
    synth::waving_flag(5, 4, frames)
}

/// Splits a structure-aware input into (config, packets); `None` when it has no record.
pub fn parse_records(data: &[u8]) -> Option<(Vec<u8>, Vec<Packet>)> {
    let mut records = Vec::new();
    let mut rest = data;
    while rest.len() >= 3 {
        let kind = rest[0];
        let len = u16::from_le_bytes([rest[1], rest[2]]) as usize;
        let body = &rest[3..(3 + len).min(rest.len())];
        records.push((kind, body.to_vec()));
        rest = &rest[(3 + len).min(rest.len())..];
    }
    let mut it = records.into_iter();
    let (_, config) = it.next()?;
    let mut first_frame = 0u32;
    let packets = it
        .map(|(kind, data)| {
            let frame_count = 1 + (kind >> 1) as u32;
            let p = Packet { first_frame, frame_count, keyframe: kind & 1 == 1, data };
            first_frame += frame_count;
            p
        })
        .collect();
    Some((config, packets))
}

/// The record form of a config and packets (what [`parse_records`] reads); packets of more
/// than 128 frames or 64 KiB do not fit and are cut.
pub fn to_records(config: &[u8], packets: &[Packet]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut push = |kind: u8, body: &[u8]| {
        let body = &body[..body.len().min(u16::MAX as usize)];
        out.push(kind);
        out.extend_from_slice(&(body.len() as u16).to_le_bytes());
        out.extend_from_slice(body);
    };
    push(0, config);
    for p in packets {
        let frames = p.frame_count.clamp(1, 128) - 1;
        push(((frames as u8) << 1) | p.keyframe as u8, &p.data);
    }
    out
}

/// Targets `codec_<name>`.
pub fn codec_stream(codec_name: &str, data: &[u8]) {
    if let Some(bytes) = codec_container(codec_name, data) {
        decode_stream(&bytes, fuzz_limits());
    }
}

/// The container a structure-aware input of codec `codec_name` stands for (see the module
/// documentation); `None` when it has no record or no frame. Public for the C library's replay
/// of these corpora (`capi/tests/fuzz_corpus.rs`).
pub fn codec_container(codec_name: &str, data: &[u8]) -> Option<Vec<u8>> {
    let registry = animcodec::registry();
    let codec = registry.by_name(codec_name).unwrap_or_else(|e| panic!("{e}"));
    let (config, packets) = parse_records(data)?;
    let frames: usize = packets.iter().map(|p| p.frame_count as usize).sum();
    if frames == 0 {
        return None;
    }
    let topology = fuzz_topology();
    let mut w = ContainerWriter::new(
        Vec::new(),
        codec.fourcc(),
        codec.stream_version(),
        &topology,
        frames,
        synth::FRAME_RATE,
        &config,
    )
    .expect("a valid header");
    for p in &packets {
        w.write_packet(p).expect("packets written in order");
    }
    Some(w.finish().expect("packets cover the frames"))
}

/// Live-memory budget of a reader on an input of `len` bytes: the file's positions as `f32`
/// and `f64` a few times over, plus a fixed allowance for the parsers' own tables.
fn reader_budget(len: usize) -> u64 {
    64 * len as u64 + (16 << 20)
}

/// Target `read_pc2`.
pub fn read_pc2(data: &[u8]) {
    within("read_pc2", reader_budget(data.len()), || {
        if let Ok((h, p)) = animcodec::formats::pc2::parse_pc2(data, "fuzz.pc2") {
            assert_eq!(p.len(), h.vertex_count * h.frame_count * 3);
        }
    });
}

/// Target `read_mdd`.
pub fn read_mdd(data: &[u8]) {
    within("read_mdd", reader_budget(data.len()), || {
        let _ = animcodec::formats::mdd::parse_mdd(data, "fuzz.mdd");
    });
}

/// Target `read_obj`.
pub fn read_obj(data: &[u8]) {
    within("read_obj", reader_budget(data.len()), || {
        if let Ok(mesh) = animcodec::formats::obj::parse_obj(data, "fuzz.obj") {
            let n = mesh.vertex_count() as u32;
            assert!(mesh.triangles.iter().flatten().all(|&i| i < n), "triangle index out of range");
        }
    });
}

/// Target `read_gltf` (GLB or glTF JSON; external buffers are not resolved). The read's own
/// memory budget is 8 MiB, half the target's floor: a Draco primitive decodes under limits
/// taken from it (a few hundred bytes of Draco data may legitimately decode to megabytes).
pub fn read_gltf(data: &[u8]) {
    within("read_gltf", reader_budget(data.len()), || {
        let selection = animcodec::formats::gltf::GltfSelection {
            frame_rate: Some(synth::FRAME_RATE),
            memory_budget: Some(8 << 20),
            ..Default::default()
        };
        if let Ok(a) = animcodec::formats::gltf::parse_gltf_with(data, None, "fuzz.glb", &selection) {
            assert!(a.positions().iter().all(|x| x.is_finite()));
        }
    });
}

/// Target `read_usd` (seeded with USD text layers; crate files and packages are read too).
/// The read's own memory budget is a quarter of the target's, so a layer whose cache would be
/// far larger than the file (a long animated mesh beside a large static one) is refused
/// before anything is allocated.
pub fn read_usd(data: &[u8]) {
    read_usd_layer("read_usd", data);
}

/// Target `read_usdc`: the same reader, seeded with crate files (ours and usd-core's) and
/// usdz packages. A crate file's time samples may share one array, so a small file can stand
/// for a large cache: the read's budget refuses it before it is allocated.
pub fn read_usdc(data: &[u8]) {
    read_usd_layer("read_usdc", data);
}

fn read_usd_layer(target: &str, data: &[u8]) {
    let budget = reader_budget(data.len());
    within(target, budget, || {
        if let Ok(a) = animcodec::formats::usd::parse_usd(data, "fuzz.usd", None, Some(budget / 4)) {
            assert!(a.positions().iter().all(|x| x.is_finite()));
            let n = a.vertex_count() as u32;
            assert!(a.triangles().iter().flatten().all(|&i| i < n), "triangle index out of range");
        }
    });
}

/// Target `read_abc` (an Alembic archive; HDF5 ones are refused by their magic). As for
/// `read_usd`, the read's own memory budget is a quarter of the target's.
pub fn read_abc(data: &[u8]) {
    let budget = reader_budget(data.len());
    within("read_abc", budget, || {
        if let Ok(a) = animcodec::formats::abc::parse_abc(data, "fuzz.abc", None, None, Some(budget / 4)) {
            assert!(a.positions().iter().all(|x| x.is_finite()));
            let n = a.vertex_count() as u32;
            assert!(a.triangles().iter().flatten().all(|&i| i < n), "triangle index out of range");
        }
        let _ = animcodec::formats::abc::parse_meshes(data, "fuzz.abc");
    });
}

/// `fuzz/corpus`: one folder per target (cargo-fuzz's layout), committed.
pub fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("fuzz").join("corpus")
}

/// Prefix of the generated seed files in a corpus folder. Files with it belong to [`seeds`]:
/// [`write_seeds`] rewrites and deletes them; every other file (what a fuzzer kept, `regress-*`
/// findings) is never touched.
pub const SEED_PREFIX: &str = "seed-";

/// How one committed seed file differs from what [`seeds`] makes now.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SeedDifference {
    /// The generator makes it but no file is committed.
    Missing,
    /// A committed `seed-*` file the generator no longer makes (a setting or codec removed).
    Orphan,
    /// Both exist with different bytes.
    Changed,
    /// Both exist with different bytes, on a CPU that is not at the SIMD level the seeds are
    /// written at ([`seeds_are_exact_here`]), and the committed file still decodes: tolerated
    /// (faer's kernels round differently without AVX2, and some encoders' bytes follow them).
    ChangedOnThisCpu,
}

impl SeedDifference {
    /// Whether this difference makes the committed seeds stale (everything but
    /// [`SeedDifference::ChangedOnThisCpu`]).
    pub fn is_stale(&self) -> bool {
        *self != SeedDifference::ChangedOnThisCpu
    }
}

/// Whether this CPU makes every seed exactly as committed: x86-64 with AVX2 and FMA (x86-64-v3
/// and up), the level the seeds are written at. Measured under `qemu-x86_64 -cpu`:
/// AVX-512 and Haswell (AVX2 + FMA) make every seed alike; Nehalem (SSE only) makes one sac
/// seed (`codec_sac/seed-flag-low`) differently, because faer's SIMD paths round differently
/// (the decoders agree: `tests/tests/simd_levels.rs`). Elsewhere [`seed_differences`] only
/// asks a changed seed to still decode.
pub fn seeds_are_exact_here() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether `data` is a valid input of `target` all the way through: the stream decodes, or the
/// file reads (not just "no panic", which every corpus file must give).
fn decodes(target: &str, data: &[u8]) -> bool {
    let registry = animcodec::registry();
    match target {
        "container" => codec_core::decode_animation(data, &registry, fuzz_limits()).is_ok(),
        "read_pc2" => animcodec::formats::pc2::parse_pc2(data, "seed.pc2").is_ok(),
        "read_mdd" => animcodec::formats::mdd::parse_mdd(data, "seed.mdd").is_ok(),
        "read_obj" => animcodec::formats::obj::parse_obj(data, "seed.obj").is_ok(),
        "read_gltf" => animcodec::formats::gltf::parse_gltf(data, None, "seed.glb", synth::FRAME_RATE).is_ok(),
        "read_usd" | "read_usdc" => animcodec::formats::usd::parse_usd(data, "seed.usd", None, None).is_ok(),
        "read_abc" => animcodec::formats::abc::parse_abc(data, "seed.abc", None, None, None).is_ok(),
        t => t
            .strip_prefix("codec_")
            .and_then(|c| codec_container(&c.replace('_', "-"), data))
            .is_some_and(|bytes| codec_core::decode_animation(&bytes, &registry, fuzz_limits()).is_ok()),
    }
}

/// The committed seeds compared with [`seeds`] in memory (nothing is written): every
/// difference as `(target, file name, difference)`, sorted. No stale one
/// ([`SeedDifference::is_stale`]) when `ANIMCODEC_WRITE_FUZZ_SEEDS=1` would change nothing.
pub fn seed_differences() -> Vec<(String, String, SeedDifference)> {
    let root = corpus_dir();
    let exact = seeds_are_exact_here();
    let mut expected = std::collections::BTreeMap::new();
    for (target, name, bytes) in seeds() {
        expected.insert((target, format!("{SEED_PREFIX}{name}")), bytes);
    }
    let mut out = Vec::new();
    for ((target, file), bytes) in &expected {
        match std::fs::read(root.join(target).join(file)) {
            Ok(committed) if &committed == bytes => {}
            Ok(committed) if !exact && decodes(target, &committed) => {
                out.push((target.clone(), file.clone(), SeedDifference::ChangedOnThisCpu))
            }
            Ok(_) => out.push((target.clone(), file.clone(), SeedDifference::Changed)),
            Err(_) => out.push((target.clone(), file.clone(), SeedDifference::Missing)),
        }
    }
    for (target, file) in committed_seed_files(&root) {
        if !expected.contains_key(&(target.clone(), file.clone())) {
            out.push((target, file, SeedDifference::Orphan));
        }
    }
    out.sort_by(|a, b| (&a.0, &a.1).cmp(&(&b.0, &b.1)));
    out
}

/// Every `seed-*` file under `root/<target>/`, as `(target, file name)`.
fn committed_seed_files(root: &Path) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let Ok(dirs) = std::fs::read_dir(root) else { return out };
    for dir in dirs.flatten().filter(|d| d.path().is_dir()) {
        let target = dir.file_name().to_string_lossy().into_owned();
        for f in std::fs::read_dir(dir.path()).into_iter().flatten().flatten() {
            let file = f.file_name().to_string_lossy().into_owned();
            if file.starts_with(SEED_PREFIX) {
                out.push((target.clone(), file));
            }
        }
    }
    out
}

/// Makes the committed seeds equal to [`seeds`]: writes the missing and changed files (not
/// those only this CPU makes differently, [`SeedDifference::ChangedOnThisCpu`]) and deletes
/// orphaned `seed-*` files (only those: a fuzzer's files have hash names). Returns the
/// paths it wrote or deleted. `ANIMCODEC_WRITE_FUZZ_SEEDS=1 cargo test --workspace
/// --test fuzz_corpus` calls it.
pub fn write_seeds() -> std::io::Result<Vec<PathBuf>> {
    let root = corpus_dir();
    let mut touched = Vec::new();
    let differences = seed_differences();
    if differences.is_empty() {
        return Ok(touched);
    }
    let fresh: std::collections::BTreeMap<(String, String), Vec<u8>> =
        seeds().into_iter().map(|(t, n, b)| ((t, format!("{SEED_PREFIX}{n}")), b)).collect();
    for (target, file, difference) in differences {
        let path = root.join(&target).join(&file);
        match difference {
            // Rewriting it would make the committed seed this CPU's, not the write level's.
            SeedDifference::ChangedOnThisCpu => continue,
            SeedDifference::Orphan => std::fs::remove_file(&path)?,
            SeedDifference::Missing | SeedDifference::Changed => {
                std::fs::create_dir_all(root.join(&target))?;
                std::fs::write(&path, &fresh[&(target, file)])?;
            }
        }
        touched.push(path);
    }
    Ok(touched)
}

/// Seed inputs for every target, made from the synthetic animations: `(target, name, bytes)`.
/// Committed as `fuzz/corpus/<target>/seed-<name>` ([`write_seeds`]).
pub fn seeds() -> Vec<(String, String, Vec<u8>)> {
    let registry = animcodec::registry();
    let mut out = Vec::new();
    let tiny = [("flag", fuzz_animation(12)), ("flag3", fuzz_animation(3)), ("flag1", fuzz_animation(1))];
    for codec in registry.iter() {
        let target = format!("codec_{}", codec.name().replace('-', "_"));
        let ladder = codec.rate_ladder(&codec.default_params());
        let mut settings = vec![("default".to_owned(), codec.default_params())];
        for (end, step) in [("low", ladder.steps.first()), ("high", ladder.steps.last())] {
            if let Some(p) =
                step.and_then(|s| codec.default_params().with(&codec.param_specs(), ladder.param, s.clone()).ok())
            {
                settings.push((end.to_owned(), p));
            }
        }
        for (anim_name, anim) in &tiny {
            for (label, params) in &settings {
                let Ok(bytes) = codec_core::encode_animation(codec, params, anim) else { continue };
                let parts = crate::split(&bytes).expect("a valid stream");
                out.push((
                    target.clone(),
                    format!("{anim_name}-{label}"),
                    to_records(&parts.header.config, &parts.packets),
                ));
                if label == "default" {
                    out.push(("container".to_owned(), format!("{}-{anim_name}", codec.name()), bytes));
                }
            }
        }
    }
    for (name, anim) in [("flag", synth::waving_flag(4, 3, 5)), ("tumble1", fuzz_animation(1))] {
        out.push(("read_pc2".into(), name.into(), animcodec::formats::pc2::encode_pc2(&anim).expect("pc2")));
        out.push(("read_mdd".into(), name.into(), animcodec::formats::mdd::encode_mdd(&anim).expect("mdd")));
        let text =
            animcodec::formats::obj::obj_text(std::path::Path::new("seed.obj"), anim.frame(0), anim.triangles(), name)
                .expect("obj");
        out.push(("read_obj".into(), name.into(), text.into_bytes()));
        out.push(("read_usd".into(), name.into(), animcodec::formats::usd::encode_usda(&anim).expect("usda")));
        out.push(("read_abc".into(), name.into(), animcodec::formats::abc::encode_abc(&anim).expect("abc")));
        out.push(("read_usdc".into(), name.into(), animcodec::formats::usdc::encode_usdc(&anim).expect("usdc")));
    }
    // What usd-core writes (two meshes, polygons, a left-handed one, a class and an inactive
    // prim, metadata and dictionaries the reader must skip).
    out.push(("read_usd".into(), "usd-core-style".into(), SEED_USDA.as_bytes().to_vec()));
    out.push((
        "read_obj".into(),
        "polygons".into(),
        b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2//1 3/1/1 -1\n".to_vec(),
    ));
    out.push(("read_gltf".into(), "morph-triangle".into(), seed_gltf()));
    // glTF as animcodec's writer makes it (KHR_mesh_quantization, EXT_meshopt_compression
    // ATTRIBUTES/TRIANGLES, morph targets; rigid motion as node animation): the reader's
    // meshopt, quantization and accessor-layout checks.
    let flag = synth::waving_flag(4, 3, 5);
    let writer = animcodec::formats::gltf_out::GltfOptions::default();
    let rigid = animcodec::formats::gltf_out::GltfOptions { rigid: Some(true), ..writer.clone() };
    for (name, options) in [("meshopt-basis", writer), ("meshopt-rigid", rigid)] {
        if let Ok((glb, _)) = animcodec::formats::gltf_out::encode_gltf(&flag, &options, true) {
            out.push(("read_gltf".into(), name.into(), glb));
        }
    }
    out
}

/// A small glTF (JSON, buffer as a base64 data URI): one triangle with two morph targets and
/// a LINEAR weights animation.
pub fn seed_gltf() -> Vec<u8> {
    use base64::Engine as _;
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut add = |bytes: Vec<u8>, count: usize, ty: &str, component: u32, minmax: Option<([f32; 3], [f32; 3])>| {
        let offset = bin.len();
        bin.extend_from_slice(&bytes);
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        views.push(serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
        let mut a =
            serde_json::json!({"bufferView": views.len() - 1, "componentType": component, "count": count, "type": ty});
        if let Some((min, max)) = minmax {
            a["min"] = serde_json::json!(min);
            a["max"] = serde_json::json!(max);
        }
        accessors.push(a);
        accessors.len() - 1
    };
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let base = add(f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]), 3, "VEC3", 5126, Some(([0.; 3], [1., 1., 0.])));
    let t0 = add(f32s(&[0.5, 0., 0., 0.5, 0., 0., 0.5, 0., 0.]), 3, "VEC3", 5126, Some(([0.5, 0., 0.], [0.5, 0., 0.])));
    let t1 = add(f32s(&[0., 0.5, 0., 0., 0.5, 0., 0., 0.5, 0.]), 3, "VEC3", 5126, Some(([0., 0.5, 0.], [0., 0.5, 0.])));
    let idx = add([0u16, 1, 2].iter().flat_map(|x| x.to_le_bytes()).collect(), 3, "SCALAR", 5123, None);
    let input = add(f32s(&[0., 0.5, 1.]), 3, "SCALAR", 5126, None);
    let output = add(f32s(&[0., 0., 1., 0., 0., 1.]), 6, "SCALAR", 5126, None);
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": base}, "indices": idx,
            "targets": [{"POSITION": t0}, {"POSITION": t1}]}]}],
        "animations": [{"samplers": [{"input": input, "output": output, "interpolation": "LINEAR"}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]}],
        "buffers": [{"byteLength": bin.len(), "uri": uri}],
        "bufferViews": views,
        "accessors": accessors,
    });
    serde_json::to_vec(&doc).expect("json")
}

/// A USD text layer in the style usd-core writes, with the constructs the reader skips or
/// refuses nearby (seed of `read_usd`).
pub const SEED_USDA: &str = r#"#usda 1.0
(
    defaultPrim = "root"
    endTimeCode = 2
    startTimeCode = 0
    timeCodesPerSecond = 24
    upAxis = "Y"
    customLayerData = {
        string creator = "seed"
        int[] n = [1, 2]
    }
)

class "Proto" { def Mesh "m" { point3f[] points = [(0, 0, 0)] } }

def Xform "root" (
    kind = "component"
)
{
    def Mesh "quad" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {
        float3[] extent = [(0, 0, 0), (1, 1, 0)]
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        uniform token orientation = "leftHanded"
        point3f[] points.timeSamples = {
            0: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
            1: [(0, 0, 0.5), (1, 0, 0.5), (1, 1, 0.5), (0, 1, 0.5)],
            2: [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
        }
        rel material:binding = </root/mat>
        uniform token subdivisionScheme = "none"
    }
    def Mesh "tri" (active = true)
    {
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 2, 1]
        point3f[] points = [(-1.5, 2.25, -0), (3e-3, 4, 5), (6, 7, 8)]
    }
    def Mesh "off" (active = false) { point3f[] points = [(1, 2, 3)] }
}
"#;
