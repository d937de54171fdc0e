//! A CSV record of a flat serde struct, written over serde's field list: the header is the
//! struct's field names in declaration order, a record its values. Written by hand rather than
//! with the `csv` crate because the sweep CSV's cells are Rust's `Display` of each value
//! (`0.000031`, `100`), where `csv` writes floats in ryu's shortest form (`3.1e-5`, `100.0`) —
//! the documents would change — and because the `params` cell is a `key=value;…` list, which
//! no general CSV writer produces.
//!
//! Cells: numbers and booleans as `Display`; strings quoted as RFC 4180 says when they hold a
//! comma, a quote or a newline; `None`/unit empty; a map `key=value` pairs joined by `;` (its
//! values as plain text). Anything else (sequences, nested structs) is refused.

use std::fmt::Display;

use serde::ser::{self, Impossible, Serialize, SerializeMap, SerializeStruct, Serializer};

/// Why a value cannot be a CSV cell.
#[derive(Debug)]
pub struct CsvError(String);

impl std::fmt::Display for CsvError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CsvError {}

impl ser::Error for CsvError {
    fn custom<T: Display>(msg: T) -> Self {
        CsvError(msg.to_string())
    }
}

/// The header (field names in declaration order, those in `skip` left out) and the cells of
/// `row`, a struct of scalar, optional and map fields.
pub fn header_and_cells<T: Serialize>(row: &T, skip: &[&str]) -> Result<(Vec<&'static str>, Vec<String>), CsvError> {
    row.serialize(Record { skip, names: Vec::new(), cells: Vec::new() })
}

/// One CSV line: the cells joined by commas.
pub fn line(cells: &[String]) -> String {
    cells.join(",")
}

fn unsupported<T>(what: &str) -> Result<T, CsvError> {
    Err(CsvError(format!("a CSV record holds scalars, options and maps; not {what}")))
}

/// Serializes a struct into its field names and cells.
struct Record<'s> {
    skip: &'s [&'s str],
    names: Vec<&'static str>,
    cells: Vec<String>,
}

/// Serializes one value into one cell; `quote` says whether strings are quoted (not inside a
/// `params` map, whose text needs no quoting: `;` separates the pairs).
struct Cell {
    quote: bool,
}

/// Serializes a map into `key=value;…`.
struct PairList {
    pairs: Vec<String>,
    key: Option<String>,
}

macro_rules! display_cells {
    ($($method:ident: $ty:ty),*) => {
        $(fn $method(self, v: $ty) -> Result<String, CsvError> { Ok(v.to_string()) })*
    };
}

