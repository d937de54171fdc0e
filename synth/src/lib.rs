//! Synthetic animations for demos and tests: deterministic, pure math (no random numbers),
//! each a valid [`Animation`] at [`FRAME_RATE`] frames per second.
//!
//! | name       | generator                                   | what it exercises                            |
//! |------------|---------------------------------------------|----------------------------------------------|
//! | `flag`     | [`waving_flag`]                             | smooth non-rigid waves, open grid mesh       |
//! | `cylinder` | [`bending_cylinder`]                        | two-bone linear blend skinning (bend + twist)|
//! | `tumble`   | [`tumbling_body`]                           | exact rigid motion of a closed mesh          |
//! | `phases`   | [`phased_motion`]                           | motion whose character changes at known frames |
//!
//! [`skinned_character`] (not in [`by_name`]: it takes a [`CharacterSpec`]) is a stress
//! input: disconnected meshes, tiny rigid parts, duplicated seam vertices, bone chains.
//!
//! [`by_name`] builds any of them at a [`SynthSize`]. [`flag_frame`] generates the flag one
//! frame at a time, so arbitrarily long sequences can be streamed into an encoder without
//! holding them in memory.
//!
//! All geometry is computed in `f64` and rounded to `f32` once, so the rigid body is rigid
//! to `f32` rounding. Results depend only on the arguments (the same bytes on every run and
//! thread count; `sin`/`cos` come from the platform's libm).
//!
//! Sizes are clamped to the smallest meaningful mesh (documented per function), so no
//! argument makes a generator fail, except sizes whose vertex count does not fit in `u32`
//! or whose positions do not fit in memory, which panic (these are test generators, and
//! such sizes are programming errors).

use std::f64::consts::{PI, TAU};

use codec_core::{Animation, Error, Result, Topology};

/// Frame rate of every synthetic animation.
pub const FRAME_RATE: f32 = 30.0;

/// Names accepted by [`by_name`].
pub const NAMES: &[&str] = &["flag", "cylinder", "tumble", "phases"];

/// Size presets for [`by_name`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SynthSize {
    /// A few hundred vertices × 40 frames: for unit tests.
    Small,
    /// About 2.5–3k vertices × 120 frames: for demos.
    Medium,
    /// About 10k vertices × 300 frames: for benchmarks.
    Large,
}

impl SynthSize {
    /// Every size, smallest first.
    pub const ALL: [SynthSize; 3] = [SynthSize::Small, SynthSize::Medium, SynthSize::Large];

    /// Lower-case name (`small`, `medium`, `large`).
    pub fn name(self) -> &'static str {
        match self {
            SynthSize::Small => "small",
            SynthSize::Medium => "medium",
            SynthSize::Large => "large",
        }
    }

    /// Parses a lower-case name; the error lists the valid ones.
    pub fn from_name(name: &str) -> Result<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name).ok_or_else(|| {
            Error::InvalidAnimation(format!("unknown synthetic size '{name}'; valid sizes: small, medium, large"))
        })
    }

    /// Number of frames of this preset: 40, 120 or 300.
    pub fn frames(self) -> usize {
        match self {
            SynthSize::Small => 40,
            SynthSize::Medium => 120,
            SynthSize::Large => 300,
        }
    }

    /// Grid resolution used by the grid-like generators: `(a, b)` with `a × b` ≈ the vertex count.
    fn grid(self) -> (usize, usize) {
        match self {
            SynthSize::Small => (20, 12),
            SynthSize::Medium => (64, 40),
            SynthSize::Large => (128, 80),
        }
    }
}

/// Builds the synthetic animation `name` (one of [`NAMES`]) at `size`.
///
/// Vertex counts (Small / Medium / Large): `flag` 240 / 2560 / 10240, `cylinder` 242 / 2562 /
/// 10242, `tumble` 240 / 2560 / 10240, `phases` 242 / 2562 / 10242; frames 40 / 120 / 300.
/// An unknown name gives an error listing [`NAMES`].
pub fn by_name(name: &str, size: SynthSize) -> Result<Animation> {
    let (a, b) = size.grid();
    let f = size.frames();
    match name {
        "flag" => Ok(waving_flag(a, b, f)),
        // rings × segments: `a` rings along the height, `b` segments around, plus two cap centres.
        "cylinder" => Ok(bending_cylinder(a, b, f)),
        "tumble" => Ok(tumbling_body_sized(a, b, f)),
        "phases" => Ok(phased_motion_sized(a, b, f).0),
        _ => Err(Error::InvalidAnimation(format!(
            "unknown synthetic animation '{name}'; valid names: {}",
            NAMES.join(", ")
        ))),
    }
}

fn to_f32(p: [f64; 3], out: &mut Vec<f32>) {
    out.extend_from_slice(&[p[0] as f32, p[1] as f32, p[2] as f32]);
}

fn animation(vertex_count: usize, triangles: Vec<[u32; 3]>, positions: Vec<f32>) -> Animation {
    Animation::from_parts(vertex_count, triangles, positions, FRAME_RATE)
        .expect("synthetic generators produce finite positions and in-range indices")
}

