//! A minimal protobuf (proto3) wire-format writer and reader, and a builder for the
//! `FileDescriptorSet` that MCAP's `protobuf` schema encoding carries.
//!
//! Only what the rollout log needs: varints, zigzag, 64/32-bit fixed values, packed repeated
//! `double`/`float`, strings. Written here instead of pulling in a code generator because the
//! log has three small, fixed messages whose layout is documented in [`super::schema`].

/// Wire types of the protobuf encoding.
pub const WIRE_VARINT: u32 = 0;
pub const WIRE_FIXED64: u32 = 1;
pub const WIRE_LEN: u32 = 2;
pub const WIRE_FIXED32: u32 = 5;

/// A malformed protobuf payload.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    #[error("payload ends inside a field (at byte {0})")]
    Truncated(usize),
    #[error("varint longer than 10 bytes at byte {0}")]
    VarintTooLong(usize),
    #[error("unsupported wire type {wire_type} for field {field}")]
    WireType { field: u32, wire_type: u32 },
    #[error("field {field}: {problem}")]
    Field { field: u32, problem: String },
}

/// Appends protobuf fields to a byte buffer.
pub struct Encoder<'a> {
    pub buf: &'a mut Vec<u8>,
}

impl<'a> Encoder<'a> {
    pub fn new(buf: &'a mut Vec<u8>) -> Encoder<'a> {
        Encoder { buf }
    }

    #[inline]
    pub fn varint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.buf.push((v as u8) | 0x80);
            v >>= 7;
        }
        self.buf.push(v as u8);
    }

    #[inline]
    fn key(&mut self, field: u32, wire: u32) {
        self.varint(u64::from((field << 3) | wire));
    }

    /// A `uint32`/`uint64`/`bool` field; zero is skipped (proto3 default).
    #[inline]
    pub fn uint(&mut self, field: u32, v: u64) {
        if v != 0 {
            self.key(field, WIRE_VARINT);
            self.varint(v);
        }
    }

    /// A repeated `uint32`/`uint64` field, one entry per value, zeros included (unpacked, which
    /// every protobuf reader accepts).
    pub fn uints(&mut self, field: u32, vs: impl IntoIterator<Item = u64>) {
        for v in vs {
            self.key(field, WIRE_VARINT);
            self.varint(v);
        }
    }

    /// A `sint32`/`sint64` field (zigzag), always written (so -1 and 0 are both explicit).
    #[inline]
    pub fn sint(&mut self, field: u32, v: i64) {
        self.key(field, WIRE_VARINT);
        self.varint(((v << 1) ^ (v >> 63)) as u64);
    }

    /// A `double` field, always written (bit patterns matter, including -0.0).
    #[inline]
    pub fn double(&mut self, field: u32, v: f64) {
        self.key(field, WIRE_FIXED64);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A packed `repeated double` field; empty is skipped.
    #[inline]
    pub fn doubles(&mut self, field: u32, vs: &[f64]) {
        if vs.is_empty() {
            return;
        }
        self.key(field, WIRE_LEN);
        self.varint(8 * vs.len() as u64);
        for v in vs {
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// A packed `repeated float` field; empty is skipped.
    #[inline]
    pub fn floats(&mut self, field: u32, vs: &[f32]) {
        if vs.is_empty() {
            return;
        }
        self.key(field, WIRE_LEN);
        self.varint(4 * vs.len() as u64);
        for v in vs {
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// A `string`/`bytes` field (or an embedded message); empty is skipped.
    pub fn bytes(&mut self, field: u32, v: &[u8]) {
        if v.is_empty() {
            return;
        }
        self.key(field, WIRE_LEN);
        self.varint(v.len() as u64);
        self.buf.extend_from_slice(v);
    }

    /// An embedded message built by `f`; written even when empty.
    pub fn message(&mut self, field: u32, f: impl FnOnce(&mut Encoder)) {
        let mut inner = Vec::new();
        f(&mut Encoder::new(&mut inner));
        self.key(field, WIRE_LEN);
        self.varint(inner.len() as u64);
        self.buf.extend_from_slice(&inner);
    }
}

/// One decoded field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value<'a> {
    Varint(u64),
    Fixed64(u64),
    Fixed32(u32),
    Len(&'a [u8]),
}

impl<'a> Value<'a> {
    pub fn as_u64(self, field: u32) -> Result<u64, DecodeError> {
        match self {
            Value::Varint(v) => Ok(v),
            _ => Err(wrong(field, "expected a varint")),
        }
    }

    pub fn as_u32(self, field: u32) -> Result<u32, DecodeError> {
        u32::try_from(self.as_u64(field)?).map_err(|_| wrong(field, "value exceeds 32 bits"))
    }

    pub fn as_sint(self, field: u32) -> Result<i64, DecodeError> {
        let v = self.as_u64(field)?;
        Ok(((v >> 1) as i64) ^ -((v & 1) as i64))
    }

    pub fn as_bool(self, field: u32) -> Result<bool, DecodeError> {
        Ok(self.as_u64(field)? != 0)
    }

    pub fn as_f64(self, field: u32) -> Result<f64, DecodeError> {
        match self {
            Value::Fixed64(v) => Ok(f64::from_bits(v)),
            _ => Err(wrong(field, "expected a double")),
        }
    }

    pub fn as_str(self, field: u32) -> Result<&'a str, DecodeError> {
        match self {
            Value::Len(b) => std::str::from_utf8(b).map_err(|_| wrong(field, "invalid UTF-8")),
            _ => Err(wrong(field, "expected a string")),
        }
    }

    /// Appends a `repeated double` field's values: packed, or one unpacked element.
    pub fn push_doubles(self, field: u32, out: &mut Vec<f64>) -> Result<(), DecodeError> {
        match self {
            Value::Len(b) if b.len() % 8 == 0 => {
                out.extend(
                    b.chunks_exact(8)
                        .map(|c| f64::from_le_bytes(c.try_into().expect("chunk of 8"))),
                );
                Ok(())
            }
            Value::Fixed64(v) => {
                out.push(f64::from_bits(v));
                Ok(())
            }
            _ => Err(wrong(field, "malformed repeated double")),
        }
    }

    /// Appends a `repeated float` field's values: packed, or one unpacked element.
    pub fn push_floats(self, field: u32, out: &mut Vec<f32>) -> Result<(), DecodeError> {
        match self {
            Value::Len(b) if b.len() % 4 == 0 => {
                out.extend(
                    b.chunks_exact(4)
                        .map(|c| f32::from_le_bytes(c.try_into().expect("chunk of 4"))),
                );
                Ok(())
            }
            Value::Fixed32(v) => {
                out.push(f32::from_bits(v));
                Ok(())
            }
            _ => Err(wrong(field, "malformed repeated float")),
        }
    }
}

fn wrong(field: u32, problem: &str) -> DecodeError {
    DecodeError::Field {
        field,
        problem: problem.into(),
    }
}

/// Iterates over the fields of a protobuf payload.
pub struct Decoder<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Decoder<'a> {
    pub fn new(buf: &'a [u8]) -> Decoder<'a> {
        Decoder { buf, pos: 0 }
    }

    fn varint(&mut self) -> Result<u64, DecodeError> {
        let start = self.pos;
        let mut v = 0u64;
        for shift in (0..70).step_by(7) {
            let Some(&b) = self.buf.get(self.pos) else {
                return Err(DecodeError::Truncated(self.pos));
            };
            self.pos += 1;
            if shift == 63 && b > 1 {
                return Err(DecodeError::VarintTooLong(start));
            }
            v |= u64::from(b & 0x7f) << shift;
            if b < 0x80 {
                return Ok(v);
            }
        }
        Err(DecodeError::VarintTooLong(start))
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeError> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.buf.len())
            .ok_or(DecodeError::Truncated(self.pos))?;
        let s = &self.buf[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    /// The next `(field number, value)`, or `None` at the end.
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Result<Option<(u32, Value<'a>)>, DecodeError> {
        if self.pos >= self.buf.len() {
            return Ok(None);
        }
        let key = self.varint()?;
        let field = (key >> 3) as u32;
        let wire_type = (key & 7) as u32;
        let value = match wire_type {
            WIRE_VARINT => Value::Varint(self.varint()?),
            WIRE_FIXED64 => Value::Fixed64(u64::from_le_bytes(
                self.take(8)?.try_into().expect("8 bytes"),
            )),
            WIRE_FIXED32 => Value::Fixed32(u32::from_le_bytes(
                self.take(4)?.try_into().expect("4 bytes"),
            )),
            WIRE_LEN => {
                let n = self.varint()?;
                let n = usize::try_from(n).map_err(|_| DecodeError::Truncated(self.pos))?;
                Value::Len(self.take(n)?)
            }
            _ => return Err(DecodeError::WireType { field, wire_type }),
        };
        Ok(Some((field, value)))
    }
}

/// Scalar field types used by the log (numbers as in `descriptor.proto`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldType {
    Double = 1,
    Float = 2,
    Uint64 = 4,
    Bool = 8,
    String = 9,
    Uint32 = 13,
    Sint32 = 17,
}

/// One field of a message description.
#[derive(Clone, Copy, Debug)]
pub struct FieldSpec {
    pub name: &'static str,
    pub number: u32,
    pub ty: FieldType,
    pub repeated: bool,
}

/// A message description: its name (without package) and fields.
#[derive(Clone, Copy, Debug)]
pub struct MessageSpec {
    pub name: &'static str,
    pub fields: &'static [FieldSpec],
}

/// Serialises a `google.protobuf.FileDescriptorSet` with one proto3 file declaring
/// `messages` in `package` — the schema data MCAP readers (Foxglove, `mcap-protobuf-support`)
/// expect for `protobuf` channels.
pub fn file_descriptor_set(file_name: &str, package: &str, messages: &[MessageSpec]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut set = Encoder::new(&mut out);
    // FileDescriptorSet.file = 1
    set.message(1, |file| {
        file.bytes(1, file_name.as_bytes()); // name
        file.bytes(2, package.as_bytes()); // package
        for m in messages {
            // message_type = 4
            file.message(4, |msg| {
                msg.bytes(1, m.name.as_bytes());
                for f in m.fields {
                    // field = 2 (FieldDescriptorProto)
                    msg.message(2, |fd| {
                        fd.bytes(1, f.name.as_bytes()); // name
                        fd.uint(3, u64::from(f.number)); // number
                        fd.uint(4, if f.repeated { 3 } else { 1 }); // label
                        fd.uint(5, f.ty as u64); // type
                        fd.bytes(10, json_name(f.name).as_bytes()); // json_name
                    });
                }
            });
        }
        file.bytes(12, b"proto3"); // syntax
    });
    out
}

/// protoc's json_name: snake_case -> lowerCamelCase.
fn json_name(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    let mut upper = false;
    for c in name.chars() {
        if c == '_' {
            upper = true;
        } else if upper {
            out.extend(c.to_uppercase());
            upper = false;
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalars_round_trip() {
        let mut buf = Vec::new();
        let mut e = Encoder::new(&mut buf);
        e.uint(1, 300);
        e.sint(2, -1);
        e.sint(3, 0);
        e.double(4, -0.0);
        e.floats(5, &[1.5, f32::MIN_POSITIVE]);
        e.doubles(6, &[f64::MAX, 1e-300]);
        e.bytes(7, b"hi");
        e.uint(8, u64::MAX);
        let mut d = Decoder::new(&buf);
        let mut fields = vec![];
        while let Some(f) = d.next().unwrap() {
            fields.push(f);
        }
        assert_eq!(fields[0].1.as_u64(1).unwrap(), 300);
        assert_eq!(fields[1].1.as_sint(2).unwrap(), -1);
        assert_eq!(fields[2].1.as_sint(3).unwrap(), 0);
        assert_eq!(
            fields[3].1.as_f64(4).unwrap().to_bits(),
            (-0.0f64).to_bits()
        );
        let mut fl = vec![];
        fields[4].1.push_floats(5, &mut fl).unwrap();
        assert_eq!(fl, vec![1.5, f32::MIN_POSITIVE]);
        let mut db = vec![];
        fields[5].1.push_doubles(6, &mut db).unwrap();
        assert_eq!(db, vec![f64::MAX, 1e-300]);
        assert_eq!(fields[6].1.as_str(7).unwrap(), "hi");
        assert_eq!(fields[7].1.as_u64(8).unwrap(), u64::MAX);
    }

    #[test]
    fn truncated_payload_is_an_error() {
        let mut buf = Vec::new();
        Encoder::new(&mut buf).doubles(1, &[1.0, 2.0]);
        for cut in 1..buf.len() {
            let mut d = Decoder::new(&buf[..cut]);
            assert!(d.next().is_err(), "cut at {cut}");
        }
    }

    #[test]
    fn json_names_are_camel_case() {
        assert_eq!(json_name("rm_state"), "rmState");
        assert_eq!(json_name("qpos"), "qpos");
    }
}
