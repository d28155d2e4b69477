//! A serde `Serializer` that records the *shape* a value serializes to: struct names, field
//! names in order, primitive kinds, sequence element kinds. This is what CDR sees, so if it
//! matches a definition's field list, the wire layout matches too. (Tests only.)

use serde::Serialize;
use serde::ser::{self, Impossible};
use std::fmt;

use super::definition;

/// Checks that `value` serializes exactly as the definition `text` (of a type in `package`)
/// says: same field names, same order, same kinds.
pub(super) fn check_struct_against_definition<T: Serialize>(
    value: &T,
    text: &str,
    package: &str,
) -> Result<(), String> {
    check_struct_against_fields(value, &definition::fields(text, package)?)
}

#[derive(Debug, Clone, PartialEq)]
enum Shape {
    Prim(&'static str),
    Seq(Vec<Shape>),
    Tuple(Vec<Shape>),
    Struct(&'static str, Vec<(&'static str, Shape)>),
}

#[derive(Debug)]
struct RecordError(String);
impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}
impl std::error::Error for RecordError {}
impl ser::Error for RecordError {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        RecordError(msg.to_string())
    }
}

struct Recorder;

struct SeqRecorder {
    tuple: bool,
    items: Vec<Shape>,
}

struct StructRecorder {
    name: &'static str,
    fields: Vec<(&'static str, Shape)>,
}

fn unsupported<T>(what: &str) -> Result<T, RecordError> {
    Err(RecordError(format!("{what} has no ROS 2 message equivalent")))
}

/// `fn serialize_x(self, _: x) -> Result<Shape, _> { Ok(Shape::Prim("x")) }` for each primitive.
macro_rules! primitives {
    ($($method:ident($ty:ty) => $kind:literal),* $(,)?) => {
        $(fn $method(self, _: $ty) -> Result<Shape, RecordError> {
            Ok(Shape::Prim($kind))
        })*
    };
}

impl ser::Serializer for Recorder {
    type Ok = Shape;
    type Error = RecordError;
    type SerializeSeq = SeqRecorder;
    type SerializeTuple = SeqRecorder;
    type SerializeTupleStruct = SeqRecorder;
    type SerializeTupleVariant = Impossible<Shape, RecordError>;
    type SerializeMap = Impossible<Shape, RecordError>;
    type SerializeStruct = StructRecorder;
    type SerializeStructVariant = Impossible<Shape, RecordError>;

    primitives! {
        serialize_bool(bool) => "bool", serialize_i8(i8) => "i8", serialize_i16(i16) => "i16",
        serialize_i32(i32) => "i32", serialize_i64(i64) => "i64", serialize_u8(u8) => "u8",
        serialize_u16(u16) => "u16", serialize_u32(u32) => "u32", serialize_u64(u64) => "u64",
        serialize_f32(f32) => "f32", serialize_f64(f64) => "f64"
    }
    fn serialize_char(self, _: char) -> Result<Shape, RecordError> {
        unsupported("a Rust char (4 bytes in CDR)")
    }
    fn serialize_str(self, _: &str) -> Result<Shape, RecordError> {
        Ok(Shape::Prim("str"))
    }
    fn serialize_bytes(self, _: &[u8]) -> Result<Shape, RecordError> {
        Ok(Shape::Seq(vec![Shape::Prim("u8")]))
    }
    fn serialize_none(self) -> Result<Shape, RecordError> {
        unsupported("Option")
    }
    fn serialize_some<T: ?Sized + Serialize>(self, _: &T) -> Result<Shape, RecordError> {
        unsupported("Option")
    }
    fn serialize_unit(self) -> Result<Shape, RecordError> {
        unsupported("()")
    }
    fn serialize_unit_struct(self, name: &'static str) -> Result<Shape, RecordError> {
        unsupported(name)
    }
    fn serialize_unit_variant(self, name: &'static str, _: u32, _: &'static str) -> Result<Shape, RecordError> {
        unsupported(name)
    }
    fn serialize_newtype_struct<T: ?Sized + Serialize>(self, name: &'static str, _: &T) -> Result<Shape, RecordError> {
        unsupported(name)
    }
    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        name: &'static str,
        _: u32,
        _: &'static str,
        _: &T,
    ) -> Result<Shape, RecordError> {
        unsupported(name)
    }
    fn serialize_seq(self, _: Option<usize>) -> Result<SeqRecorder, RecordError> {
        Ok(SeqRecorder { tuple: false, items: Vec::new() })
    }
    fn serialize_tuple(self, _: usize) -> Result<SeqRecorder, RecordError> {
        Ok(SeqRecorder { tuple: true, items: Vec::new() })
    }
    fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<SeqRecorder, RecordError> {
        Ok(SeqRecorder { tuple: true, items: Vec::new() })
    }
    fn serialize_tuple_variant(
        self,
        name: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleVariant, RecordError> {
        unsupported(name)
    }
    fn serialize_map(self, _: Option<usize>) -> Result<Self::SerializeMap, RecordError> {
        unsupported("a map")
    }
    fn serialize_struct(self, name: &'static str, _: usize) -> Result<StructRecorder, RecordError> {
        Ok(StructRecorder { name, fields: Vec::new() })
    }
    fn serialize_struct_variant(
        self,
        name: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStructVariant, RecordError> {
        unsupported(name)
    }
}

impl ser::SerializeSeq for SeqRecorder {
    type Ok = Shape;
    type Error = RecordError;
    fn serialize_element<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), RecordError> {
        self.items.push(value.serialize(Recorder)?);
        Ok(())
    }
    fn end(self) -> Result<Shape, RecordError> {
        Ok(if self.tuple { Shape::Tuple(self.items) } else { Shape::Seq(self.items) })
    }
}
impl ser::SerializeTuple for SeqRecorder {
    type Ok = Shape;
    type Error = RecordError;
    fn serialize_element<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), RecordError> {
        ser::SerializeSeq::serialize_element(self, value)
    }
    fn end(self) -> Result<Shape, RecordError> {
        ser::SerializeSeq::end(self)
    }
}
impl ser::SerializeTupleStruct for SeqRecorder {
    type Ok = Shape;
    type Error = RecordError;
    fn serialize_field<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), RecordError> {
        ser::SerializeSeq::serialize_element(self, value)
    }
    fn end(self) -> Result<Shape, RecordError> {
        ser::SerializeSeq::end(self)
    }
}
impl ser::SerializeStruct for StructRecorder {
    type Ok = Shape;
    type Error = RecordError;
    fn serialize_field<T: ?Sized + Serialize>(&mut self, key: &'static str, value: &T) -> Result<(), RecordError> {
        self.fields.push((key, value.serialize(Recorder)?));
        Ok(())
    }
    fn skip_field(&mut self, key: &'static str) -> Result<(), RecordError> {
        Err(RecordError(format!("field {key} is skipped: it would be missing on the wire")))
    }
    fn end(self) -> Result<Shape, RecordError> {
        Ok(Shape::Struct(self.name, self.fields))
    }
}