fn index(i: usize) -> u32 {
    u32::try_from(i).expect("synthetic mesh vertex count fits in u32")
}

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// 3×3 rotation by `angle` about the unit `axis` (Rodrigues' formula), row-major.
fn rotation(axis: [f64; 3], angle: f64) -> [[f64; 3]; 3] {
    let [x, y, z] = axis;
    let (s, c) = angle.sin_cos();
    let k = 1.0 - c;
    [
        [c + x * x * k, x * y * k - z * s, x * z * k + y * s],
        [y * x * k + z * s, c + y * y * k, y * z * k - x * s],
        [z * x * k - y * s, z * y * k + x * s, c + z * z * k],
    ]
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

fn apply(m: &[[f64; 3]; 3], p: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * p[2],
        m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * p[2],
        m[2][0] * p[0] + m[2][1] * p[1] + m[2][2] * p[2],
    ]
}

/// Rotation about a pivot: `pivot + m (p - pivot)`.
fn rotate_about(m: &[[f64; 3]; 3], pivot: [f64; 3], p: [f64; 3]) -> [f64; 3] {
    let r = apply(m, [p[0] - pivot[0], p[1] - pivot[1], p[2] - pivot[2]]);
    [r[0] + pivot[0], r[1] + pivot[1], r[2] + pivot[2]]
}

fn lerp3(a: [f64; 3], b: [f64; 3], w: f64) -> [f64; 3] {
    [a[0] + (b[0] - a[0]) * w, a[1] + (b[1] - a[1]) * w, a[2] + (b[2] - a[2]) * w]
}

// ---------------------------------------------------------------------------------------------
// Flag

/// Flag width (along the pole's normal, x) and height (along the pole, y).
const FLAG_WIDTH: f64 = 2.0;
const FLAG_HEIGHT: f64 = 1.25;

/// Topology of [`waving_flag`]`(cols, rows, _)`: a `cols × rows` grid (each clamped to at
/// least 2), vertex `r * cols + c` at column `c`, row `r`.
pub fn flag_topology(cols: usize, rows: usize) -> Topology {
    Topology::grid(cols.max(2), rows.max(2)).expect("synthetic mesh vertex count fits in u32")
}

/// Writes frame `t` of [`waving_flag`]`(cols, rows, frames)` into `out` (cleared first; it
/// receives `cols × rows × 3` floats). Frames can be generated in any order and one at a
/// time, so a 5000-frame × 10 000-vertex flag can be streamed into an encoder.
///
/// The cloth hangs from a pole along the y axis at x = 0 and waves in z: two travelling
/// sine waves along x (a fundamental and a second harmonic with a phase that varies with
/// height), with amplitude growing linearly with the distance from the pole, plus a slight
/// sag and in-plane contraction where the wave is large. A slow gust envelope over the whole
/// sequence (one period per `frames` frames) varies the amplitude by ±25 %.
pub fn flag_frame(cols: usize, rows: usize, t: usize, frames: usize, out: &mut Vec<f32>) {
    let (cols, rows) = (cols.max(2), rows.max(2));
    let frames = frames.max(1);
    out.clear();
    out.reserve(cols * rows * 3);
    let time = t as f64 / FRAME_RATE as f64;
    let gust = 1.0 + 0.25 * (TAU * t as f64 / frames as f64).sin();
    let k = TAU / 1.6; // wavelength 1.6 units
    let omega = TAU * 0.9; // 0.9 Hz
    for r in 0..rows {
        let v = r as f64 / (rows - 1) as f64;
        let y = v * FLAG_HEIGHT;
        for c in 0..cols {
            let u = c as f64 / (cols - 1) as f64;
            let x = u * FLAG_WIDTH;
            let amp = 0.22 * u * gust;
            let phase = k * x - omega * time + 0.6 * v;
            let z = amp * (phase.sin() + 0.35 * (2.0 * phase + 1.3 * v).sin());
            // The cloth does not stretch: where it bends out of plane it pulls in towards the
            // pole a little and sags under gravity.
            let dx = -0.08 * amp * (1.0 - (2.0 * phase).cos());
            let dy = -0.05 * u * u * (1.0 + 0.3 * (omega * time + 2.0 * u).cos());
            to_f32([x + dx, y + dy, z], out);
        }
    }
}

/// A `cols × rows` grid cloth (each clamped to at least 2) waving on a pole for `frames`
/// frames (at least 1) at 30 fps: travelling sine waves in z whose amplitude grows with the
/// distance from the pole, with a second harmonic. See [`flag_frame`] for the exact motion.
pub fn waving_flag(cols: usize, rows: usize, frames: usize) -> Animation {
    let (cols, rows, frames) = (cols.max(2), rows.max(2), frames.max(1));
    let mut positions = Vec::with_capacity(frames * cols * rows * 3);
    let mut frame = Vec::new();
    for t in 0..frames {
        flag_frame(cols, rows, t, frames, &mut frame);
        positions.extend_from_slice(&frame);
    }
    Animation::new(flag_topology(cols, rows), positions, FRAME_RATE)
        .expect("synthetic generators produce finite positions")
}

// ---------------------------------------------------------------------------------------------
// Tube meshes (cylinder and phases)

const TUBE_LENGTH: f64 = 2.0;
const TUBE_RADIUS: f64 = 0.3;

