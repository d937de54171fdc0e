//! Value representations (`ValueRep`, `pxr/usd/usd/crateFile.h`) and the values they point
//! to, decoded on demand and only for the types a vertex cache needs.
//!
//! A representation is a `u64`: bit 63 array, bit 62 inlined, bit 61 compressed, bits 48–55
//! the type, bits 0–47 the payload — the value itself when inlined (4 bytes: scalars, token
//! and string indexes, vectors and diagonal matrices of `i8` components), else its file
//! offset. Arrays start with their element count (`u32` before version 0.7.0, `u64` after;
//! before 0.5.0 a `u32` shape rank precedes it); payload 0 is the empty array. Integer arrays
//! of 16 or more elements may be integer-coded; `half`/`float`/`double` arrays of 16 or more
//! may be stored as coded `i32`s (code `'i'`) or as a lookup table and coded indexes (`'t'`);
//! everything else is stored raw. Time samples (type 46) are a forward jump to the times'
//! representation, another jump to `u64 n` and the n value representations.

use codec_core::{Error, Result};

use super::super::gltf_buffers::Budget;
use super::super::usd_layer::Value;
use super::container::{compressed_ints, Crate, Cursor};

/// Type numbers of `crateDataTypes.h` read here.
pub mod ty {
    pub const BOOL: u8 = 1;
    pub const UCHAR: u8 = 2;
    pub const INT: u8 = 3;
    pub const UINT: u8 = 4;
    pub const INT64: u8 = 5;
    pub const UINT64: u8 = 6;
    pub const HALF: u8 = 7;
    pub const FLOAT: u8 = 8;
    pub const DOUBLE: u8 = 9;
    pub const STRING: u8 = 10;
    pub const TOKEN: u8 = 11;
    pub const ASSET_PATH: u8 = 12;
    pub const MATRIX2D: u8 = 13;
    pub const MATRIX4D: u8 = 15;
    pub const QUATD: u8 = 16;
    pub const QUATF: u8 = 17;
    pub const QUATH: u8 = 18;
    pub const VEC2D: u8 = 19;
    pub const VEC4I: u8 = 30;
    pub const TOKEN_LIST_OP: u8 = 32;
    pub const PATH_LIST_OP: u8 = 34;
    pub const TOKEN_VECTOR: u8 = 41;
    pub const SPECIFIER: u8 = 42;
    pub const VARIABILITY: u8 = 44;
    pub const TIME_SAMPLES: u8 = 46;
    pub const DOUBLE_VECTOR: u8 = 48;
    pub const STRING_VECTOR: u8 = 50;
    pub const VALUE_BLOCK: u8 = 51;
    pub const TIME_CODE: u8 = 56;
}

/// A decoded value representation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rep(pub u64);

impl Rep {
    pub fn is_array(self) -> bool {
        self.0 >> 63 != 0
    }
    pub fn is_inlined(self) -> bool {
        (self.0 >> 62) & 1 != 0
    }
    pub fn is_compressed(self) -> bool {
        (self.0 >> 61) & 1 != 0
    }
    pub fn ty(self) -> u8 {
        (self.0 >> 48) as u8
    }
    pub fn payload(self) -> u64 {
        self.0 & ((1 << 48) - 1)
    }
}

/// Arrays this short are never compressed (`MinCompressedArraySize`).
const MIN_COMPRESSED: u64 = 16;

/// The scalar kind and component count of a numeric type: (element bytes of one component,
/// components, kind) with kind 0 integer, 1 half, 2 float, 3 double.
fn numeric(ty: u8) -> Option<(u64, u64, u8)> {
    Some(match ty {
        ty::BOOL | ty::UCHAR => (1, 1, 0),
        ty::INT | ty::UINT => (4, 1, 0),
        ty::INT64 | ty::UINT64 => (8, 1, 0),
        ty::HALF => (2, 1, 1),
        ty::FLOAT => (4, 1, 2),
        ty::DOUBLE | ty::TIME_CODE => (8, 1, 3),
        ty::MATRIX2D => (8, 4, 3),
        14 => (8, 9, 3),
        ty::MATRIX4D => (8, 16, 3),
        ty::QUATD => (8, 4, 3),
        ty::QUATF => (4, 4, 2),
        ty::QUATH => (2, 4, 1),
        // Vec{2,3,4}{d,f,h,i}: 19..=30, in that order.
        ty::VEC2D..=ty::VEC4I => {
            let k = ty - ty::VEC2D;
            let n = 2 + (k / 4) as u64;
            match k % 4 {
                0 => (8, n, 3),
                1 => (4, n, 2),
                2 => (2, n, 1),
                _ => (4, n, 0),
            }
        }
        _ => return None,
    })
}