macro_rules! refuse_outside_struct {
    () => {
        type Ok = (Vec<&'static str>, Vec<String>);
        type Error = CsvError;
        type SerializeSeq = Impossible<Self::Ok, CsvError>;
        type SerializeTuple = Impossible<Self::Ok, CsvError>;
        type SerializeTupleStruct = Impossible<Self::Ok, CsvError>;
        type SerializeTupleVariant = Impossible<Self::Ok, CsvError>;
        type SerializeMap = Impossible<Self::Ok, CsvError>;
        type SerializeStruct = Self;
        type SerializeStructVariant = Impossible<Self::Ok, CsvError>;

        fn serialize_bool(self, _: bool) -> Result<Self::Ok, CsvError> {
            unsupported("a bare boolean")
        }
        fn serialize_i8(self, _: i8) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_i16(self, _: i16) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_i32(self, _: i32) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_i64(self, _: i64) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_u8(self, _: u8) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_u16(self, _: u16) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_u32(self, _: u32) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_u64(self, _: u64) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_f32(self, _: f32) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_f64(self, _: f64) -> Result<Self::Ok, CsvError> {
            unsupported("a bare number")
        }
        fn serialize_char(self, _: char) -> Result<Self::Ok, CsvError> {
            unsupported("a bare character")
        }
        fn serialize_str(self, _: &str) -> Result<Self::Ok, CsvError> {
            unsupported("a bare string")
        }
        fn serialize_bytes(self, _: &[u8]) -> Result<Self::Ok, CsvError> {
            unsupported("bytes")
        }
        fn serialize_none(self) -> Result<Self::Ok, CsvError> {
            unsupported("a bare option")
        }
        fn serialize_some<T: ?Sized + Serialize>(self, _: &T) -> Result<Self::Ok, CsvError> {
            unsupported("a bare option")
        }
        fn serialize_unit(self) -> Result<Self::Ok, CsvError> {
            unsupported("unit")
        }
        fn serialize_unit_struct(self, _: &'static str) -> Result<Self::Ok, CsvError> {
            unsupported("a unit struct")
        }
        fn serialize_unit_variant(self, _: &'static str, _: u32, _: &'static str) -> Result<Self::Ok, CsvError> {
            unsupported("an enum")
        }
        fn serialize_newtype_struct<T: ?Sized + Serialize>(self, _: &'static str, _: &T) -> Result<Self::Ok, CsvError> {
            unsupported("a newtype")
        }
        fn serialize_newtype_variant<T: ?Sized + Serialize>(
            self,
            _: &'static str,
            _: u32,
            _: &'static str,
            _: &T,
        ) -> Result<Self::Ok, CsvError> {
            unsupported("an enum")
        }
        fn serialize_seq(self, _: Option<usize>) -> Result<Self::SerializeSeq, CsvError> {
            unsupported("a sequence")
        }
        fn serialize_tuple(self, _: usize) -> Result<Self::SerializeTuple, CsvError> {
            unsupported("a tuple")
        }
        fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<Self::SerializeTupleStruct, CsvError> {
            unsupported("a tuple struct")
        }
        fn serialize_tuple_variant(
            self,
            _: &'static str,
            _: u32,
            _: &'static str,
            _: usize,
        ) -> Result<Self::SerializeTupleVariant, CsvError> {
            unsupported("an enum")
        }
        fn serialize_map(self, _: Option<usize>) -> Result<Self::SerializeMap, CsvError> {
            unsupported("a bare map")
        }
        fn serialize_struct_variant(
            self,
            _: &'static str,
            _: u32,
            _: &'static str,
            _: usize,
        ) -> Result<Self::SerializeStructVariant, CsvError> {
            unsupported("an enum")
        }
    };
}

impl<'s> Serializer for Record<'s> {
    refuse_outside_struct!();

    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Self, CsvError> {
        Ok(self)
    }
}

impl SerializeStruct for Record<'_> {
    type Ok = (Vec<&'static str>, Vec<String>);
    type Error = CsvError;

    fn serialize_field<T: ?Sized + Serialize>(&mut self, key: &'static str, value: &T) -> Result<(), CsvError> {
        if !self.skip.contains(&key) {
            self.names.push(key);
            self.cells.push(value.serialize(Cell { quote: true })?);
        }
        Ok(())
    }

    fn end(self) -> Result<Self::Ok, CsvError> {
        Ok((self.names, self.cells))
    }
}

impl Serializer for Cell {
    type Ok = String;
    type Error = CsvError;
    type SerializeSeq = Impossible<String, CsvError>;
    type SerializeTuple = Impossible<String, CsvError>;
    type SerializeTupleStruct = Impossible<String, CsvError>;
    type SerializeTupleVariant = Impossible<String, CsvError>;
    type SerializeMap = PairList;
    type SerializeStruct = Impossible<String, CsvError>;
    type SerializeStructVariant = Impossible<String, CsvError>;

    display_cells!(serialize_bool: bool, serialize_i8: i8, serialize_i16: i16, serialize_i32: i32, serialize_i64: i64,
        serialize_u8: u8, serialize_u16: u16, serialize_u32: u32, serialize_u64: u64, serialize_f32: f32,
        serialize_f64: f64, serialize_char: char);

    fn serialize_str(self, v: &str) -> Result<String, CsvError> {
        // A series label holds commas (`pca-aoi[mode=baoi,tmax=2]`).
        Ok(if self.quote && v.contains([',', '"', '\n']) {
            format!("\"{}\"", v.replace('"', "\"\""))
        } else {
            v.to_owned()
        })
    }

    fn serialize_bytes(self, _: &[u8]) -> Result<String, CsvError> {
        unsupported("bytes")
    }

    fn serialize_none(self) -> Result<String, CsvError> {
        Ok(String::new())
    }

    fn serialize_some<T: ?Sized + Serialize>(self, value: &T) -> Result<String, CsvError> {
        value.serialize(self)
    }

    fn serialize_unit(self) -> Result<String, CsvError> {
        Ok(String::new())
    }

    fn serialize_unit_struct(self, _: &'static str) -> Result<String, CsvError> {
        Ok(String::new())
    }

    fn serialize_unit_variant(self, _: &'static str, _: u32, variant: &'static str) -> Result<String, CsvError> {
        Ok(variant.to_owned())
    }

    fn serialize_newtype_struct<T: ?Sized + Serialize>(self, _: &'static str, value: &T) -> Result<String, CsvError> {
        value.serialize(self)
    }

    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: &T,
    ) -> Result<String, CsvError> {
        unsupported("an enum with data")
    }

    fn serialize_seq(self, _: Option<usize>) -> Result<Self::SerializeSeq, CsvError> {
        unsupported("a sequence")
    }

    fn serialize_tuple(self, _: usize) -> Result<Self::SerializeTuple, CsvError> {
        unsupported("a tuple")
    }

    fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<Self::SerializeTupleStruct, CsvError> {
        unsupported("a tuple struct")
    }

    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleVariant, CsvError> {
        unsupported("an enum with data")
    }

    fn serialize_map(self, _: Option<usize>) -> Result<PairList, CsvError> {
        Ok(PairList { pairs: Vec::new(), key: None })
    }

    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Self::SerializeStruct, CsvError> {
        unsupported("a nested struct")
    }

    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStructVariant, CsvError> {
        unsupported("an enum with data")
    }
}

impl SerializeMap for PairList {
    type Ok = String;
    type Error = CsvError;

    fn serialize_key<T: ?Sized + Serialize>(&mut self, key: &T) -> Result<(), CsvError> {
        self.key = Some(key.serialize(Cell { quote: false })?);
        Ok(())
    }

    fn serialize_value<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), CsvError> {
        let key = self.key.take().unwrap_or_default();
        self.pairs.push(format!("{key}={}", value.serialize(Cell { quote: false })?));
        Ok(())
    }

    fn end(self) -> Result<String, CsvError> {
        Ok(self.pairs.join(";"))
    }
}