/// A closed tube along z from 0 to [`TUBE_LENGTH`]: `rings` rings (≥ 2) of `segments`
/// vertices (≥ 3), vertex `i * segments + j` on ring `i`, then the bottom and top cap centres.
fn tube(rings: usize, segments: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut rest = Vec::with_capacity(rings * segments + 2);
    for i in 0..rings {
        let z = TUBE_LENGTH * i as f64 / (rings - 1) as f64;
        // A slight bulge in the middle keeps the silhouette from being a plain prism.
        let r = TUBE_RADIUS * (1.0 + 0.15 * (PI * z / TUBE_LENGTH).sin());
        for j in 0..segments {
            let a = TAU * j as f64 / segments as f64;
            rest.push([r * a.cos(), r * a.sin(), z]);
        }
    }
    let bottom = rest.len();
    rest.push([0.0, 0.0, 0.0]);
    let top = rest.len();
    rest.push([0.0, 0.0, TUBE_LENGTH]);

    let mut tris = Vec::with_capacity(2 * rings * segments);
    for i in 0..rings - 1 {
        for j in 0..segments {
            let j1 = (j + 1) % segments;
            let a = index(i * segments + j);
            let b = index(i * segments + j1);
            let c = index((i + 1) * segments + j);
            let d = index((i + 1) * segments + j1);
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
    }
    let last = (rings - 1) * segments;
    for j in 0..segments {
        let j1 = (j + 1) % segments;
        tris.push([index(bottom), index(j1), index(j)]);
        tris.push([index(top), index(last + j), index(last + j1)]);
    }
    (rest, tris)
}

/// A skinned closed cylinder (height 2 along z, radius ≈ 0.3, with end caps) of `rings`
/// rings (≥ 2) × `segments` vertices around (≥ 3) plus two cap centres, bending and twisting
/// for `frames` frames (≥ 1) at 30 fps.
///
/// Two bones meet at a joint at mid-height. Bone 0 (the lower half) stays put; bone 1 bends
/// about a horizontal axis through the joint whose direction turns slowly (bend angle
/// `0.9 sin(2π·0.5 s)` rad, axis at angle `2π·0.15 s` in the xy plane, `s` in seconds) and
/// twists about the cylinder's axis (`0.6 sin(2π·0.35 s)` rad). Each vertex is skinned by
/// linear blend skinning with weight `w₁ = smoothstep((z − 0.5)/1.0)` on bone 1 and `1 − w₁`
/// on bone 0, so the blend region spans the middle half of the height.
pub fn bending_cylinder(rings: usize, segments: usize, frames: usize) -> Animation {
    let (rings, segments, frames) = (rings.max(2), segments.max(3), frames.max(1));
    let (rest, tris) = tube(rings, segments);
    let joint = [0.0, 0.0, 0.5 * TUBE_LENGTH];
    let weights: Vec<f64> =
        rest.iter().map(|p| smoothstep((p[2] - 0.25 * TUBE_LENGTH) / (0.5 * TUBE_LENGTH))).collect();
    let mut positions = Vec::with_capacity(frames * rest.len() * 3);
    for t in 0..frames {
        let s = t as f64 / FRAME_RATE as f64;
        let bend = 0.9 * (TAU * 0.5 * s).sin();
        let axis_angle = TAU * 0.15 * s;
        let axis = [axis_angle.cos(), axis_angle.sin(), 0.0];
        let twist = 0.6 * (TAU * 0.35 * s).sin();
        let m = mat_mul(&rotation(axis, bend), &rotation([0.0, 0.0, 1.0], twist));
        for (p, &w) in rest.iter().zip(&weights) {
            to_f32(lerp3(*p, rotate_about(&m, joint, *p), w), &mut positions);
        }
    }
    animation(rest.len(), tris, positions)
}

// ---------------------------------------------------------------------------------------------
// Tumbling rigid body

/// Rest pose of the tumbling body: a lopsided torus with `around` (≥ 3) × `tube` (≥ 3)
/// vertices, vertex `i * tube + j`. The major radius, tube radius and x scale vary around
/// the ring, so no rotation maps it onto itself and its motion is visible from every side.
fn lopsided_torus(around: usize, tube: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut rest = Vec::with_capacity(around * tube);
    for i in 0..around {
        let u = TAU * i as f64 / around as f64;
        let major = 1.0 + 0.25 * u.cos();
        let minor = 0.3 + 0.12 * u.sin();
        for j in 0..tube {
            let v = TAU * j as f64 / tube as f64;
            let radial = major + minor * v.cos();
            rest.push([1.4 * radial * u.cos(), radial * u.sin(), 0.8 * minor * v.sin() + 0.1 * u.cos()]);
        }
    }
    let mut tris = Vec::with_capacity(2 * around * tube);
    for i in 0..around {
        let i1 = (i + 1) % around;
        for j in 0..tube {
            let j1 = (j + 1) % tube;
            let a = index(i * tube + j);
            let b = index(i * tube + j1);
            let c = index(i1 * tube + j);
            let d = index(i1 * tube + j1);
            tris.push([a, c, d]);
            tris.push([a, d, b]);
        }
    }
    (rest, tris)
}

/// The rigid transform of frame `t` of the tumbling body: `(rotation, translation)`.
fn tumble_transform(t: usize) -> ([[f64; 3]; 3], [f64; 3]) {
    let s = t as f64 / FRAME_RATE as f64;
    // Three rotations at unrelated rates: the instantaneous rotation axis keeps changing.
    let rz = rotation([0.0, 0.0, 1.0], 1.3 * s);
    let ry = rotation([0.0, 1.0, 0.0], 0.8 * s);
    let rx = rotation([1.0, 0.0, 0.0], 0.9 * (1.1 * s).sin());
    let r = mat_mul(&rz, &mat_mul(&ry, &rx));
    let tr = [0.8 * (0.7 * s).sin(), 0.3 * s, 0.5 * (0.9 * s).cos() - 0.5];
    (r, tr)
}

/// A rigid closed mesh (a lopsided torus, 20 × 12 = 240 vertices) tumbling for `frames`
/// frames (≥ 1) at 30 fps: it rotates about an axis that keeps changing (three rotations at
/// unrelated rates) while translating along a curved path. Every frame is an exact rigid
/// transform of frame 0 (up to `f32` rounding); frame 0 is the rest pose.
pub fn tumbling_body(frames: usize) -> Animation {
    tumbling_body_sized(20, 12, frames)
}

/// [`tumbling_body`] with `around × tube` vertices (each clamped to at least 3).
pub fn tumbling_body_sized(around: usize, tube: usize, frames: usize) -> Animation {
    let (around, tube, frames) = (around.max(3), tube.max(3), frames.max(1));
    let (rest, tris) = lopsided_torus(around, tube);
    let mut positions = Vec::with_capacity(frames * rest.len() * 3);
    for t in 0..frames {
        let (r, tr) = tumble_transform(t);
        for p in &rest {
            let q = apply(&r, *p);
            to_f32([q[0] + tr[0], q[1] + tr[1], q[2] + tr[2]], &mut positions);
        }
    }
    animation(rest.len(), tris, positions)
}

// ---------------------------------------------------------------------------------------------
// Phased motion

/// Boundaries of [`phased_motion`] for `frames` frames: `[F/4, F/2, 3F/4]` (integer division).
pub fn phase_boundaries(frames: usize) -> [usize; 3] {
    [frames / 4, frames / 2, 3 * frames / 4]
}

/// A closed tube (the `bending_cylinder` mesh, 16 rings × 15 segments + 2 cap centres =
/// 242 vertices) whose motion changes character at known frames, for `frames` frames (≥ 1)
/// at 30 fps. Returns the animation and the boundaries `[F/4, F/2, 3F/4]` (integer division,
/// see [`phase_boundaries`]); a boundary `b` is the first frame of the new phase.
///
/// With `z` the rest height (0 ..= 2):
/// - `[0, F/4)`: rigid translation: every vertex moves by the same `(0.02, 0.01, 0)` per frame.
/// - `[F/4, F/2)`: bending: the part above `z = 0.6` bends about the x axis through
///   `(0, 0, 0.8)` by an angle growing linearly (0 at `F/4`, 0.9 rad at `F/2`) with skinning
///   weight `smoothstep((z − 0.6)/0.4)`; vertices with `z ≤ 0.6` do not move.
/// - `[F/2, 3F/4)`: only the top part (`z > 1.5`, weight `smoothstep((z − 1.5)/0.2)`) nods about
///   a horizontal axis through `(0, 0, 1.5)`, angle `0.8 sin(2π·2τ/L)` (`τ` frames into the phase
///   of length `L`: two full swings); the bend is held and everything with `z ≤ 1.5` is still.
/// - `[3F/4, F)`: the whole, now still, shape breathes: it is scaled about its centroid by
///   `1 + 0.12 sin(2π·2τ/L)` (two breaths).
///
/// Each phase starts from the pose the previous one would reach at its end, so positions are
/// continuous and only the kind of motion changes. With fewer than 4 frames some phases are
/// empty.
pub fn phased_motion(frames: usize) -> (Animation, Vec<usize>) {
    phased_motion_sized(16, 15, frames)
}

/// [`phased_motion`] with `rings` (≥ 2) × `segments` (≥ 3) tube vertices plus two cap centres.
pub fn phased_motion_sized(rings: usize, segments: usize, frames: usize) -> (Animation, Vec<usize>) {
    let (rings, segments, frames) = (rings.max(2), segments.max(3), frames.max(1));
    let (rest, tris) = tube(rings, segments);
    let [b1, b2, b3] = phase_boundaries(frames);
    let bend_w: Vec<f64> = rest.iter().map(|p| smoothstep((p[2] - 0.6) / 0.4)).collect();
    let nod_w: Vec<f64> = rest.iter().map(|p| smoothstep((p[2] - 1.5) / 0.2)).collect();
    let velocity = [0.02, 0.01, 0.0];

    // The pose given the phase parameters: nod (rest space) → bend → translate → scale.
    let pose = |offset_frames: f64, bend: f64, nod: f64, scale: Option<(f64, [f64; 3])>, out: &mut Vec<[f64; 3]>| {
        out.clear();
        let bend_m = rotation([1.0, 0.0, 0.0], bend);
        let nod_m = rotation([0.0, 1.0, 0.0], nod);
        for ((p, &wb), &wn) in rest.iter().zip(&bend_w).zip(&nod_w) {
            let q = lerp3(*p, rotate_about(&nod_m, [0.0, 0.0, 1.5], *p), wn);
            let q = lerp3(q, rotate_about(&bend_m, [0.0, 0.0, 0.8], q), wb);
            let q = [q[0] + velocity[0] * offset_frames, q[1] + velocity[1] * offset_frames, q[2]];
            out.push(match scale {
                Some((s, c)) => [c[0] + s * (q[0] - c[0]), c[1] + s * (q[1] - c[1]), c[2] + s * (q[2] - c[2])],
                None => q,
            });
        }
    };

    const MAX_BEND: f64 = 0.9;
    let swing = |tau: usize, len: usize| (TAU * 2.0 * tau as f64 / len.max(1) as f64).sin();
    // The still shape that phase 3 scales: the end pose of phase 2 (bend held, nod back at 0).
    let mut held = Vec::new();
    pose(b1 as f64, MAX_BEND, 0.0, None, &mut held);
    let n = held.len() as f64;
    let centroid = held.iter().fold([0.0; 3], |c, p| [c[0] + p[0] / n, c[1] + p[1] / n, c[2] + p[2] / n]);

    let mut positions = Vec::with_capacity(frames * rest.len() * 3);
    let mut frame = Vec::with_capacity(rest.len());
    for t in 0..frames {
        if t < b1 {
            pose(t as f64, 0.0, 0.0, None, &mut frame);
        } else if t < b2 {
            let bend = MAX_BEND * (t - b1) as f64 / (b2 - b1) as f64;
            pose(b1 as f64, bend, 0.0, None, &mut frame);
        } else if t < b3 {
            pose(b1 as f64, MAX_BEND, 0.8 * swing(t - b2, b3 - b2), None, &mut frame);
        } else {
            let s = 1.0 + 0.12 * swing(t - b3, frames - b3);
            pose(b1 as f64, MAX_BEND, 0.0, Some((s, centroid)), &mut frame);
        }
        for p in &frame {
            to_f32(*p, &mut positions);
        }
    }
    (animation(rest.len(), tris, positions), vec![b1, b2, b3])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dist(a: [f32; 3], b: [f32; 3]) -> f64 {
        (0..3).map(|k| (a[k] as f64 - b[k] as f64).powi(2)).sum::<f64>().sqrt()
    }

    #[test]
    fn every_named_small_animation_is_valid_and_deterministic() {
        for name in NAMES {
            let a = by_name(name, SynthSize::Small).unwrap();
            let b = by_name(name, SynthSize::Small).unwrap();
            assert_eq!(a, b, "{name} is not deterministic");
            assert_eq!(a.frame_count(), 40, "{name}");
            assert!((200..400).contains(&a.vertex_count()), "{name}: {} vertices", a.vertex_count());
            assert!(!a.triangles().is_empty(), "{name} has no triangles");
            assert_eq!(a.frame_rate(), FRAME_RATE);
            // Revalidate through the checked constructor.
            let (topo, pos, fps) = a.clone().into_parts();
            assert!(Animation::new(topo, pos, fps).is_ok());
            // No degenerate triangles: every triangle has positive area in frame 0.
            for tri in a.triangles() {
                let [p, q, r] = tri.map(|i| a.vertex(0, i as usize));
                let u = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                let v = [r[0] - p[0], r[1] - p[1], r[2] - p[2]];
                let c = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
                assert!(c.iter().map(|x| x * x).sum::<f32>() > 0.0, "{name}: degenerate triangle {tri:?}");
            }
            // Every animation actually moves.
            let moved = (0..a.vertex_count()).any(|v| dist(a.vertex(0, v), a.vertex(a.frame_count() - 1, v)) > 1e-3);
            assert!(moved, "{name} does not move");
        }
    }

    #[test]
    fn sizes_match_their_documentation() {
        let expected = [("flag", [240, 2560, 10240]), ("cylinder", [242, 2562, 10242]), ("tumble", [240, 2560, 10240])];
        for (name, counts) in expected {
            for (size, count) in SynthSize::ALL.into_iter().zip(counts) {
                if size == SynthSize::Large {
                    continue; // keeps the test fast; the grid sizes are shared with Medium's code path
                }
                let a = by_name(name, size).unwrap();
                assert_eq!(a.vertex_count(), count, "{name} {size:?}");
                assert_eq!(a.frame_count(), size.frames());
            }
        }
        assert_eq!(SynthSize::from_name("medium").unwrap(), SynthSize::Medium);
        assert!(SynthSize::from_name("huge").unwrap_err().to_string().contains("small, medium, large"));
    }

    #[test]
    fn unknown_name_lists_the_valid_names() {
        let e = by_name("teapot", SynthSize::Small).unwrap_err().to_string();
        assert!(e.contains("teapot") && e.contains("flag, cylinder, tumble, phases"), "{e}");
    }

    #[test]
    fn degenerate_sizes_are_clamped_to_valid_meshes() {
        assert_eq!(waving_flag(0, 1, 0).vertex_count(), 4);
        assert_eq!(waving_flag(0, 1, 0).frame_count(), 1);
        assert_eq!(bending_cylinder(0, 0, 1).vertex_count(), 2 * 3 + 2);
        assert_eq!(tumbling_body_sized(0, 0, 1).vertex_count(), 9);
        let (a, b) = phased_motion(1);
        assert_eq!(a.frame_count(), 1);
        assert_eq!(b, vec![0, 0, 0]);
    }

    #[test]
    fn streamed_flag_frames_equal_the_whole_animation() {
        let a = waving_flag(9, 5, 12);
        let mut f = Vec::new();
        for t in (0..12).rev() {
            flag_frame(9, 5, t, 12, &mut f);
            assert_eq!(f.as_slice(), a.frame(t), "frame {t}");
        }
        assert_eq!(&flag_topology(9, 5), a.topology());
    }

    #[test]
    fn tumbling_body_is_rigid() {
        let a = tumbling_body(40);
        let v = a.vertex_count();
        assert!((200..=400).contains(&v));
        // Pairwise distances of a spread of vertex pairs (every 7th vertex against every 11th)
        // are preserved in every frame, relative to the distance itself (f32 rounding of
        // coordinates of size ~3 gives ~1e-6 absolute error; distances here are ≥ ~0.05).
        let mut checked = 0;
        for i in (0..v).step_by(7) {
            for j in (3..v).step_by(11) {
                let d0 = dist(a.vertex(0, i), a.vertex(0, j));
                if d0 < 1e-3 {
                    continue;
                }
                for t in 1..a.frame_count() {
                    let d = dist(a.vertex(t, i), a.vertex(t, j));
                    assert!((d - d0).abs() <= 1e-4 * d0, "pair ({i},{j}) frame {t}: {d} vs {d0}");
                }
                checked += 1;
            }
        }
        assert!(checked > 500, "only {checked} pairs checked");
        // …and it really rotates: the direction between two far-apart vertices changes.
        let dir = |t: usize| {
            let (p, q) = (a.vertex(t, 0), a.vertex(t, v / 2));
            [q[0] - p[0], q[1] - p[1], q[2] - p[2]]
        };
        let (d0, d1) = (dir(0), dir(39));
        let cos = (0..3).map(|k| d0[k] * d1[k]).sum::<f32>()
            / (d0.iter().map(|x| x * x).sum::<f32>().sqrt() * d1.iter().map(|x| x * x).sum::<f32>().sqrt());
        assert!(cos < 0.9, "body barely rotates: cos {cos}");
    }

    /// Motion statistics of the step `t → t+1`: (fraction of vertices that move, whether the
    /// motion is a uniform translation, fraction of the vertices in each height band that move).
    fn step_stats(a: &Animation, rest_z: &[f32], t: usize) -> (f64, bool, [f64; 3]) {
        let v = a.vertex_count();
        let eps = 1e-5;
        let disp: Vec<[f64; 3]> = (0..v)
            .map(|i| {
                let (p, q) = (a.vertex(t, i), a.vertex(t + 1, i));
                [(q[0] - p[0]) as f64, (q[1] - p[1]) as f64, (q[2] - p[2]) as f64]
            })
            .collect();
        let norm = |d: &[f64; 3]| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let moving = disp.iter().filter(|d| norm(d) > eps).count() as f64 / v as f64;
        let uniform = disp.iter().all(|d| norm(&[d[0] - disp[0][0], d[1] - disp[0][1], d[2] - disp[0][2]]) < eps)
            && norm(&disp[0]) > eps;
        let mut bands = [0.0; 3];
        for (k, (lo, hi)) in [(0.0, 0.6), (0.8, 1.5), (1.7, 2.1)].into_iter().enumerate() {
            let idx: Vec<usize> = (0..v).filter(|&i| rest_z[i] >= lo && rest_z[i] <= hi).collect();
            bands[k] = idx.iter().filter(|&&i| norm(&disp[i]) > eps).count() as f64 / idx.len() as f64;
        }
        (moving, uniform, bands)
    }

    #[test]
    fn phase_boundaries_are_where_documented() {
        let frames = 40;
        let (a, b) = phased_motion(frames);
        assert_eq!(b, vec![10, 20, 30]);
        assert_eq!(b, phase_boundaries(frames).to_vec());
        // Rest heights: frame 0 is the rest pose (translation starts at 0).
        let rest_z: Vec<f32> = (0..a.vertex_count()).map(|i| a.vertex(0, i)[2]).collect();
        let kind = |t: usize| {
            let (moving, uniform, bands) = step_stats(&a, &rest_z, t);
            if uniform {
                "translate"
            } else if bands[0] == 0.0 && bands[1] > 0.9 && bands[2] > 0.9 {
                "bend"
            } else if bands[0] == 0.0 && bands[1] == 0.0 && bands[2] > 0.9 {
                "nod"
            } else if moving > 0.95 {
                "scale"
            } else {
                "other"
            }
        };
        let expect = ["translate", "bend", "nod", "scale"];
        let starts = [0, b[0], b[1], b[2]];
        let ends = [b[0], b[1], b[2], frames];
        for p in 0..4 {
            // Every step inside a phase (t and t+1 both in it) has that phase's character,
            // except where a swing passes through zero velocity, which we do not sample.
            for t in starts[p]..ends[p] - 1 {
                let k = kind(t);
                assert_eq!(k, expect[p], "phase {p} step {t}->{}", t + 1);
            }
        }
    }

    #[test]
    fn cylinder_lower_bone_is_fixed_and_upper_moves() {
        let a = bending_cylinder(16, 12, 40);
        // Ring 0 (z = 0) is fully on bone 0: it never moves.
        for t in 0..40 {
            for j in 0..12 {
                assert_eq!(a.vertex(t, j), a.vertex(0, j));
            }
        }
        // The top ring moves substantially.
        let top = 15 * 12;
        let d = (0..40).map(|t| dist(a.vertex(t, top), a.vertex(0, top))).fold(0.0, f64::max);
        assert!(d > 0.3, "top ring moved only {d}");
    }
}

// ---------------------------------------------------------------------------------------------
// Skinned character with tiny rigid parts (a stress input)

/// What [`skinned_character`] builds. Every field is clamped to a meaningful range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CharacterSpec {
    /// Rings of the body tube along its length (≥ 2).
    pub rings: usize,
    /// Vertices around a ring before the seam column is duplicated (≥ 3).
    pub segments: usize,
    /// Bones of the skeleton chain along the body (1..=8).
    pub bones: usize,
    /// Disconnected rigid parts (UV spheres) riding on the body (0..=200).
    pub parts: usize,
    /// Radius of a part, in units of the body length 2 (e.g. 0.006: 0.3 % of the diagonal).
    pub part_radius: f64,
    /// Latitude bands and longitude vertices of a part (≥ 2, ≥ 3): `(lat − 1)·lon + 2` vertices.
    pub part_lat: usize,
    /// See `part_lat`.
    pub part_lon: usize,
    /// Frames (≥ 1).
    pub frames: usize,
    /// Chooses anchors, amplitudes and phases (a hash, no random-number generator).
    pub seed: u64,
}