fn half_to_f32(h: u16) -> f32 {
    let sign = ((h >> 15) as u32) << 31;
    let exp = ((h >> 10) & 0x1f) as u32;
    let frac = (h & 0x3ff) as u32;
    let bits = match exp {
        0 if frac == 0 => sign,
        0 => {
            // Subnormal: normalise.
            let mut e = 113u32;
            let mut f = frac;
            while f & 0x400 == 0 {
                f <<= 1;
                e -= 1;
            }
            sign | (e << 23) | ((f & 0x3ff) << 13)
        }
        31 => sign | 0x7f80_0000 | (frac << 13),
        _ => sign | ((exp + 112) << 23) | (frac << 13),
    };
    f32::from_bits(bits)
}

/// Numbers read from raw little-endian bytes of `component`-byte components of `kind`.
enum Numbers {
    Ints(Vec<i64>),
    Floats(Vec<f32>),
    Doubles(Vec<f64>),
}

fn raw_numbers(bytes: &[u8], component: u64, kind: u8, signed: bool) -> Numbers {
    let c = component as usize;
    match kind {
        0 => Numbers::Ints(
            bytes
                .chunks_exact(c)
                .map(|b| match (c, signed) {
                    (1, _) => b[0] as i64,
                    (4, true) => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64,
                    (4, false) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64,
                    _ => i64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
                })
                .collect(),
        ),
        1 => Numbers::Floats(bytes.chunks_exact(2).map(|b| half_to_f32(u16::from_le_bytes([b[0], b[1]]))).collect()),
        2 => Numbers::Floats(bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()),
        _ => Numbers::Doubles(
            bytes
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
                .collect(),
        ),
    }
}

fn into_value(numbers: Numbers, arity: u64, ty: u8) -> Value {
    let arity = arity as usize;
    let mut v = match numbers {
        Numbers::Ints(v) => return Value::Ints(v),
        Numbers::Floats(values) => Value::Floats { arity, values },
        Numbers::Doubles(values) => Value::Doubles { arity, values },
    };
    // Quaternions are stored (i, j, k, real); the model holds (real, i, j, k) as USDA does.
    if matches!(ty, ty::QUATD | ty::QUATF | ty::QUATH) {
        match &mut v {
            Value::Floats { values, .. } => values.chunks_exact_mut(4).for_each(|q| q.rotate_right(1)),
            Value::Doubles { values, .. } => values.chunks_exact_mut(4).for_each(|q| q.rotate_right(1)),
            _ => {}
        }
    }
    v
}

/// Decodes the reader's view of one crate's values.
pub struct Values<'k, 'a> {
    pub krate: &'k Crate<'a>,
}

impl Values<'_, '_> {
    fn err(&self, what: &str, detail: impl Into<String>) -> Error {
        self.krate.err(what.to_owned(), detail)
    }