fn shape_kind(shape: &Shape) -> Result<String, String> {
    Ok(match shape {
        Shape::Prim(p) => (*p).to_string(),
        Shape::Struct(name, _) => format!("struct {name}"),
        Shape::Seq(items) => {
            let first = items.first().ok_or("a sample sequence is empty: its element type is unknown")?;
            let kind = shape_kind(first)?;
            for item in items {
                if shape_kind(item)? != kind {
                    return Err("sequence elements of different kinds".into());
                }
            }
            format!("sequence of {kind}")
        }
        Shape::Tuple(items) => {
            let kind = match items.first() {
                Some(first) => shape_kind(first)?,
                None => "nothing".into(),
            };
            format!("array of {} {kind}", items.len())
        }
    })
}

/// The serde kind a ROS field type must serialize to.
fn ros_kind(ros_type: &str) -> Result<String, String> {
    if let Some(open) = ros_type.find('[') {
        let (base, suffix) = ros_type.split_at(open);
        let inner = suffix.strip_prefix('[').and_then(|s| s.strip_suffix(']')).ok_or("bad array suffix")?;
        let elem = ros_kind(base)?;
        return Ok(if inner.is_empty() || inner.starts_with("<=") {
            format!("sequence of {elem}")
        } else {
            let n: usize = inner.parse().map_err(|_| format!("bad array size in {ros_type}"))?;
            format!("array of {n} {elem}")
        });
    }
    if ros_type == "wstring" || ros_type.starts_with("wstring<=") {
        return Err("wstring is not mirrored".into());
    }
    Ok(match super::syntax::rust_primitive(ros_type) {
        Some("String") => "str".to_string(), // serde's kind of a String
        Some(prim) => prim.to_string(),
        None => format!("struct {}", ros_type.rsplit('/').next().unwrap_or(ros_type)),
    })
}

/// Checks that `value` serializes exactly as the field list says: same field names, same
/// order, same kinds.
pub(super) fn check_struct_against_fields<T: Serialize>(value: &T, fields: &[(String, String)]) -> Result<(), String> {
    let shape = value.serialize(Recorder).map_err(|e| e.to_string())?;
    let Shape::Struct(name, recorded) = shape else {
        return Err(format!("not a struct: {shape:?}"));
    };
    let rust: Vec<(String, String)> = recorded
        .iter()
        .map(|(field, shape)| Ok(((*field).to_string(), shape_kind(shape)?)))
        .collect::<Result<_, String>>()?;
    let ros: Vec<(String, String)> =
        fields.iter().map(|(ty, field)| Ok(((*field).to_string(), ros_kind(ty)?))).collect::<Result<_, String>>()?;
    if rust != ros {
        return Err(format!("struct {name} serializes as\n  {rust:?}\nbut its definition says\n  {ros:?}"));
    }
    Ok(())
}