impl CharacterSpec {
    /// The shape of `../shared/probe-round3/hosvd-divergence/` (`gen.py spheres srad=0.006
    /// nframes=30 nsph=40 nseg=30 nring=16`): a 30 × 16 tube and 40 UV spheres of 128
    /// vertices and radius 0.006, 30 frames. The motion is this module's (skinned bones), not
    /// `gen.py`'s integrated centre line.
    pub fn spheres_like(seed: u64) -> Self {
        Self {
            rings: 30,
            segments: 16,
            bones: 4,
            parts: 40,
            part_radius: 0.006,
            part_lat: 10,
            part_lon: 14,
            frames: 30,
            seed,
        }
    }
}

/// A deterministic value in `[0, 1)` from `seed` and `salt` (SplitMix64's finalizer).
fn unit_hash(seed: u64, salt: u64) -> f64 {
    let mut z = seed ^ salt.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// A rigid transform `p ↦ m·p + c`.
#[derive(Clone, Copy)]
struct Rigid {
    m: [[f64; 3]; 3],
    c: [f64; 3],
}

impl Rigid {
    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let q = apply(&self.m, p);
        [q[0] + self.c[0], q[1] + self.c[1], q[2] + self.c[2]]
    }

    /// `self ∘ other`.
    fn then_inner(&self, other: &Rigid) -> Rigid {
        let c = self.apply(other.c);
        Rigid { m: mat_mul(&self.m, &other.m), c }
    }
}