    /// A cursor from `offset` to the end of the file.
    fn at(&self, offset: u64, what: &str) -> Result<Cursor<'_>> {
        Cursor::new(self.krate.bytes, offset, self.krate.bytes.len() as u64)
            .ok_or_else(|| self.err(what, format!("a value at offset {offset}, past the end of the file")))
    }

    /// The items of a token or path list op (`SdfListOp`, `crateFile.cpp` `_ListOpHeader`) as
    /// token or path indexes: a header byte (bit 0 explicit, then which of the explicit,
    /// added, deleted, ordered, prepended and appended lists follow), then each present list
    /// as a `u64` count and that many `u32` indexes, in the order explicit, added, prepended,
    /// appended, deleted, ordered. Composed over nothing (one layer): the explicit items, else
    /// the prepended, added and appended ones; deleted and ordered items change nothing.
    pub fn list_op(&self, rep: Rep, what: &str, budget: &mut Budget) -> Result<Vec<u32>> {
        if rep.is_inlined() || rep.is_array() {
            return Err(self.err(what, "a list op that is inlined or an array"));
        }
        let mut c = self.at(rep.payload(), what)?;
        let bits = c.u8().map_err(|e| self.err(what, e))?;
        let mut items = Vec::new();
        // (header bit, kept): explicit, added, prepended, appended, deleted, ordered.
        for (bit, kept) in [(1u8, true), (2, true), (5, true), (6, true), (3, false), (4, false)] {
            if bits & (1 << bit) == 0 {
                continue;
            }
            let n = c.u64().map_err(|e| self.err(what, e))?;
            let data = c.take(n.saturating_mul(4)).map_err(|e| self.err(what, format!("a list of {n} items: {e}")))?;
            if kept {
                budget.take("list op items", n.saturating_mul(4))?;
                items.extend(data.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])));
            }
            // An explicit list op authors its explicit items only.
            if bit == 1 && bits & 1 != 0 {
                break;
            }
        }
        Ok(items)
    }

    /// The value of `rep` in the layer model; types not needed here are [`Value::Other`].
    /// `what` names the field in errors.
    pub fn value(&self, rep: Rep, what: &str, budget: &mut Budget) -> Result<Value> {
        let k = self.krate;
        let ty = rep.ty();
        if rep.is_array() {
            return self.array(rep, what, budget);
        }
        match ty {
            ty::TOKEN | ty::STRING | ty::ASSET_PATH => {
                let index = rep.payload() as u32;
                let text = if ty == ty::STRING { k.string(index, what)? } else { k.token(index, what)? };
                budget.take("tokens", text.len() as u64 + 24)?;
                return Ok(Value::Token(text.to_owned()));
            }
            ty::TOKEN_VECTOR => {
                let mut c = self.at(rep.payload(), what)?;
                let n = c.u64().map_err(|e| self.err(what, e))?;
                let data = c.take(n.saturating_mul(4)).map_err(|e| self.err(what, e))?;
                let mut tokens = Vec::new();
                for b in data.chunks_exact(4) {
                    let t = k.token(u32::from_le_bytes([b[0], b[1], b[2], b[3]]), what)?;
                    budget.take("tokens", t.len() as u64 + 24)?;
                    tokens.push(t.to_owned());
                }
                return Ok(Value::Tokens(tokens));
            }
            // Enumerations (specifier, permission, variability): always inlined.
            ty::SPECIFIER..=ty::VARIABILITY => return Ok(Value::Ints(vec![rep.payload() as u32 as i64])),
            _ => {}
        }
        let Some((component, count, kind)) = numeric(ty) else { return Ok(Value::Other) };
        if rep.is_inlined() {
            let bits = rep.payload() as u32;
            let b = bits.to_le_bytes();
            return Ok(match ty {
                ty::FLOAT | ty::DOUBLE | ty::TIME_CODE => {
                    let f = f32::from_bits(bits);
                    if ty == ty::FLOAT {
                        Value::Floats { arity: 1, values: vec![f] }
                    } else {
                        Value::Doubles { arity: 1, values: vec![f as f64] }
                    }
                }
                ty::HALF => Value::Floats { arity: 1, values: vec![half_to_f32(bits as u16)] },
                ty::BOOL | ty::UCHAR | ty::UINT | ty::UINT64 => Value::Ints(vec![bits as i64]),
                ty::INT | ty::INT64 => Value::Ints(vec![bits as i32 as i64]),
                // Matrices: the diagonal as i8s, zeros elsewhere.
                ty::MATRIX2D..=ty::MATRIX4D => {
                    let n = (count as f64).sqrt() as usize;
                    let mut m = vec![0.0; n * n];
                    for i in 0..n {
                        m[i * n + i] = b[i] as i8 as f64;
                    }
                    Value::Doubles { arity: n * n, values: m }
                }
                // Vectors: each component an i8.
                _ => {
                    let comps = b.iter().take(count as usize).map(|&x| x as i8);
                    match kind {
                        0 => Value::Ints(comps.map(|x| x as i64).collect()),
                        3 => Value::Doubles { arity: count as usize, values: comps.map(|x| x as f64).collect() },
                        _ => Value::Floats { arity: count as usize, values: comps.map(|x| x as f32).collect() },
                    }
                }
            });
        }
        let bytes = component * count;
        let mut c = self.at(rep.payload(), what)?;
        let data = c.take(bytes).map_err(|e| self.err(what, e))?;
        Ok(into_value(raw_numbers(data, component, kind, !matches!(ty, ty::UINT | ty::UINT64)), count, ty))
    }

    /// An array value.
    fn array(&self, rep: Rep, what: &str, budget: &mut Budget) -> Result<Value> {
        let k = self.krate;
        let ty = rep.ty();
        let numeric = numeric(ty);
        let is_text = matches!(ty, ty::TOKEN | ty::STRING | ty::ASSET_PATH);
        if numeric.is_none() && !is_text {
            return Ok(Value::Other);
        }
        if rep.payload() == 0 {
            return Ok(match numeric {
                Some((_, _, 0)) => Value::Ints(Vec::new()),
                Some((_, n, 3)) => Value::Doubles { arity: n as usize, values: Vec::new() },
                Some((_, n, _)) => Value::Floats { arity: n as usize, values: Vec::new() },
                None => Value::Tokens(Vec::new()),
            });
        }
        let e = |d: String| self.err(what, d);
        let mut c = self.at(rep.payload(), what)?;
        let [_, minor, _] = k.version;
        if minor < 5 {
            c.u32().map_err(e)?; // the shape rank
        }
        let n = if minor < 7 { c.u32().map_err(e)? as u64 } else { c.u64().map_err(e)? };
        if is_text {
            let data = c
                .take(n.saturating_mul(4))
                .map_err(|_| e(format!("an array of {n} tokens runs past the end of the file")))?;
            let mut tokens = Vec::with_capacity(n as usize);
            for b in data.chunks_exact(4) {
                let i = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                let t = if ty == ty::STRING { k.string(i, what)? } else { k.token(i, what)? };
                budget.take("tokens", t.len() as u64 + 24)?;
                tokens.push(t.to_owned());
            }
            return Ok(Value::Tokens(tokens));
        }
        let Some((component, arity, kind)) = numeric else { return Ok(Value::Other) };
        let signed = !matches!(ty, ty::UINT | ty::UINT64);
        let elements = n.checked_mul(arity).ok_or_else(|| e(format!("an array of {n} elements overflows")))?;
        // What the decoded array holds (as i64/f32/f64).
        let held = elements.saturating_mul(if kind == 2 || kind == 1 { 4 } else { 8 });
        let compressed = rep.is_compressed() && n >= MIN_COMPRESSED && arity == 1;
        if compressed && kind == 0 && minor >= 5 {
            budget.take("arrays", held)?;
            let ints = compressed_ints(&mut c, n, component.clamp(4, 8), budget, "integer array").map_err(e)?;
            let ints =
                if signed || component == 8 { ints } else { ints.into_iter().map(|v| v as u32 as i64).collect() };
            return Ok(Value::Ints(ints));
        }
        if compressed && kind != 0 && minor >= 6 {
            budget.take("arrays", held)?;
            let code = c.u8().map_err(e)?;
            let values: Vec<f64> = match code {
                b'i' => compressed_ints(&mut c, n, 4, budget, "coded float array")
                    .map_err(e)?
                    .into_iter()
                    .map(|v| v as i32 as f64)
                    .collect(),
                b't' => {
                    let lut_size = c.u32().map_err(e)? as u64;
                    let lut = c
                        .take(lut_size.saturating_mul(component))
                        .map_err(|_| e(format!("a lookup table of {lut_size} values runs past the end of the file")))?;
                    budget.take("arrays", lut_size.saturating_mul(8))?;
                    let lut = match raw_numbers(lut, component, kind, true) {
                        Numbers::Floats(v) => v.into_iter().map(|x| x as f64).collect::<Vec<f64>>(),
                        Numbers::Doubles(v) => v,
                        Numbers::Ints(_) => Vec::new(),
                    };
                    let indexes = compressed_ints(&mut c, n, 4, budget, "lookup indexes").map_err(e)?;
                    indexes
                        .into_iter()
                        .map(|i| lut.get(i as u32 as usize).copied())
                        .collect::<Option<Vec<f64>>>()
                        .ok_or_else(|| e(format!("a lookup index is past the {lut_size}-entry table")))?
                }
                other => return Err(e(format!("compressed array code {other} (`i` or `t` expected)"))),
            };
            return Ok(if kind == 3 {
                Value::Doubles { arity: 1, values }
            } else {
                Value::Floats { arity: 1, values: values.into_iter().map(|v| v as f32).collect() }
            });
        }
        let bytes = elements.checked_mul(component).ok_or_else(|| e(format!("an array of {n} elements overflows")))?;
        let data = c
            .take(bytes)
            .map_err(|_| e(format!("an array of {n} elements ({bytes} bytes) runs past the end of the file")))?;
        budget.take("arrays", held)?;
        Ok(into_value(raw_numbers(data, component, kind, signed), arity, ty))
    }

    /// The time samples of a `TimeSamples` value: (time, value representation) in file order.
    pub fn time_samples(&self, rep: Rep, what: &str, budget: &mut Budget) -> Result<Vec<(f64, Rep)>> {
        let e = |d: String| self.err(what, d);
        if rep.ty() != ty::TIME_SAMPLES || rep.is_array() || rep.is_inlined() {
            return Err(e(format!("time samples of type {} (46 expected)", rep.ty())));
        }
        let len = self.krate.bytes.len() as u64;
        let jump = |c: &mut Cursor| -> Result<Cursor<'_>> {
            let start = c.pos as i64;
            let offset = c.i64().map_err(e)?;
            let to = start
                .checked_add(offset)
                .and_then(|t| u64::try_from(t).ok())
                .filter(|&t| t < len)
                .ok_or_else(|| e(format!("a jump of {offset} bytes from offset {start} leaves the file")))?;
            self.at(to, what)
        };
        let mut c = self.at(rep.payload(), what)?;
        let mut c = jump(&mut c)?;
        let times_rep = Rep(c.u64().map_err(e)?);
        let mut c = jump(&mut c)?;
        let n = c.u64().map_err(e)?;
        let reps =
            c.take(n.saturating_mul(8)).map_err(|_| e(format!("{n} sample values run past the end of the file")))?;
        let times = match (times_rep.ty(), times_rep.is_array(), times_rep.is_inlined()) {
            (ty::DOUBLE_VECTOR, false, false) => {
                let mut t = self.at(times_rep.payload(), what)?;
                let count = t.u64().map_err(e)?;
                let data = t
                    .take(count.saturating_mul(8))
                    .map_err(|_| e(format!("{count} sample times run past the end of the file")))?;
                budget.take("sample times", count.saturating_mul(8))?;
                data.chunks_exact(8)
                    .map(|b| f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
                    .collect::<Vec<f64>>()
            }
            (ty::DOUBLE, true, _) => match self.array(times_rep, what, budget)? {
                Value::Doubles { values, .. } => values,
                _ => Vec::new(),
            },
            (t, ..) => return Err(e(format!("sample times of type {t} (a double vector expected)"))),
        };
        if times.len() as u64 != n {
            return Err(e(format!("{} sample times but {n} sample values", times.len())));
        }
        if let Some(t) = times.iter().find(|t| !t.is_finite()) {
            return Err(e(format!("sample time {t} is not finite")));
        }
        if let Some(w) = times.windows(2).find(|w| w[0] >= w[1]) {
            return Err(e(format!("sample times {} and {} are not increasing", w[0], w[1])));
        }
        budget.take("time samples", n.saturating_mul(16))?;
        Ok(times
            .into_iter()
            .zip(reps.chunks_exact(8))
            .map(|(t, b)| (t, Rep(u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))))
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_convert_exactly() {
        for (h, f) in [(0x3c00u16, 1.0f32), (0xc000, -2.0), (0x0001, 5.960_464_5e-8), (0x7bff, 65504.0), (0, 0.0)] {
            assert_eq!(half_to_f32(h), f, "{h:#x}");
        }
        assert!(half_to_f32(0x7e00).is_nan());
        assert_eq!(half_to_f32(0xfc00), f32::NEG_INFINITY);
    }

    #[test]
    fn numeric_types_have_their_layouts() {
        assert_eq!(numeric(24), Some((4, 3, 2))); // Vec3f
        assert_eq!(numeric(23), Some((8, 3, 3))); // Vec3d
        assert_eq!(numeric(25), Some((2, 3, 1))); // Vec3h
        assert_eq!(numeric(30), Some((4, 4, 0))); // Vec4i
        assert_eq!(numeric(ty::MATRIX4D), Some((8, 16, 3)));
        assert_eq!(numeric(31), None); // a dictionary
    }
}