/// A UV sphere of `lat` bands (≥ 2) and `lon` vertices around (≥ 3) at the origin:
/// `(lat − 1)·lon + 2` vertices (poles first and last).
fn uv_sphere(lat: usize, lon: usize, radius: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut v = vec![[0.0, 0.0, radius]];
    for i in 1..lat {
        let th = PI * i as f64 / lat as f64;
        for j in 0..lon {
            let ph = TAU * j as f64 / lon as f64;
            v.push([radius * th.sin() * ph.cos(), radius * th.sin() * ph.sin(), radius * th.cos()]);
        }
    }
    v.push([0.0, 0.0, -radius]);
    let last = index(v.len() - 1);
    let mut f = Vec::new();
    for j in 0..lon {
        f.push([0, index(1 + j), index(1 + (j + 1) % lon)]);
    }
    for i in 0..lat - 2 {
        let (a, b) = (1 + i * lon, 1 + (i + 1) * lon);
        for j in 0..lon {
            let j2 = (j + 1) % lon;
            f.push([index(a + j), index(b + j), index(b + j2)]);
            f.push([index(a + j), index(b + j2), index(a + j2)]);
        }
    }
    let a = 1 + (lat - 2) * lon;
    for j in 0..lon {
        f.push([index(a + j), last, index(a + (j + 1) % lon)]);
    }
    (v, f)
}

/// A skinned "character" with what a real character that once failed has: several
/// disconnected meshes, tiny rigid parts, coincident seam vertices and bone-driven motion.
///
/// The body is an open tube along z (length 2, radius 0.12) of `rings × (segments + 1)`
/// vertices: the seam column is duplicated (coincident positions, not connected across, as
/// UV seams are in glTF). A chain of `bones` bones splits its length evenly; bone `b`
/// rotates about its joint (`z = 2b/bones`) by `a_b sin(2π(f_b s + φ_b))` about a horizontal
/// axis turning at `w_b` rad/s, composed down the chain; the body vertices are skinned by
/// linear blend skinning with hat weights around each bone's centre (normalised). `parts`
/// UV spheres of radius `part_radius` ride *rigidly* on the body: each is attached to a
/// surface point (hashed anchor along the length and around) and follows the transform of
/// the bone with the largest weight there. Amplitudes, frequencies, phases and anchors come
/// from `seed` through a hash, so equal specs give equal bytes.
pub fn skinned_character(spec: &CharacterSpec) -> Animation {
    const LENGTH: f64 = 2.0;
    const RADIUS: f64 = 0.12;
    let rings = spec.rings.max(2);
    let segments = spec.segments.max(3);
    let bones = spec.bones.clamp(1, 8);
    let parts = spec.parts.min(200);
    let (lat, lon) = (spec.part_lat.max(2), spec.part_lon.max(3));
    let frames = spec.frames.max(1);
    let radius = if spec.part_radius.is_finite() { spec.part_radius.clamp(1e-5, 0.1) } else { 0.006 };
    let h = |salt: u64| unit_hash(spec.seed, salt);

    // Body: the seam column j = segments repeats j = 0.
    let around = segments + 1;
    let mut rest = Vec::with_capacity(rings * around);
    for i in 0..rings {
        let z = LENGTH * i as f64 / (rings - 1) as f64;
        for j in 0..around {
            let a = TAU * (j % segments) as f64 / segments as f64;
            rest.push([RADIUS * a.cos(), RADIUS * a.sin(), z]);
        }
    }
    let mut tris = Vec::new();
    for i in 0..rings - 1 {
        for j in 0..segments {
            let a = index(i * around + j);
            let b = index(i * around + j + 1);
            let c = index((i + 1) * around + j);
            let d = index((i + 1) * around + j + 1);
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
    }
    let body = rest.len();
    let bone_len = LENGTH / bones as f64;
    let weights = |z: f64| -> Vec<f64> {
        let raw: Vec<f64> = (0..bones)
            .map(|b| {
                let centre = (b as f64 + 0.5) * bone_len;
                (1.0 - (z - centre).abs() / bone_len).max(0.0) + 1e-9
            })
            .collect();
        let sum: f64 = raw.iter().sum();
        raw.iter().map(|w| w / sum).collect()
    };
    let body_weights: Vec<Vec<f64>> = rest.iter().map(|p| weights(p[2])).collect();

    // Parts: a sphere per anchor, offset just outside the surface.
    let (sphere, sphere_tris) = uv_sphere(lat, lon, radius);
    let mut anchors = Vec::with_capacity(parts);
    for k in 0..parts {
        let z = 0.05 + (LENGTH - 0.1) * h(1000 + 2 * k as u64);
        let a = TAU * h(1001 + 2 * k as u64);
        let centre = [(RADIUS + radius) * a.cos(), (RADIUS + radius) * a.sin(), z];
        let w = weights(z);
        let bone = (0..bones).fold(0, |best, b| if w[b] > w[best] { b } else { best });
        let first = rest.len();
        for q in &sphere {
            rest.push([centre[0] + q[0], centre[1] + q[1], centre[2] + q[2]]);
        }
        for t in &sphere_tris {
            tris.push([t[0] + index(first), t[1] + index(first), t[2] + index(first)]);
        }
        anchors.push((first, bone));
    }

    let mut positions = Vec::with_capacity(frames * rest.len() * 3);
    for t in 0..frames {
        let s = t as f64 / FRAME_RATE as f64;
        // World transform of each bone, down the chain.
        let mut world: Vec<Rigid> = Vec::with_capacity(bones);
        for b in 0..bones {
            let salt = 10 * b as u64;
            let amplitude = if b == 0 { 0.15 } else { 0.2 + 0.5 * h(salt) };
            let angle = amplitude * (TAU * ((0.3 + 1.2 * h(salt + 1)) * s + h(salt + 2))).sin();
            let heading = TAU * h(salt + 3) + (0.5 + h(salt + 4)) * s;
            let axis = [heading.cos(), heading.sin(), 0.0];
            let joint = [0.0, 0.0, b as f64 * bone_len];
            let m = rotation(axis, angle);
            let local = Rigid {
                m,
                c: [joint[0] - apply(&m, joint)[0], joint[1] - apply(&m, joint)[1], joint[2] - apply(&m, joint)[2]],
            };
            let w = match world.last() {
                Some(parent) => parent.then_inner(&local),
                None => local,
            };
            world.push(w);
        }
        for (p, w) in rest[..body].iter().zip(&body_weights) {
            let mut out = [0.0; 3];
            for b in 0..bones {
                let q = world[b].apply(*p);
                for a in 0..3 {
                    out[a] += w[b] * q[a];
                }
            }
            to_f32(out, &mut positions);
        }
        for &(first, bone) in &anchors {
            for p in &rest[first..first + sphere.len()] {
                to_f32(world[bone].apply(*p), &mut positions);
            }
        }
    }
    animation(rest.len(), tris, positions)
}
